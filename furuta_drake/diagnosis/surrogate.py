"""Fast batch surrogate of the Furuta pendulum with the vocabulary's effects, for fitting candidates.

Many short windows are integrated at once (numpy arrays over windows, fixed-step RK4 with substeps). The rigid
body is the full nonlinear Furuta model in the four lumped constants a = J_arm + m r^2, b = J_p + m l^2,
c = m l r, d = m g l (q = [theta, phi], theta = 0 upright):

    [b,            c cos(theta)     ] [theta'']   [ d sin(theta) + b sin(theta) cos(theta) phi'^2 + tau_theta ]
    [c cos(theta), a + b sin^2(theta)] [phi''  ] = [ c sin(theta) theta'^2
                                                     - 2 b sin(theta) cos(theta) theta' phi' + tau_phi         ]

(a test checks it against Drake's MultibodyPlant). Friction uses the laws of :mod:`furuta_drake.friction`
(static model with a regularisation velocity of ``REGULARIZATION_VELOCITY``, the same in the Drake replay).
The held-out figures of a report come from the Drake diagram (:mod:`furuta_drake.diagnosis.replay`), not
from here.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from furuta_drake.friction import (
    JointFrictionParameters,
    bristle_friction_torque,
    dahl_exact_step,
    static_friction_torque,
    stribeck_curve,
)
from furuta_drake.rig import RigParameters

REGULARIZATION_VELOCITY = 0.02  # [rad/s] smooth sign(v) for the static friction laws of the diagnosis models


@dataclass(frozen=True)
class Model:
    """The nominal rig plus effect parameters, all in SI units (see the effect vocabulary)."""

    a: float
    b: float
    c: float
    d: float
    arm_friction: JointFrictionParameters
    pendulum_friction: JointFrictionParameters
    back_emf_damping: float = 0.0  # kt ke / R [N m s/rad]
    gain: float = 1.0
    deadzone: float = 0.0  # [N m]
    deadzone_form: str = "subtract"  # "subtract": u - sat(u); "threshold": u where |u| > deadzone, else 0
    saturation: float = np.inf  # [N m]
    saturation_form: str = "hard"  # "hard": clip(u, -L, L); "smooth": L tanh(u / L)
    delay: float = 0.0  # [s]
    lag: float = 0.0  # [s]
    spring_stiffness: float = 0.0  # [N m/rad]
    spring_equilibrium: float = 0.0  # [rad]
    spring_cubic: float = 0.0  # [N m/rad^3]: the spring's torque is -(k x + k3 x^3), x = phi - phi_0
    counts_per_rev: int = 4096
    noise_std: float = 0.0  # [rad]
    rig_constants: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)  # the rig file's (a, b, c, d)

    @classmethod
    def from_rig(cls, rig: RigParameters) -> Model:
        def joint(coulomb, viscous):
            return JointFrictionParameters(
                model="static",
                coulomb_pos=coulomb,
                coulomb_neg=coulomb,
                viscous=viscous,
                regularization_velocity=REGULARIZATION_VELOCITY,
            )

        constants = (rig.arm_inertia_total, rig.pendulum_inertia_total, rig.coupling, rig.gravity_torque)
        return cls(
            *constants,
            rig_constants=constants,
            arm_friction=joint(rig.arm_coulomb, rig.arm_viscous),
            pendulum_friction=joint(rig.pendulum_coulomb, rig.pendulum_viscous),
            back_emf_damping=0.0 if rig.motor is None else rig.motor.back_emf_damping,
            counts_per_rev=rig.counts_per_rev,
        )

    def replace(self, **changes) -> Model:
        return dataclasses.replace(self, **changes)


def sensor_variance(model: Model, nominal_counts: int) -> float:
    """Expected variance [counts^2 of the nominal encoder] of a measured angle about the true one: the
    model's quantisation step^2 / 12 plus its white noise."""
    count = 2 * np.pi / nominal_counts
    step = 2 * np.pi / model.counts_per_rev
    return (step / count) ** 2 / 12.0 + (model.noise_std / count) ** 2


