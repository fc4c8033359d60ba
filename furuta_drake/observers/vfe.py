"""Velocity and friction error (VFE) observer, paper Eq. 11-13, with the slips NOTES.md lists fixed:

    x_hat'     = A x_hat + B u + B_F (F_hat + eps_hat_F) + K1 (y - C x_hat)
    eps_hat_F' = K2 (y - C x_hat)

eps_hat_F is a state (A_F of Eq. 13 has a zero block for it; Eq. 15 needs it), with two entries [pendulum,
arm] entering through B_F like the friction F, and F_hat = [0, F_hat_phi] from the Dahl observer in the arm
entry. K_F = [K1; K2] is placed (scipy's ``place_poles``) so that G = A_F - K_F C_F (Eq. 12) has the chosen
eigenvalues; with a slowly varying friction error, eps_hat_F converges to F - F_hat (Eq. 14-15).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.systems.primitives import LinearSystem
from scipy.signal import place_poles

from furuta_drake.errors import ConfigError
from furuta_drake.observers.linear import DiscreteLinearObserver

ANGLES = np.hstack([np.eye(2), np.zeros((2, 2))])


@dataclass
class VfeParameters:
    """The six eigenvalues of G (Eq. 12) [1/s] (distinct, negative) and the sampling period."""

    eigenvalues: list[float] = field(default_factory=lambda: [-20.0, -23.0, -26.0, -29.0, -32.0, -35.0])
    period: float = 1e-3  # [s]

    def validate(self, where: str = "observers.vfe") -> None:
        if len(self.eigenvalues) != 6:
            raise ConfigError(f"{where}.eigenvalues must list 6 eigenvalues of G, got {len(self.eigenvalues)}")
        if not all(math.isfinite(e) and e < 0 for e in self.eigenvalues):
            raise ConfigError(f"{where}.eigenvalues must be negative (a stable G, Eq. 12), got {self.eigenvalues}")
        if len(set(self.eigenvalues)) != 6:
            raise ConfigError(f"{where}.eigenvalues must be distinct for pole placement, got {self.eigenvalues}")
        if not (math.isfinite(self.period) and self.period > 0):
            raise ConfigError(f"{where}.period must be > 0, got {self.period!r}")


def augmented_model(A: np.ndarray, B_F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A_F (6x6) and C_F (2x6) of Eq. 13: the friction error as a constant state entering through B_F."""
    A_F = np.zeros((6, 6))
    A_F[:4, :4], A_F[:4, 4:] = A, B_F
    C_F = np.hstack([ANGLES, np.zeros((2, 2))])
    return A_F, C_F


def vfe_gains(A: np.ndarray, B_F: np.ndarray, eigenvalues) -> np.ndarray:
    """K_F = [K1; K2] (6x2) placing the eigenvalues of G = A_F - K_F C_F (Eq. 12)."""
    A_F, C_F = augmented_model(A, B_F)
    return place_poles(A_F.T, C_F.T, np.asarray(eigenvalues, dtype=float)).gain_matrix.T


def vfe_error_matrix(A: np.ndarray, B_F: np.ndarray, K_F: np.ndarray) -> np.ndarray:
    """G = A_F - K_F C_F of Eq. 12."""
    A_F, C_F = augmented_model(A, B_F)
    return A_F - K_F @ C_F


def continuous_vfe_observer(A: np.ndarray, B_F: np.ndarray, params: VfeParameters) -> LinearSystem:
    """Eq. 11 as a continuous LinearSystem: input [y_theta, y_phi, u, F_hat_phi], output [x_hat, eps_hat_F]."""
    K_F = vfe_gains(A, B_F, params.eigenvalues)
    A_F, C_F = augmented_model(A, B_F)
    arm = np.concatenate([B_F[:, 1], np.zeros(2)]).reshape(6, 1)
    return LinearSystem(A_F - K_F @ C_F, np.hstack([K_F, arm, arm]), np.eye(6), np.zeros((6, 4)))


class VfeObserver(DiscreteLinearObserver):
    """Eq. 11 sampled at ``params.period``. Inputs ``measured_angles_rad``, ``arm_torque_Nm`` (u) and
    ``friction_estimate_Nm`` (F_hat_phi); outputs ``state_estimate`` (x_hat) and ``friction_error_estimate_Nm``
    (eps_hat_F = [pendulum, arm])."""

    def __init__(self, model, params: VfeParameters | None = None):
        params = params or VfeParameters()
        params.validate()
        A, B_F = model
        self.params = params
        self.gains = vfe_gains(A, B_F, params.eigenvalues)
        DiscreteLinearObserver.__init__(
            self, continuous_vfe_observer(A, B_F, params), params.period,
            inputs=[("measured_angles_rad", 2), ("arm_torque_Nm", 1), ("friction_estimate_Nm", 1)],
            outputs=[("state_estimate", 4), ("friction_error_estimate_Nm", 2)], name="vfe_observer")
