"""Velocity and friction error (VFE) observer, paper Eq. 11-13, with the slips ``docs/paper.md`` lists fixed:

    x_hat'     = A x_hat + B u + B_F (F_hat + eps_hat_F) + K1 (y - C x_hat)
    eps_hat_F' = K2 (y - C x_hat)

eps_hat_F is a state (Eq. 11 prints a static map, but A_F of Eq. 13 has a zero block for it and Eq. 15 needs
it), with two entries [pendulum, arm] entering through B_F like the friction F, and F_hat = [0, F_hat_phi]
from the Dahl observer in the arm entry (Eq. 11 prints [F_hat_phi, 0]). K_F = [K1; K2] is placed (scipy's
``place_poles``) so that G = A_F - K_F C_F (Eq. 12) has the chosen eigenvalues. G is also the dynamics of the
error [x - x_hat; (F - F_hat) - eps_hat_F] while F - F_hat is constant, so then eps_hat_F converges to the
friction error F - F_hat (Eq. 14-15) and x_hat to x.

Default eigenvalues -20, -23, ..., -35 rad/s: at least as fast as the fastest pole of the default LQ loop, so the
estimate does not slow the regulation, and several times slower than the default HG observer (-200 rad/s),
which is what makes the VFE estimate quiet (Table II).
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field

import numpy as np
from pydrake.systems.primitives import LinearSystem
from scipy.signal import place_poles

from furuta_drake.errors import ConfigError, require_control_period
from furuta_drake.observers.linear import ANGLES, DiscreteLinearObserver, model_matrices


@dataclass
class VfeParameters:
    """The six eigenvalues of G (Eq. 12) [1/s] (negative reals, none repeated more than twice: the two
    measured angles allow a multiplicity of two)."""

    eigenvalues: list[float] = field(default_factory=lambda: [-20.0, -23.0, -26.0, -29.0, -32.0, -35.0])
    period: float | None = None  # [s] optional: the observer runs at the control period; a stated one must equal it

    def validate(self, where: str = "observers.vfe") -> None:
        if len(self.eigenvalues) != 6:
            raise ConfigError(f"{where}.eigenvalues must list 6 eigenvalues of G (Eq. 12), got {len(self.eigenvalues)}")
        for i, value in enumerate(self.eigenvalues):
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value < 0):
                raise ConfigError(
                    f"{where}.eigenvalues[{i}] must be a negative real (a stable G, Eq. 12), got {value!r}"
                )
        for value in self.eigenvalues:
            if self.eigenvalues.count(value) > 2:
                raise ConfigError(
                    f"{where}.eigenvalues repeats {value} {self.eigenvalues.count(value)} times; "
                    f"two angle measurements allow at most 2"
                )
        if self.period is not None and not (math.isfinite(self.period) and self.period > 0):
            raise ConfigError(f"{where}.period must be > 0 (or null: the control period), got {self.period!r}")


def augmented_model(A: np.ndarray, B_F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A_F (6x6) and C_F (2x6) of Eq. 13: the friction error as a constant state entering through B_F."""
    A_F = np.zeros((6, 6))
    A_F[:4, :4], A_F[:4, 4:] = A, B_F
    C_F = np.hstack([ANGLES, np.zeros((2, 2))])
    return A_F, C_F


def vfe_gains(A: np.ndarray, B_F: np.ndarray, eigenvalues) -> np.ndarray:
    """K_F = [K1; K2] (6x2, K1 the first four rows) placing the eigenvalues of G = A_F - K_F C_F (Eq. 12).

    Pole placement on the dual pair (A_F^T, C_F^T); the placed eigenvalues are checked to 1e-6 relative
    (scipy only warns when its robustness refinement stops early, which does not affect the placement)."""
    A_F, C_F = augmented_model(A, B_F)
    wanted = np.sort(np.asarray(eigenvalues, dtype=float))
    with warnings.catch_warnings():
        warnings.filterwarnings("ignore", message="Convergence was not reached", category=UserWarning)
        K_F = place_poles(A_F.T, C_F.T, wanted).gain_matrix.T
    placed = np.sort(np.linalg.eigvals(A_F - K_F @ C_F).real)
    if not np.allclose(placed, wanted, rtol=1e-6, atol=0.0):
        raise ConfigError(f"observers.vfe.eigenvalues {wanted.tolist()} could not be placed (got {placed.tolist()})")
    return K_F