def applied_torque(model: Model, command: np.ndarray) -> np.ndarray:
    """The actuator's static map after delay and lag: dead zone (u - sat(u), or u where |u| exceeds it), gain,
    saturation (a clip, or L tanh(u / L))."""
    u = command
    if model.deadzone > 0:
        u = (
            command - np.clip(command, -model.deadzone, model.deadzone)
            if model.deadzone_form == "subtract"
            else np.where(np.abs(command) > model.deadzone, command, 0.0)
        )
    u = model.gain * u if model.gain != 1.0 else u
    if not np.isfinite(model.saturation):
        return u
    if model.saturation_form == "smooth":
        return model.saturation * np.tanh(u / model.saturation)
    return np.clip(u, -model.saturation, model.saturation)


def spring_torque(model: Model, phi):
    """The arm spring's torque -(k x + k3 x^3), x = phi - phi_0 [N m]."""
    stretch = phi - model.spring_equilibrium
    return -(model.spring_stiffness + model.spring_cubic * stretch**2) * stretch


def _acts(p: JointFrictionParameters) -> bool:
    return p.model == "static" and (
        p.coulomb_pos > 0 or p.coulomb_neg > 0 or p.viscous > 0 or bool(p.static_pos) or bool(p.static_neg)
    )


def _accelerations(
    model: Model, x: np.ndarray, tau_arm: np.ndarray, arm_friction: bool = True, pendulum_friction: bool = True
) -> np.ndarray:
    """x' of the Furuta model (module docstring); the flags skip friction terms known to be zero."""
    theta, phi, theta_dot, phi_dot = x
    s, c_ = np.sin(theta), np.cos(theta)
    sc = s * c_
    tau_phi = tau_arm
    if arm_friction:
        tau_phi = tau_phi + static_friction_torque(phi_dot, model.arm_friction)
    if model.back_emf_damping:
        tau_phi = tau_phi - model.back_emf_damping * phi_dot
    if model.spring_stiffness or model.spring_cubic:
        tau_phi = tau_phi + spring_torque(model, phi)
    m12, m22 = model.c * c_, model.a + model.b * s * s
    r1 = model.d * s + model.b * sc * phi_dot**2
    if pendulum_friction:
        r1 = r1 + static_friction_torque(theta_dot, model.pendulum_friction)
    r2 = model.c * s * theta_dot**2 - 2.0 * model.b * sc * theta_dot * phi_dot + tau_phi
    det = model.b * m22 - m12 * m12
    return np.array([theta_dot, phi_dot, (m22 * r1 - m12 * r2) / det, (model.b * r2 - m12 * r1) / det])


def _delayed_command(command, starts, t, dt, period, delay):
    """The held command delayed by ``delay``, averaged over [t, t + dt) (relative to each window's start):
    a fractional delay moves the switch inside the step, so the step sees the time-weighted mix. ``t`` may be
    a column of times (one row per step)."""
    position = (t - delay) / period + 1e-9
    first = np.floor(position).astype(int)
    switch = (first + 1) * period + delay  # time the next held value starts
    late = np.clip((t + dt - switch) / dt, 0.0, 1.0)
    last = command.size - 1
    current = command[np.clip(starts + first, 0, last)]
    following = command[np.clip(starts + first + 1, 0, last)]
    return (1.0 - late) * current + late * following


def _bristle_levels(displacement, velocity, p: JointFrictionParameters):
    """The level the bristle saturates at: Fc of the direction (Dahl, Eq. 7) or g(v) (LuGre) [N m]."""
    if p.model == "dahl":
        return np.maximum(np.where(displacement > 0, p.coulomb_pos, p.coulomb_neg), 1e-12)
    return np.maximum(stribeck_curve(velocity, p), 1e-12)


def bristle_step(z, displacement, velocity, p: JointFrictionParameters):
    """The arm's bristle state after the joint moved by ``displacement`` [rad] at ``velocity`` [rad/s] in one
    direction. Dahl (Eq. 7) is rate independent, so z follows the path alone (exact for a monotone move); LuGre
    relaxes towards g(v) / sigma0 with the Stribeck level g of the step's velocity held."""
    return dahl_exact_step(z, displacement, 1.0, p.sigma0, _bristle_levels(displacement, velocity, p))


