"""LQ state feedback at the upright (paper Sec. IV-A), with the friction compensation of Sec. IV-C / V-C.

The design model is Drake's linearization of the MultibodyPlant at theta = 0 (paper Eq. 1-2), in the paper's
order x = [theta, phi, theta_dot, phi_dot] with the arm torque u as input: d/dt x = A x + B u, B = [0, 0, beta4,
beta5]^T. The control law is u = -K (x_hat - x_ref) - F_hat, saturated at the rig's torque limit, computed from
the sample at t_k and held over [t_k, t_k+1) at the control period, like the rig's controller.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import DiscreteTimeApproximation
from pydrake.systems.controllers import DiscreteTimeLinearQuadraticRegulator, LinearQuadraticRegulator
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import (
    Demultiplexer,
    Linearize,
    LinearSystem,
    MatrixGain,
    Multiplexer,
    Saturation,
    ZeroOrderHold,
)

from furuta_drake.errors import ConfigError, require_control_period
from furuta_drake.plant import plant_to_paper_permutation
from furuta_drake.rig import _require_nonnegative, _require_positive


def upright_linearization(plant: MultibodyPlant) -> tuple[np.ndarray, np.ndarray]:
    """A (4x4) and B (4x1, the arm-torque column) of paper Eq. 1-2 from Drake's ``Linearize`` of ``plant``.

    The plant is linearized at q = v = 0 (theta = 0 upright) with its actuation port as the input and the
    applied generalized forces fixed to zero, then permuted to the paper's order with
    :func:`furuta_drake.plant.plant_to_paper_permutation`. ``plant`` must be finalized; it may belong to an
    unbuilt ``DiagramBuilder``.
    """
    context = plant.CreateDefaultContext()
    plant.SetPositionsAndVelocities(context, np.zeros(plant.num_multibody_states()))
    plant.get_actuation_input_port().FixValue(context, np.zeros(plant.num_actuated_dofs()))
    plant.get_applied_generalized_force_input_port().FixValue(context, np.zeros(plant.num_velocities()))
    linear = Linearize(
        plant, context, plant.get_actuation_input_port().get_index(), plant.get_state_output_port().get_index()
    )
    P = plant_to_paper_permutation(plant)
    return P @ linear.A() @ P.T, P @ linear.B()


def zero_order_hold(A: np.ndarray, B: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray]:
    """Ad, Bd of x_k+1 = Ad x_k + Bd u_k for an input held over each ``period`` [s] (Drake's
    ``DiscreteTimeApproximation``)."""
    n, m = B.shape
    discrete = DiscreteTimeApproximation(LinearSystem(A, B, np.zeros((0, n)), np.zeros((0, m))), period)
    return discrete.A(), discrete.B()


@dataclass
class LqrParameters:
    """Weights of the LQ design (paper Sec. IV-A, Anderson and Moore) and the controller's torque limit; the
    controller samples at the control period.

    The cost is sum x^T Q x + R u^2 with Q = diag(state_weights) in paper order. The defaults give the Lund rig
    moderate gains (closed-loop poles of a few to a few tens of rad/s): the start from theta = 0.1 rad stays
    within the 0.2 N m limit, the gains on the velocities are low enough for observer velocity estimates, and
    with the paper's arm friction uncompensated the residual motion is of the size of Table I.
    """

    state_weights: list[float] = field(default_factory=lambda: [10.0, 10.0, 0.1, 0.1])  # [theta, phi, dtheta, dphi]
    input_weight: float = 100.0  # R
    discrete: bool = True  # DARE on the zero-order-hold model at the control period; else the continuous one
    period: float | None = None  # [s] optional: a stated period must equal the control period
    torque_limit: float = 0.2  # [N m]

    def validate(self, where: str = "lqr") -> None:
        if len(self.state_weights) != 4:
            raise ConfigError(
                f"{where}.state_weights must be 4 weights [theta, phi, theta_dot, phi_dot], got {self.state_weights!r}"
            )
        for i, weight in enumerate(self.state_weights):
            _require_nonnegative(weight, f"{where}.state_weights[{i}]")
        for name in ("input_weight", "torque_limit"):
            _require_positive(getattr(self, name), f"{where}.{name}")
        if self.period is not None:
            _require_positive(self.period, f"{where}.period")
        if not isinstance(self.discrete, bool):
            raise ConfigError(f"{where}.discrete must be true or false, got {self.discrete!r}")


def design_lqr(
    plant: MultibodyPlant, params: LqrParameters, *, period: float, where: str = "controller.lqr"
) -> np.ndarray:
    """LQ gain K (1x4, paper order, u = -K x) for the upright linearization of ``plant``, for a controller
    sampled at ``period`` [s] (the DARE on the zero-order-hold model when ``params.discrete``).

    Raises :class:`ConfigError` when the weights leave an unstable or marginal mode out of the cost (e.g. zero
    weight on phi leaves the arm's double integrator unregulated), for which no stabilising LQ gain exists.
    """
    params.validate(where)
    require_control_period(params.period, period, f"{where}.period")
    A, B = upright_linearization(plant)
    Q, R = np.diag(np.asarray(params.state_weights, dtype=float)), np.array([[params.input_weight]])
    if params.discrete:
        Ad, Bd = zero_order_hold(A, B, period)
        _require_detectable(Ad, Q, True, where)
        K, _ = DiscreteTimeLinearQuadraticRegulator(Ad, Bd, Q, R)
    else:
        _require_detectable(A, Q, False, where)
        K, _ = LinearQuadraticRegulator(A, B, Q, R)
    return K


def lqr_gain(
    plant: MultibodyPlant, params: LqrParameters, *, period: float, gain=None, where: str = "controller.gain"
) -> np.ndarray:
    """The LQR gain K (1x4, paper order) of a controller sampled at ``period`` [s]: ``gain`` (4 numbers) when
    given, checked by :func:`check_stabilizing` to stabilise the upright linearization of ``plant`` (``where``
    names it in the error), else :func:`design_lqr` of ``params``."""
    if gain is None:
        return design_lqr(plant, params, period=period)
    K = np.asarray(gain, dtype=float).reshape(1, 4)
    A, B = upright_linearization(plant)
    check_stabilizing(A, B, K, params.discrete, period, where)
    return K


def _require_detectable(A: np.ndarray, Q: np.ndarray, discrete: bool, where: str) -> None:
    """PBH test: every mode with |z| >= 1 (discrete) or Re s >= 0 (continuous) must be seen by the cost."""
    n = A.shape[0]
    eigenvalues = np.linalg.eigvals(A)
    marginal = np.abs(eigenvalues) >= 1 - 1e-9 if discrete else eigenvalues.real >= -1e-9
    for eigenvalue in eigenvalues[marginal]:
        if np.linalg.matrix_rank(np.vstack([eigenvalue * np.eye(n) - A, Q])) < n:
            raise ConfigError(
                f"{where}.state_weights {np.diag(Q).tolist()} leave the mode at eigenvalue "
                f"{eigenvalue:.4g} out of the cost: no stabilising LQ gain (weight phi and theta)"
            )


def state_feedback_eigenvalues(
    A: np.ndarray, B: np.ndarray, K: np.ndarray, discrete: bool, period: float
) -> np.ndarray:
    """Eigenvalues of A - B K (continuous, rad/s) or of Ad - Bd K (discrete, zero-order hold at ``period``)."""
    K = np.asarray(K, dtype=float).reshape(1, -1)
    if discrete:
        Ad, Bd = zero_order_hold(A, B, period)
        return np.linalg.eigvals(Ad - Bd @ K)
    return np.linalg.eigvals(A - B @ K)


def check_stabilizing(A: np.ndarray, B: np.ndarray, K, discrete: bool, period: float, where: str) -> None:
    """Raise :class:`ConfigError` naming ``where`` unless K is 4 finite numbers and stabilises (A, B):
    all |eig(Ad - Bd K)| < 1 (discrete) or all Re eig(A - B K) < 0 (continuous)."""
    K = np.asarray(K, dtype=float)
    if K.size != A.shape[0] or not np.all(np.isfinite(K)):
        raise ConfigError(
            f"{where} must be {A.shape[0]} finite numbers [theta, phi, theta_dot, phi_dot], got {K.ravel().tolist()}"
        )
    eigenvalues = state_feedback_eigenvalues(A, B, K, discrete, period)
    if discrete:
        worst = eigenvalues[np.argmax(np.abs(eigenvalues))]
        if abs(worst) >= 1.0:
            raise ConfigError(
                f"{where} {K.ravel().tolist()} does not stabilise the upright at a {period} s "
                f"period: closed-loop eigenvalue {worst:.4g} has |z| = {abs(worst):.4g} >= 1"
            )
    else:
        worst = eigenvalues[np.argmax(eigenvalues.real)]
        if worst.real >= 0.0:
            raise ConfigError(
                f"{where} {K.ravel().tolist()} does not stabilise the upright: closed-loop "
                f"eigenvalue {worst:.4g} has a non-negative real part"
            )


class LqrController(Diagram):
    """u = sat(u_LQ - F_hat), u_LQ = -K (x_hat - x_ref) (paper Sec. IV-A, IV-C), sampled and held at ``period``,
    from Drake's C++ blocks (a Python update at every sample would cost more than the rest of the loop):
    ``Multiplexer`` [x_hat; F_hat; x_ref] -> ``MatrixGain`` [[-K, -1, K], [-K, 0, K]] -> ``Saturation``
    (+-``torque_limit`` on the command, none on u_LQ) -> ``ZeroOrderHold`` at ``period`` -> ``Demultiplexer``.

    Inputs: ``state_estimate`` (x_hat, paper order); with ``friction_compensation``, ``friction_compensation_Nm``
    (F_hat, the estimated friction torque on the arm in the paper's convention tau = u + F); with ``reference``,
    ``state_reference`` (x_ref). Outputs, held from t_k to t_k+1: ``arm_torque_Nm`` (the command, saturated at
    +-``torque_limit``) and ``lqr_torque_Nm`` (u_LQ before compensation and saturation). No direct feedthrough.
    """

    def __init__(
        self, K, *, period: float, torque_limit: float, friction_compensation: bool = False, reference: bool = False
    ):
        Diagram.__init__(self)
        K = _checked_gain(K, period, torque_limit).reshape(1, 4)
        inputs = [("state_estimate", 4, -K)]
        if friction_compensation:
            inputs.append(("friction_compensation_Nm", 1, np.array([[-1.0]])))
        if reference:
            inputs.append(("state_reference", 4, K))
        gains = np.vstack(
            [
                np.hstack([gain for _, _, gain in inputs]),
                np.hstack([0.0 * gain if name == "friction_compensation_Nm" else gain for name, _, gain in inputs]),
            ]
        )
        builder = DiagramBuilder()
        law = builder.AddNamedSystem("law", MatrixGain(gains))
        if len(inputs) == 1:
            builder.ExportInput(law.get_input_port(), inputs[0][0])
        else:
            mux = builder.AddNamedSystem("inputs", Multiplexer([size for _, size, _ in inputs]))
            builder.Connect(mux.get_output_port(), law.get_input_port())
            for i, (name, _, _) in enumerate(inputs):
                builder.ExportInput(mux.get_input_port(i), name)
        limit = float(torque_limit)
        saturation = builder.AddNamedSystem("saturation", Saturation([-limit, -np.inf], [limit, np.inf]))
        hold = builder.AddNamedSystem("hold", ZeroOrderHold(period, 2))
        outputs = builder.AddNamedSystem("outputs", Demultiplexer(2))
        builder.Connect(law.get_output_port(), saturation.get_input_port())
        builder.Connect(saturation.get_output_port(), hold.get_input_port())
        builder.Connect(hold.get_output_port(), outputs.get_input_port())
        builder.ExportOutput(outputs.get_output_port(0), "arm_torque_Nm")
        builder.ExportOutput(outputs.get_output_port(1), "lqr_torque_Nm")
        builder.BuildInto(self)
        self.set_name("lqr")


def _checked_gain(K, period: float, torque_limit: float) -> np.ndarray:
    K = np.asarray(K, dtype=float)
    if K.size != 4 or not np.all(np.isfinite(K)):
        raise ConfigError(f"LQR gain must be 4 finite numbers, got {K.ravel().tolist()}")
    _require_positive(period, "LqrController period")
    _require_positive(torque_limit, "LqrController torque_limit")
    return K


__all__ = [
    "upright_linearization",
    "zero_order_hold",
    "LqrParameters",
    "design_lqr",
    "lqr_gain",
    "state_feedback_eigenvalues",
    "check_stabilizing",
    "LqrController",
]
