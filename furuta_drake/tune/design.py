"""The LQ design on the corrected model: Drake's linearization at the upright, sampled at the control period with
the input delay as delayed-command states and the actuator lag as a filter state, and the LQ gain on the four
states the rig's controller feeds back (paper Sec. IV-A).

**Linearization.** The world of the corrected model (:func:`~furuta_drake.world.add_furuta_world`: its rigid body,
the viscous parts of the joints' friction, the arm spring, the motor's back-EMF, the actuator's gain and lag) is
linearized by Drake's ``Linearize`` at the upright, q = v = 0: d/dt s = A s + B u with s = [theta, phi,
theta_dot, phi_dot, (lagged torque)] (paper order, :func:`~furuta_drake.plant.plant_to_paper_permutation`) and u
the commanded arm torque [N m]. Coulomb levels, dead zones and saturation have no linearization at rest and are
left to the simulations; a cubic spring enters through its slope at phi = 0.

**Delay.** A delay tau = m h + tau' (0 <= tau' < h) of a command held over each period h gives (Astrom and
Wittenmark, Computer-Controlled Systems, Sec. 2.3)

    s_k+1 = Phi s_k + Gamma0 u_k-m + Gamma1 u_k-m-1,
    Gamma0 = int_0^(h - tau') e^(A t) dt B,   Gamma1 = e^(A (h - tau')) int_0^tau' e^(A t) dt B,

so the past commands u_k-1 ... u_k-N (N = m, plus one when tau' > 0) are states of the design model.

**Gain.** The rig's controller feeds back x = [theta, phi, theta_dot, phi_dot] (u = -K x, the contract's
``lqr_gain``), not the lag state nor the commands in flight. K minimises the LQ cost sum x^T Q x + R u^2 of the
design model over those four gains (output feedback, Levine and Athans 1970, in discrete time): from an initial
plant state of unit covariance with no command in flight, J(K) = trace(P X0), P the closed loop's cost matrix,
with the gradient 2 [(R + Gamma^T P Gamma) K S - Gamma^T P Phi] L S^T (L the closed loop's state covariance,
S the selection of x). Without delay and lag, it is the DARE's gain.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_discrete_lyapunov
from scipy.optimize import minimize

from furuta_drake.actuator import ActuatorParameters, DisturbanceParameters
from furuta_drake.config import SimulationConfig
from furuta_drake.controllers.lqr import zero_order_hold
from furuta_drake.errors import ConfigError
from furuta_drake.friction import FrictionParameters, JointFrictionParameters
from furuta_drake.world import linearized_world

PLANT_STATES = 4  # x = [theta, phi, theta_dot, phi_dot]
UNSTABLE = 1.0 - 1e-9  # a spectral radius at or above this is not a stabilising gain


@dataclass(frozen=True)
class DesignModel:
    """s_k+1 = ``Phi`` s_k + ``Gamma`` u_k at ``period`` [s]: s = [x (paper order), (lagged torque [N m]),
    u_k-1 ... u_k-N [N m]] and u the commanded arm torque [N m] (module docstring)."""

    Phi: np.ndarray
    Gamma: np.ndarray
    period: float
    delay: float  # [s]
    lag: float  # [s]

    @property
    def size(self) -> int:
        return self.Phi.shape[0]

    def feedback(self, K) -> np.ndarray:
        """The closed loop's matrix Phi - Gamma K S under u = -K x."""
        return self.Phi - self.Gamma @ self.select(K)

    def select(self, K) -> np.ndarray:
        """K (4 gains on x) as a row on the design model's state: K S."""
        row = np.zeros((1, self.size))
        row[0, :PLANT_STATES] = np.asarray(K, dtype=float).ravel()
        return row


def linear_world(config: SimulationConfig) -> SimulationConfig:
    """``config`` with what has a linearization at rest: friction's viscous parts, the spring's slope at phi = 0,
    the actuator's gain and lag (no delay, dead zone or saturation), no cogging nor torque beyond the vocabulary."""
    disturbance = config.disturbance
    slope = disturbance.arm_spring_stiffness + 3.0 * disturbance.arm_spring_cubic_stiffness * (
        disturbance.arm_spring_equilibrium**2
    )

    def viscous(joint: JointFrictionParameters) -> JointFrictionParameters:
        if joint.viscous == 0.0:
            return JointFrictionParameters()
        return JointFrictionParameters(model="static", viscous=joint.viscous)

    return dataclasses.replace(
        config,
        friction=FrictionParameters(arm=viscous(config.friction.arm), pendulum=viscous(config.friction.pendulum)),
        disturbance=DisturbanceParameters(arm_spring_stiffness=slope),
        actuator=ActuatorParameters(gain=config.actuator.gain, lag_time_constant=config.actuator.lag_time_constant),
    )