def bristle_path(path: np.ndarray, p: JointFrictionParameters, period: float) -> np.ndarray:
    """The arm's bristle state [rad] at every sample of a measured (smoothed) arm angle path sampled every
    ``period`` [s], from z = 0 at the first sample (:func:`bristle_step` per sample, a scalar loop)."""
    step = np.diff(path, prepend=path[0])
    levels = _bristle_levels(step, step / period, p).tolist()
    z = np.empty(path.size)
    zi, s0 = 0.0, p.sigma0
    for i, (d, level) in enumerate(zip(step.tolist(), levels)):
        if d != 0.0:
            zi = dahl_exact_step(zi, d, 1.0, s0, level)
        z[i] = zi
    return z


def rk4_substep(
    model: Model, x: np.ndarray, z: np.ndarray, tau: np.ndarray, dt: float, arm: bool, pendulum: bool
) -> tuple[np.ndarray, np.ndarray]:
    """One RK4 substep of length ``dt`` [s] of every column of ``x`` (4, W) under the applied torque ``tau``
    (W,) [N m] held over it; ``z`` (W,) is the arm's bristle state (Dahl or LuGre arm only, else unused).
    ``arm``, ``pendulum``: whether each joint's friction acts (:func:`_acts`). At every stage the bristle is its
    exact step from the substep's start over the stage's arm displacement (:func:`bristle_step`), so the stiff
    bristle needs no step of its own. Returns the state and bristle at the substep's end."""
    p = model.arm_friction
    bristles = p.has_bristles

    def stage(state):
        torque = tau
        if bristles:
            torque = tau + bristle_friction_torque(bristle_step(z, state[1] - x[1], state[3], p), state[3], p)
        return _accelerations(model, state, torque, arm, pendulum)

    k1 = stage(x)
    k2 = stage(x + 0.5 * dt * k1)
    k3 = stage(x + 0.5 * dt * k2)
    k4 = stage(x + dt * k3)
    x_next = x + dt / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    if bristles:
        moved = x_next[1] - x[1]
        z = bristle_step(z, moved, moved / dt, p)
    return x_next, z


def predict_windows(
    model: Model,
    x0: np.ndarray,
    command: np.ndarray,
    starts: np.ndarray,
    horizon: int,
    period: float,
    substeps: int,
    bristle0: np.ndarray | None = None,
) -> np.ndarray:
    """Angles [theta, phi] predicted at ``horizon`` samples after each window start.

    ``x0``: (4, W) initial states; ``command``: the whole log's torque command (ZOH over each period);
    ``starts``: (W,) sample index of each window; ``bristle0``: (W,) the arm's bristle state at each start
    (a Dahl or LuGre arm only: at every RK4 stage the bristle is its exact step from the substep's start over the
    stage's arm displacement, :func:`rk4_substep`).
    Returns (horizon, 2, W); row k is the prediction at start + k (row 0 is the initial angle). The fixed-step
    RK4 is written here because scipy's ODE solvers integrate one system at a time: here one step advances
    every window at once, as numpy arrays over windows.
    """
    dt = period / substeps
    x = np.array(x0, dtype=float)
    steps = (horizon - 1) * substeps
    times = (np.arange(steps) * dt)[:, None]
    held = _delayed_command(command, starts[None, :], times, dt, period, model.delay)  # (steps, W)
    if model.lag > 0:  # exact first-order filter of the held input; a substep takes the filter's mean over it
        decay = np.exp(-dt / model.lag)
        mean = model.lag / dt * (1.0 - decay)  # the mean of exp(-t / lag) over [0, dt)
        lag_state = command[starts].astype(float)
        for i in range(steps):
            start, lag_state = lag_state, held[i] + (lag_state - held[i]) * decay
            held[i] = held[i] + (start - held[i]) * mean
    torque = applied_torque(model, held)
    arm, pendulum = _acts(model.arm_friction), _acts(model.pendulum_friction)
    z = np.zeros(x.shape[1]) if bristle0 is None else np.array(bristle0, dtype=float)
    out = np.empty((horizon, 2, x.shape[1]))
    out[0] = x[:2]
    for i in range(steps):
        x, z = rk4_substep(model, x, z, torque[i], dt, arm, pendulum)
        if (i + 1) % substeps == 0:
            out[(i + 1) // substeps] = x[:2]
    return out