def vfe_error_matrix(A: np.ndarray, B_F: np.ndarray, K_F: np.ndarray) -> np.ndarray:
    """G = A_F - K_F C_F of Eq. 12 (6x6): the dynamics of [x - x_hat; F - F_hat - eps_hat_F]."""
    A_F, C_F = augmented_model(A, B_F)
    return A_F - K_F @ C_F


def friction_error_response(A: np.ndarray, B_F: np.ndarray, K_F: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(M, N) of w' = M w + N F_tilde_phi, w = [x - x_hat; eps_hat_F]: how eps_hat_F (w[5], the arm entry) answers
    an arm friction error F_tilde_phi = F_phi - F_hat_phi (Eq. 11 subtracted from the plant; the DC gain is 1,
    eig(M) = eig(G) of Eq. 12)."""
    K1, K2 = K_F[:4], K_F[4:]
    M = np.zeros((6, 6))
    M[:4, :4], M[:4, 4:] = A - K1 @ ANGLES, -B_F
    M[4:, :4] = K2 @ ANGLES
    return M, np.concatenate([B_F[:, 1], np.zeros(2)]).reshape(6, 1)


def continuous_vfe_observer(
    A: np.ndarray, B_F: np.ndarray, params: VfeParameters, pendulum_friction_input: bool = False
) -> LinearSystem:
    """Eq. 11 as a continuous LinearSystem: input [y_theta, y_phi, u, F_hat_phi] (then F_hat_theta with
    ``pendulum_friction_input``: a friction observer on the pendulum too), output [x_hat, eps_hat_F]; its input
    matrix's first two columns are K_F."""
    K_F = vfe_gains(A, B_F, params.eigenvalues)
    arm = np.concatenate([B_F[:, 1], np.zeros(2)]).reshape(6, 1)  # u and F_hat_phi both act on the arm
    columns = [K_F, arm, arm]
    if pendulum_friction_input:
        columns.append(np.concatenate([B_F[:, 0], np.zeros(2)]).reshape(6, 1))
    B = np.hstack(columns)
    return LinearSystem(vfe_error_matrix(A, B_F, K_F), B, np.eye(6), np.zeros((6, B.shape[1])))


class VfeObserver(DiscreteLinearObserver):
    """Eq. 11 sampled at the control period ``period`` [s] (exact zero-order hold of the inputs). ``rig_or_AB``: a
    RigParameters or (A, B_F). Inputs ``measured_angles_rad`` [theta, phi], ``arm_torque_Nm`` (u) and
    ``friction_estimate_Nm`` (F_hat_phi, the Dahl observer's arm friction), and with ``pendulum_friction_input``
    ``pendulum_friction_estimate_Nm`` (F_hat_theta, Eq. 10's full F_hat); outputs ``state_estimate`` (x_hat
    [rad, rad/s]) and ``friction_error_estimate_Nm`` (eps_hat_F = [pendulum, arm]). ``gains`` is K_F = [K1; K2]."""

    def __init__(
        self, rig_or_AB, params: VfeParameters | None = None, *, period: float, pendulum_friction_input: bool = False
    ):
        params = params or VfeParameters()
        params.validate()
        require_control_period(params.period, period, "observers.vfe.period")
        A, B_F = model_matrices(rig_or_AB)
        self.params = params
        continuous = continuous_vfe_observer(A, B_F, params, pendulum_friction_input)
        self.gains = continuous.B()[:, :2]
        inputs = [("measured_angles_rad", 2), ("arm_torque_Nm", 1), ("friction_estimate_Nm", 1)]
        if pendulum_friction_input:
            inputs.append(("pendulum_friction_estimate_Nm", 1))
        DiscreteLinearObserver.__init__(
            self,
            continuous,
            period,
            inputs=inputs,
            outputs=[("state_estimate", 4), ("friction_error_estimate_Nm", 2)],
            name="vfe_observer",
        )
