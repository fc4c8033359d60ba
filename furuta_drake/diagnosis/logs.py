"""Load and check the CSV run logs of ``spec/diagnosis-interface.md`` (stage 1 of the diagnosis)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class RunLog:
    """One run log, checked and in the paper's sign convention."""

    name: str  # file name (e.g. "balance_1.csv"), used in report windows
    path: str
    time: np.ndarray  # [s], strictly increasing, as logged
    theta: np.ndarray  # [rad], paper convention: theta_logged * rig.theta_direction
    phi: np.ndarray  # [rad]
    input_kind: str  # "torque" | "voltage"
    input: np.ndarray  # as logged: [N m] or [V]
    sample_period: float  # [s], median step
    torque_per_volt: float = 1.0  # kt / R of the rig's motor for voltage logs [N m / V]; 1 for torque logs

    @property
    def torque_command(self) -> np.ndarray:
        """Torque-equivalent of the command [N m]: the torque, or kt V / R for a voltage log (the back-EMF
        term kt ke / R phi_dot is a model term that the surrogate and the replay add)."""
        if self.input_kind == "torque":
            return self.input
        return self.input * self.torque_per_volt
