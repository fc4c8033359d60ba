"""High-gain (HG) observer, paper Eq. 4-6: x_hat' = A x_hat + B_F [0, u] + H (y - C x_hat).

The model has no friction (Eq. 4: the torque is B_F [0, u]); the high gain makes the estimate robust to it.
The printed H (Eq. 5) reuses alpha/beta for design constants and lost its powers of epsilon (``docs/paper.md``); this
uses the standard high-gain form, the same polynomial s^2 + a1 s + a2 (Hurwitz, Eq. 6) for both joints and a
scale eps per joint: position-row gain a1 / eps, velocity-row gain a2 / eps^2. Each joint's error poles are the
roots of s^2 + (a1/eps) s + a2/eps^2 (a1 = 2, a2 = 1: a double pole at -1/eps), moved slightly by the
model's gravity coupling: :func:`high_gain_eigenvalues` gives the designed ones, the eigenvalues of
:func:`high_gain_error_matrix` (A - H C) the true ones.

Default eps = 5 ms for both joints: designed poles at -200 rad/s, about ten times the fastest pole of the
default LQ loop, as the high-gain separation argument asks, while 1 kHz sampling stays comfortable
(exp(-0.2) per period). The price is noise: for white angle noise of std sigma the velocity estimate's std is
sigma sqrt(h a2^2 / (2 a1 eps^3)) (h the period), i.e. it grows as eps^-1.5 (4096-count quantisation:
sigma = q / sqrt(12)).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.systems.primitives import LinearSystem

from furuta_drake.errors import ConfigError, require_control_period
from furuta_drake.observers.linear import ANGLES, DiscreteLinearObserver, model_matrices


@dataclass
class HighGainParameters:
    """Design constants of Eq. 5-6."""

    a1: float = 2.0  # s^2 + a1 s + a2 Hurwitz (a1, a2 > 0) [-]
    a2: float = 1.0  # [-]
    eps_theta: float = 0.005  # pendulum joint's scale [s]: error poles of s^2 + a1/eps s + a2/eps^2
    eps_phi: float = 0.005  # arm joint's scale [s]
    period: float | None = None  # [s] optional: the observer runs at the control period; a stated one must equal it

    def validate(self, where: str = "observers.hg") -> None:
        for name in ("a1", "a2"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(
                    f"{where}.{name} must be > 0 for s^2 + a1 s + a2 to be Hurwitz (Eq. 6), got {value!r}"
                )
        for name in ("eps_theta", "eps_phi"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{where}.{name} must be > 0, got {value!r}")
        if self.period is not None and not (math.isfinite(self.period) and self.period > 0):
            raise ConfigError(f"{where}.period must be > 0 (or null: the control period), got {self.period!r}")


def high_gain_matrix(params: HighGainParameters) -> np.ndarray:
    """H (4x2) of Eq. 5 in the standard form: rows [theta, phi, theta_dot, phi_dot], columns [y_theta, y_phi]."""
    H = np.zeros((4, 2))
    for joint, eps in enumerate((params.eps_theta, params.eps_phi)):
        H[joint, joint] = params.a1 / eps
        H[2 + joint, joint] = params.a2 / eps**2
    return H


def high_gain_eigenvalues(params: HighGainParameters) -> np.ndarray:
    """The designed error poles [1/s]: the roots of s^2 + (a1/eps) s + a2/eps^2 for [theta, phi]."""
    return np.concatenate(
        [np.roots([1.0, params.a1 / eps, params.a2 / eps**2]) for eps in (params.eps_theta, params.eps_phi)]
    )


def high_gain_error_matrix(A: np.ndarray, params: HighGainParameters) -> np.ndarray:
    """A - H C, the estimation error's dynamics (its eigenvalues are the observer's true poles)."""
    return A - high_gain_matrix(params) @ ANGLES


def continuous_high_gain_observer(A: np.ndarray, B_F: np.ndarray, params: HighGainParameters) -> LinearSystem:
    """Eq. 4 as a continuous LinearSystem: input [y_theta, y_phi, u], output x_hat."""
    H = high_gain_matrix(params)
    return LinearSystem(A - H @ ANGLES, np.hstack([H, B_F[:, [1]]]), np.eye(4), np.zeros((4, 3)))


class HighGainObserver(DiscreteLinearObserver):
    """Eq. 4 sampled at the control period ``period`` [s] (exact zero-order hold of the inputs). ``rig_or_AB``: a
    RigParameters or (A, B_F). Inputs ``measured_angles_rad`` [theta, phi] and ``arm_torque_Nm`` (u, the torque
    acting over the coming period); output ``state_estimate`` [theta, phi, theta_dot, phi_dot] [rad, rad/s]."""

    def __init__(self, rig_or_AB, params: HighGainParameters | None = None, *, period: float):
        params = params or HighGainParameters()
        params.validate()
        require_control_period(params.period, period, "observers.hg.period")
        A, B_F = model_matrices(rig_or_AB)
        self.params = params
        DiscreteLinearObserver.__init__(
            self,
            continuous_high_gain_observer(A, B_F, params),
            period,
            inputs=[("measured_angles_rad", 2), ("arm_torque_Nm", 1)],
            outputs=[("state_estimate", 4)],
            name="hg_observer",
        )
