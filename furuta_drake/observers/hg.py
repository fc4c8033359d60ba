"""High-gain (HG) observer, paper Eq. 4-6: x_hat' = A x_hat + B_F [0, u] + H (y - C x_hat).

The printed H (Eq. 5) lost its powers of epsilon (NOTES.md); this uses the standard high-gain form per joint:
position-row gain a1 / eps and velocity-row gain a2 / eps^2, with s^2 + a1 s + a2 Hurwitz (Eq. 6), so each
joint's error poles are those of s^2 + (a1/eps) s + a2/eps^2 (for a1 = 2, a2 = 1 a double pole at -1/eps),
shifted slightly by the model's coupling (see :func:`high_gain_eigenvalues`). The model has no friction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.systems.primitives import LinearSystem

from furuta_drake.errors import ConfigError
from furuta_drake.observers.linear import DiscreteLinearObserver

ANGLES = np.hstack([np.eye(2), np.zeros((2, 2))])


@dataclass
class HighGainParameters:
    """Design constants of Eq. 5-6 per joint and the sampling period."""

    a1: float = 2.0
    a2: float = 1.0
    eps_theta: float = 0.005  # [s]: error poles near -1/eps = -200 rad/s
    eps_phi: float = 0.005  # [s]
    period: float = 1e-3  # [s]

    def validate(self, where: str = "observers.hg") -> None:
        if not (self.a1 > 0 and self.a2 > 0 and math.isfinite(self.a1) and math.isfinite(self.a2)):
            raise ConfigError(f"{where}: s^2 + a1 s + a2 must be Hurwitz (a1 > 0, a2 > 0), got a1 = {self.a1}, "
                              f"a2 = {self.a2}")
        for name in ("eps_theta", "eps_phi", "period"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{where}.{name} must be > 0, got {value!r}")


def high_gain_matrix(params: HighGainParameters) -> np.ndarray:
    """H (4x2) of Eq. 5 in the standard form: rows [theta, phi, theta_dot, phi_dot], columns [y_theta, y_phi]."""
    H = np.zeros((4, 2))
    for joint, eps in enumerate((params.eps_theta, params.eps_phi)):
        H[joint, joint] = params.a1 / eps
        H[2 + joint, joint] = params.a2 / eps**2
    return H


def high_gain_eigenvalues(params: HighGainParameters, A: np.ndarray | None = None) -> np.ndarray:
    """The designed error poles (roots of s^2 + a1/eps s + a2/eps^2 per joint); with ``A`` the actual
    eigenvalues of A - H C (the model's gravity coupling moves them slightly)."""
    H = high_gain_matrix(params)
    if A is not None:
        return np.linalg.eigvals(A - H @ ANGLES)
    return np.concatenate([np.roots([1.0, params.a1 / eps, params.a2 / eps**2])
                           for eps in (params.eps_theta, params.eps_phi)])


def continuous_high_gain_observer(A: np.ndarray, B_F: np.ndarray, params: HighGainParameters) -> LinearSystem:
    """Eq. 4 as a continuous LinearSystem: input [y_theta, y_phi, u], output x_hat."""
    H = high_gain_matrix(params)
    return LinearSystem(A - H @ ANGLES, np.hstack([H, B_F[:, [1]]]), np.eye(4), np.zeros((4, 3)))


class HighGainObserver(DiscreteLinearObserver):
    """Eq. 4 sampled at ``params.period``. Inputs ``measured_angles_rad`` [theta, phi] and ``arm_torque_Nm``
    (the commanded u); output ``state_estimate`` [theta, phi, theta_dot, phi_dot]."""

    def __init__(self, model, params: HighGainParameters | None = None):
        params = params or HighGainParameters()
        params.validate()
        A, B_F = model
        self.params = params
        DiscreteLinearObserver.__init__(
            self, continuous_high_gain_observer(A, B_F, params), params.period,
            inputs=[("measured_angles_rad", 2), ("arm_torque_Nm", 1)], outputs=[("state_estimate", 4)],
            name="hg_observer")