def upright_model(config: SimulationConfig) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of the corrected world at the upright from Drake's ``Linearize`` (module docstring): states
    [theta, phi, theta_dot, phi_dot, (lagged torque)], input the commanded arm torque [N m]."""
    linear = linear_world(config)
    return linearized_world(
        rig=linear.rig,
        friction=linear.friction,
        actuator=linear.actuator,
        disturbance=linear.disturbance,
        control_period=linear.control_period,
    )


def delayed_model(A: np.ndarray, B: np.ndarray, period: float, delay: float, lag: float = 0.0) -> DesignModel:
    """The sampled model of d/dt s = A s + B u(t - ``delay``) with u held over each ``period`` [s], the past
    commands as states (module docstring). ``lag`` [s] is recorded (it is a state of A already)."""
    if delay < 0 or not np.isfinite(delay):
        raise ConfigError(f"input delay must be a non-negative finite number of seconds, got {delay!r}")
    whole = int(np.floor(delay / period + 1e-9))
    fraction = max(delay - whole * period, 0.0)
    if fraction < 1e-9 * period:
        fraction = 0.0
    Phi, Gamma0 = zero_order_hold(A, B, period)  # e^(A h) and the response to an input held over h
    Gamma1 = np.zeros_like(Gamma0)
    if fraction > 0.0:
        late, Gamma0 = zero_order_hold(A, B, period - fraction)
        Gamma1 = late @ zero_order_hold(A, B, fraction)[1]
    extra = whole + (fraction > 0)
    n = A.shape[0]
    size = n + extra
    Phi_a, Gamma_a = np.zeros((size, size)), np.zeros((size, 1))
    Phi_a[:n, :n] = Phi
    # Column of u_k-j in the state (j >= 1); u_k itself is the input.
    for j, column in ((whole, Gamma0), (whole + 1, Gamma1)):
        if not column.any():
            continue
        if j == 0:
            Gamma_a[:n] = column
        else:
            Phi_a[:n, n + j - 1] = column[:, 0]
    if extra:
        Gamma_a[n, 0] = 1.0  # u_k-1 at the next step is this step's command
        for j in range(1, extra):
            Phi_a[n + j, n + j - 1] = 1.0
    return DesignModel(Phi_a, Gamma_a, period, float(delay), float(lag))


def design_model(config: SimulationConfig) -> DesignModel:
    """The design model of a corrected simulate config: Drake's linearization (:func:`upright_model`) sampled at
    its control period with its actuator delay."""
    A, B = upright_model(config)
    return delayed_model(A, B, config.control_period, config.actuator.delay, config.actuator.lag_time_constant)


def spectral_radius(matrix: np.ndarray) -> float:
    return float(np.max(np.abs(np.linalg.eigvals(matrix))))


def lq_cost(model: DesignModel, K, Q: np.ndarray, R: float) -> tuple[float, np.ndarray]:
    """(J, dJ/dK) of the gain K on x (module docstring); J = inf where K does not stabilise the model."""
    K = np.asarray(K, dtype=float).reshape(1, PLANT_STATES)
    closed = model.feedback(K)
    if spectral_radius(closed) >= UNSTABLE:
        return float("inf"), np.zeros(PLANT_STATES)
    n = model.size
    select = model.select(np.ones(PLANT_STATES)) != 0
    S = np.eye(n)[select[0]]
    weight = np.zeros((n, n))
    weight[:PLANT_STATES, :PLANT_STATES] = Q
    weight += R * (S.T @ K.T @ K @ S)
    P = solve_discrete_lyapunov(closed.T, weight)
    X0 = np.zeros((n, n))
    X0[:PLANT_STATES, :PLANT_STATES] = np.eye(PLANT_STATES)
    L = solve_discrete_lyapunov(closed, X0)
    G = model.Gamma
    gradient = 2.0 * ((R + G.T @ P @ G) @ K @ S - G.T @ P @ model.Phi) @ L @ S.T
    return float(np.trace(P @ X0)), gradient.ravel()


def output_lqr(model: DesignModel, Q, R: float, starts) -> np.ndarray:
    """The gain K (1x4, u = -K x [N m]) minimising the LQ cost of ``model`` (module docstring), by BFGS from the
    best of ``starts`` (gains on x); ConfigError when none of them stabilises the model."""
    Q = np.asarray(Q, dtype=float)
    if Q.ndim == 1:
        Q = np.diag(Q)
    costs = [(lq_cost(model, K, Q, R)[0], np.asarray(K, dtype=float).ravel()) for K in starts]
    finite = [(cost, K) for cost, K in costs if np.isfinite(cost)]
    if not finite:
        raise ConfigError(
            f"no starting gain stabilises the design model (delay {model.delay:g} s, lag {model.lag:g} s at a "
            f"{model.period:g} s period): the upright cannot be balanced by state feedback there"
        )
    start_cost, start = min(finite, key=lambda item: item[0])
    scale = np.where(
        np.abs(start) > 1e-9, start, 1e-9
    )  # optimise in relative gains (they span orders of magnitude) and in
    # the cost relative to the start's

    def cost(relative):
        J, gradient = lq_cost(model, relative * scale, Q, R)
        return (J / start_cost, gradient * scale / start_cost) if np.isfinite(J) else (1e6, np.zeros(PLANT_STATES))

    result = minimize(cost, np.ones(PLANT_STATES), jac=True, method="BFGS", options={"gtol": 1e-9, "maxiter": 500})
    best = result.x * scale
    if lq_cost(model, best, Q, R)[0] > lq_cost(model, start, Q, R)[0]:
        best = start
    return best.reshape(1, PLANT_STATES)
