"""Fast batch surrogate of the Furuta pendulum with the vocabulary's effects, for fitting candidates.

Many short windows are integrated at once (fixed-step RK4 with substeps, compiled in
:mod:`~furuta_drake.effects.surrogate_kernel`). The rigid
body is the full nonlinear Furuta model in the four lumped constants a = J_arm + m r^2, b = J_p + m l^2,
c = m l r, d = m g l (q = [theta, phi], theta = 0 upright):

    [b,            c cos(theta)     ] [theta'']   [ d sin(theta) + b sin(theta) cos(theta) phi'^2 + tau_theta ]
    [c cos(theta), a + b sin^2(theta)] [phi''  ] = [ c sin(theta) theta'^2
                                                     - 2 b sin(theta) cos(theta) theta' phi' + tau_phi         ]

(a test checks it against Drake's MultibodyPlant). Friction uses the laws of :mod:`furuta_drake.friction`
(static model with a regularisation velocity of ``REGULARIZATION_VELOCITY``, the same in the Drake replay).
The held-out figures of a report come from the Drake diagram (:mod:`furuta_drake.diagnosis.gap.replay`), not
from here.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

from furuta_drake.effects import drive_kernel, drive_tangent
from furuta_drake.effects import surrogate_kernel as kernel
from furuta_drake.effects import surrogate_tangent as tangent
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.rig import RigParameters, encoder_resolution

REGULARIZATION_VELOCITY = 0.02  # [rad/s] smooth sign(v) for the static friction laws of the diagnosis models
LAG_PREROLL = 5.0  # time constants of command history the lag filter runs over before a window (e^-5 of its
# initial error left)
LUMPED_CONSTANTS = ("arm_inertia_total", "pendulum_inertia_total", "coupling", "gravity_torque")  # a, b, c, d
HISTORY = 256  # samples of command history a window may read before its start (delay, lag pre-roll)


@dataclass(frozen=True)
class Model:
    """The nominal rig plus effect parameters, all in SI units (see the effect vocabulary); its rigid body in the
    four lumped constants (``LUMPED_CONSTANTS``, the module docstring's a, b, c, d)."""

    arm_inertia_total: float  # a = J_arm + m r^2 [kg m^2]
    pendulum_inertia_total: float  # b = J_p + m l^2 [kg m^2]
    coupling: float  # c = m l r [kg m^2]
    gravity_torque: float  # d = m g l [N m]
    arm_friction: JointFrictionParameters
    pendulum_friction: JointFrictionParameters
    back_emf_damping: float = 0.0  # kt ke / R [N m s/rad]
    gain: float = 1.0
    deadzone: float = 0.0  # [N m]
    deadzone_form: str = "subtract"  # "subtract": u - sat(u); "threshold": u where |u| > deadzone, else 0
    saturation: float = np.inf  # [N m]
    saturation_form: str = "hard"  # "hard": clip(u, -L, L); "smooth": L tanh(u / L)
    delay: float = 0.0  # [s]; with a spread, the mean of a delay drawn anew every sample
    delay_spread: float = 0.0  # [s] std of that delay, uniform over delay +- sqrt(3) delay_spread; 0: fixed
    lag: float = 0.0  # [s]
    spring_stiffness: float = 0.0  # [N m/rad]
    spring_equilibrium: float = 0.0  # [rad]
    spring_cubic: float = 0.0  # [N m/rad^3]: the spring's torque is -(k x + k3 x^3), x = phi - phi_0
    counts_per_rev: int = 4096
    noise_std: float = 0.0  # [rad]
    noise_correlation_time: float = 0.0  # [s] first-order low-passed noise (an interface that filters); 0: white
    rig_constants: tuple[float, float, float, float] = (0.0, 0.0, 0.0, 0.0)  # the rig file's (a, b, c, d)
    unmodelled_terms: tuple[tuple[int, int, float], ...] = ()  # (joint: 0 arm, 1 pendulum; term of
    # torque_library.TERMS; coefficient [N m]): a torque the vocabulary does not hold
    rotor_share: float = 0.0  # J_m N^2 / a [-]: the drive's rotor's share of a (0: no drive)
    drive_backlash: float = 0.0  # b [rad], arm side
    drive_stiffness: float = 0.0  # k [N m/rad]; 0: rigid, or with backlash the tooth contact (drive.tooth_contact)
    drive_damping: float = 0.0  # c [N m s/rad], with a stiffness
    drive_encoder: str = "arm"  # "motor": the logged arm angle is the rotor's

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
        drive = rig.drive
        return cls(
            *constants,
            rig_constants=constants,
            arm_friction=joint(rig.arm_coulomb, rig.arm_viscous),
            pendulum_friction=joint(rig.pendulum_coulomb, rig.pendulum_viscous),
            back_emf_damping=0.0 if rig.motor is None else rig.motor.back_emf_damping,
            counts_per_rev=rig.counts_per_rev,
            rotor_share=0.0 if drive is None else drive.reflected_inertia / rig.arm_inertia_total,
            drive_backlash=0.0 if drive is None else drive.backlash,
            drive_stiffness=0.0 if drive is None or drive.stiffness is None else drive.stiffness,
            drive_damping=0.0 if drive is None else drive.damping,
            drive_encoder="arm" if drive is None else drive.encoder,
        )

    def replace(self, **changes) -> Model:
        return dataclasses.replace(self, **changes)

    @property
    def has_drive(self) -> bool:
        """Whether the model's drive has a state of its own (backlash or a spring between a rotor and the arm):
        its windows then carry the twist [delta, delta'] and run in :mod:`~.drive_kernel`."""
        return self.rotor_share > 0 and (self.drive_backlash > 0 or self.drive_stiffness > 0)

    @property
    def hidden_states(self) -> int:
        """The window states beyond [theta, phi, theta', phi']: the arm's bristle z (a Dahl or LuGre arm), then the
        drive's twist delta [rad] and its rate [rad/s] (:attr:`has_drive`)."""
        return int(self.arm_friction.has_bristles) + 2 * int(self.has_drive)


def split_states(model: Model, x: np.ndarray) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None]:
    """(the arm and pendulum states x[:4]; the bristle row or None; the twist rows (2, W) or None) of window states
    ``x`` (4 + ``model.hidden_states``, W) laid out as :attr:`Model.hidden_states` says."""
    bristle = x[4] if model.arm_friction.has_bristles else None
    twist = x[-2:] if model.has_drive else None
    return x[:4], bristle, twist


def sensor_variance(model: Model, nominal_counts: int) -> float:
    """Expected variance [counts^2 of the nominal encoder] of a measured angle about the true one: the
    model's quantisation step^2 / 12 plus its white noise."""
    count = encoder_resolution(nominal_counts)
    step = encoder_resolution(model.counts_per_rev)
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
    """The arm spring's torque at the arm angles ``phi`` [N m] (:func:`~.surrogate_kernel.spring_torque`)."""
    return np.vectorize(kernel.spring_torque)(phi, model.spring_stiffness, model.spring_cubic, model.spring_equilibrium)


def _accelerations(model: Model, x: np.ndarray, tau) -> np.ndarray:
    """x' of the Furuta model (module docstring) at ``x`` (4,) or (4, W) under the arm torque ``tau`` [N m]; each
    joint's static friction law acts where the joint has one (a Dahl or LuGre arm's bristle torque comes in
    ``tau``)."""
    states = np.asarray(x, dtype=float)
    columns = states.reshape(4, -1)
    torque = np.broadcast_to(np.asarray(tau, dtype=float), columns.shape[1:])
    return kernel.derivatives(columns, np.ascontiguousarray(torque), *kernel.pack(model)).reshape(states.shape)


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


def _held_integrals(command: np.ndarray, period: float):
    """(mean, C, C2) of a command held over each ``period``: its mean, and the first and second integrals of the
    held command less that mean from sample 0, as functions of the time [s] (the ends held beyond the log)."""
    mean = float(np.mean(command))
    steps = command - mean
    first = np.concatenate([[0.0], np.cumsum(steps)]) * period  # C at k T
    second = np.concatenate([[0.0], np.cumsum(first[:-1] * period + steps * period**2 / 2.0)])  # C2 at k T

    def at(tau):
        k = np.clip(np.floor(tau / period), 0, command.size - 1).astype(int)
        offset = tau - k * period
        return k, offset

    def once(tau):
        k, offset = at(tau)
        return first[k] + steps[k] * offset

    def twice(tau):
        k, offset = at(tau)
        return second[k] + first[k] * offset + steps[k] * offset**2 / 2.0

    return mean, once, twice


def jitter_width(model: Model) -> float:
    """The width [s] of the uniform delay of ``model``'s jittering delay: sqrt(12) times its spread."""
    return float(np.sqrt(12.0) * model.delay_spread)


def expected_command(command, starts, t, dt, period, model: Model):
    """The applied command of ``model``'s input delay, averaged over [t, t + dt) (relative to each window's start):
    the held command delayed by ``model.delay`` (:func:`_delayed_command`), or, with a ``delay_spread``, its
    expectation over a delay uniform on delay +- sqrt(3) delay_spread, drawn anew at every instant (a USB link, a
    scheduler): the mean of u(s - D) over s in [t, t + dt) and D in that interval, exact through the held command's
    second integral."""
    if model.delay_spread <= 0:
        return _delayed_command(command, starts, t, dt, period, model.delay)
    width = jitter_width(model)
    mean, _, twice = _held_integrals(command, period)
    tau = np.asarray(starts) * period + t - model.delay  # the undelayed time of the substep's start
    low, high = tau - width / 2.0, tau + width / 2.0
    return mean + (twice(high + dt) - twice(low + dt) - twice(high) + twice(low)) / (dt * width)


def expected_command_points(command: np.ndarray, period: float, model: Model) -> tuple[np.ndarray, np.ndarray]:
    """(times [s] from the log's first sample, values [N m]) of the expected command of a jittering delay, which is
    linear between them: the held command averaged over the uniform delay's width, whose slope changes only where
    an edge of that width crosses a sample."""
    width = jitter_width(model)
    mean, once, _ = _held_integrals(command, period)
    edges = np.arange(command.size + 1) * period + model.delay
    times = np.unique(np.round(np.concatenate([edges - width / 2.0, edges + width / 2.0]), 12))
    tau = times - model.delay
    return times, mean + (once(tau + width / 2.0) - once(tau - width / 2.0)) / width


def bristle_path(path: np.ndarray, p: JointFrictionParameters, period: float) -> np.ndarray:
    """The arm's bristle state [rad] at every sample of a measured (smoothed) arm angle path sampled every
    ``period`` [s], from z = 0 at the first sample (the kernel's exact bristle step per sample)."""
    return kernel.bristle_path(np.ascontiguousarray(path, dtype=float), period, kernel.pack_friction(p))


def lag_states(model: Model, command: np.ndarray, starts: np.ndarray, period: float, substeps: int) -> np.ndarray:
    """The actuator lag's state [N m] at each window start (W,): its filter run over the (delayed) command's last
    ``LAG_PREROLL`` time constants, at most ``HISTORY`` samples, from the command there. The command's past is
    known, so the lag's state is not a hidden state to estimate (a start at the current command misreads every
    window that opens while the command moves)."""
    dt = period / substeps
    early = np.arange(-min(int(np.ceil(LAG_PREROLL * model.lag / dt)), HISTORY * substeps), 0) * dt
    past = expected_command(command, np.asarray(starts)[None, :], early[:, None], dt, period, model)
    return kernel.lag_filter(past, past[0].copy(), model.lag, dt)[1]


INPUT_CHAIN = ("delay", "delay_spread", "lag", "deadzone", "deadzone_form", "gain", "saturation", "saturation_form")
# the fields of a Model that :func:`window_torques` reads


def predict_windows(
    model: Model,
    x0: np.ndarray,
    command: np.ndarray,
    starts: np.ndarray,
    horizon: int,
    period: float,
    substeps: int,
    bristle0: np.ndarray | None = None,
    twist0: np.ndarray | None = None,
) -> np.ndarray:
    """Angles [theta, phi] predicted at ``horizon`` samples after each window start.

    ``x0``: (4, W) initial states; ``command``: the whole log's torque command (ZOH over each period), with
    ``HISTORY`` samples before every start (the delay and the lag read the command's past);
    ``starts``: (W,) sample index of each window; ``bristle0``: (W,) the arm's bristle state at each start
    (a Dahl or LuGre arm only); ``twist0``: (2, W) the drive's twist and its rate (a drive of its own state only).
    Returns (horizon, 2, W); row k is the prediction at start + k (row 0 is the initial angle). The input chain
    (delay, lag, static map) is evaluated for every substep at once (:func:`window_torques`); the fixed-step RK4
    is the compiled :func:`~.surrogate_kernel.integrate` (scipy's ODE solvers integrate one system at a time and
    cost far more per step than these windows' short, smooth intervals need).
    """
    torque = window_torques(model, command, starts, horizon, period, substeps)
    return integrate_windows([model], x0, torque, period, substeps, bristle0, twist0)


def window_torques(
    model: Model, command, starts, horizon: int, period: float, substeps: int, change: np.ndarray | None = None
) -> np.ndarray:
    """The arm torque [N m] of ``model``'s input chain (delay, lag, static map) at every substep of every window
    (steps, W) (each window's column depends on its own start alone); ``change`` (horizon - 1, W) [N m], or None,
    is added to each sample's applied command before the lag and the static map (a command impulse)."""
    dt = period / substeps
    times = (np.arange((horizon - 1) * substeps) * dt)[:, None]
    held = expected_command(command, starts[None, :], times, dt, period, model)  # (steps, W)
    if change is not None:
        held = held + np.repeat(change, substeps, axis=0)
    if model.lag > 0:
        held = kernel.lag_filter(held, lag_states(model, command, starts, period, substeps), model.lag, dt)[0]
    return applied_torque(model, held)


def integrate_windows(
    models: list[Model], x0: np.ndarray, torque: np.ndarray, period: float, substeps: int, bristle0=None, twist0=None
) -> np.ndarray:
    """Angles (horizon, 2, W) of windows from ``x0`` (4, W) under their arm torques ``torque`` (steps, W) at every
    substep (:func:`window_torques`), model m from its m-th block of W / M windows (the models, holding the same
    number of unmodelled torque terms, in one kernel call); every window's angles are those of its model alone.
    Models with a drive of their own state (:attr:`Model.has_drive`) start from the twist ``twist0`` (2, W) and run
    in :mod:`~.drive_kernel` (the angles read: the rotor's for an encoder on the motor)."""
    x = np.ascontiguousarray(x0, dtype=float)
    z = np.zeros(x.shape[1]) if bristle0 is None else np.array(bristle0, dtype=float)
    torque = np.ascontiguousarray(torque, dtype=float)
    if models[0].has_drive:
        twist = np.zeros((2, x.shape[1])) if twist0 is None else twist0
        rows = drive_kernel.pack_drive_rows(models)
        return drive_kernel.integrate(np.vstack([x, twist]), z, torque, period / substeps, substeps, *rows)[0]
    return kernel.integrate(x, z, torque, period / substeps, substeps, *kernel.pack_rows(models))[0]


@dataclass(frozen=True)
class WindowInputs:
    """What a batch of windows feeds the surrogate besides their states: the command every window reads [N m]
    (held over each sample, ``HISTORY`` samples of it before every start), the windows' starts (W,) in it, their
    samples, the sample period [s] and the RK4 substeps per sample."""

    command: np.ndarray
    starts: np.ndarray
    horizon: int
    period: float
    substeps: int

    def torque(self, model: Model, change: np.ndarray | None = None) -> np.ndarray:
        """:func:`window_torques` of ``model``'s input chain on these windows (steps, W) [N m]."""
        return window_torques(model, self.command, self.starts, self.horizon, self.period, self.substeps, change)


@dataclass(frozen=True)
class BatchPrediction:
    """A batch of windows predicted: their angles, the arm torque they were integrated under and, when asked for,
    the angles' derivatives in the windows' initial states or along parameter directions."""

    angles: np.ndarray  # (horizon, 2, W) [rad]
    torque: np.ndarray  # (steps, W) [N m] at every substep
    slopes: np.ndarray | None = None  # (horizon, 2, W, n) per unit of state, or (horizon, 2, W, K) per direction


def predict_batch(
    models: Model | list[Model],
    x: np.ndarray,
    inputs: WindowInputs,
    torque: np.ndarray | None = None,
    states: bool = False,
    directions: tuple[np.ndarray, list] | None = None,
) -> BatchPrediction:
    """The windows of ``inputs`` predicted from their whole states ``x`` (4 + :attr:`Model.hidden_states`, M W),
    model m from its m-th block of W columns (one model: all of them), in one kernel call: under ``torque``
    (steps, M W) [N m], else under each model's input chain (evaluated once per distinct chain, ``INPUT_CHAIN``:
    the models of a finite-difference Jacobian's columns mostly differ in their dynamics alone). With ``states``
    (one model): the angles' derivatives in x (:func:`state_sensitivities`); with ``directions`` = (rows,
    torques) (one model): along parameter directions (:func:`parameter_sensitivities`)."""
    models = [models] if isinstance(models, Model) else list(models)
    if torque is None:
        torques: dict[tuple, np.ndarray] = {}
        chains = [tuple(getattr(model, name) for name in INPUT_CHAIN) for model in models]
        for model, chain in zip(models, chains):
            if chain not in torques:
                torques[chain] = inputs.torque(model)
        torque = torques[chains[0]] if len(models) == 1 else np.concatenate([torques[c] for c in chains], axis=1)
    _, bristle, twist = split_states(models[0], x)
    period, substeps = inputs.period, inputs.substeps
    if directions is not None:
        rows, changes = directions
        angles, slopes = parameter_sensitivities(models[0], x[:4], torque, period, substeps, bristle, rows, changes)
    elif states:
        angles, slopes = state_sensitivities(models[0], x[:4], torque, period, substeps, bristle, twist)
    else:
        angles, slopes = integrate_windows(models, x[:4], torque, period, substeps, bristle, twist), None
    return BatchPrediction(angles, torque, slopes)


def initial_states(
    model: Model, smoothed: np.ndarray, arm_path: np.ndarray, command: np.ndarray, period: float, starts: np.ndarray
) -> np.ndarray:
    """A log's window states for ``model`` (4 + :attr:`Model.hidden_states`, W): the smoothed [theta, phi, theta',
    phi'] (4, W) at the window ``starts``, then the arm's bristle (:func:`bristle_starts`) and the drive's twist
    (:func:`twist_starts`) read from the log's smoothed arm angle ``arm_path`` [rad] and ``command`` [N m] (one
    sample every ``period`` [s]); with the encoder on the motor the smoothed arm angle and rate are the rotor's,
    the arm's those less the twist's."""
    x = smoothed
    if model.arm_friction.has_bristles:
        x = np.vstack([x, bristle_starts(model, arm_path, period, starts)])
    if model.has_drive:
        twist = twist_starts(model, arm_path, command, period, starts)
        if model.drive_encoder == "motor":
            x = x.copy()
            x[[1, 3]] -= twist
        x = np.vstack([x, twist])
    return x


def bristle_starts(model: Model, arm_path: np.ndarray, period: float, starts: np.ndarray) -> np.ndarray:
    """The arm's bristle state [rad] (W,) at the window ``starts`` of a log whose smoothed arm angle is
    ``arm_path`` [rad] (a Dahl or LuGre arm): the Dahl law is rate independent, so the bristle depends on the path
    of phi alone (LuGre's also on its speed). The windows refine it (a hidden state)."""
    return bristle_path(arm_path, model.arm_friction, period)[starts]


def twist_starts(
    model: Model, arm_path: np.ndarray, command: np.ndarray, period: float, starts: np.ndarray
) -> np.ndarray:
    """The drive's twist [delta, delta'] [rad, rad/s] (2, W) at the window ``starts`` of a log (a drive of its own
    state): with the rotor following the arm, the coupling passes T = u - d phi' - J phi'' (u the applied
    ``command``, d the back-EMF damping, J the rotor's inertia), so the twist is T / k beyond the backlash on the
    side T pushes, b sign(T) + T / k (k the drive's or the tooth contact's stiffness), and its rate the path's of
    that twist. The windows refine both (hidden states)."""
    row = drive_kernel.pack_drive(model)
    rotor, backlash = row[drive_kernel.D_INERTIA], row[drive_kernel.D_BACKLASH]
    stiffness = row[drive_kernel.D_STIFFNESS]
    rate = np.gradient(arm_path, period)
    passed = applied_torque(model, command) - model.back_emf_damping * rate - rotor * np.gradient(rate, period)
    twist = backlash * np.sign(passed) + passed / stiffness
    return np.vstack([twist, np.gradient(twist, period)])[:, starts]


def state_sensitivities(
    model: Model, x0: np.ndarray, torque: np.ndarray, period: float, substeps: int, bristle0=None, twist0=None
) -> tuple[np.ndarray, np.ndarray]:
    """(the angles (horizon, 2, W) of :func:`integrate_windows` of ``model`` alone; their derivatives
    (horizon, 2, W, n) in each window's initial theta, phi [rad], theta', phi' [rad/s] and, with ``bristle0``, the
    arm's bristle z [rad] (n = 4 or 5)): the RK4's exact forward sensitivities
    (:func:`~.surrogate_tangent.tangents`), in one pass; with a drive of its own state also in the twist ``twist0``
    [rad, rad/s] (n = 6 or 7), the flow's through the teeth's engagements (:func:`~.drive_tangent.state_tangents`)."""
    if model.has_drive:
        x = np.vstack([x0, np.zeros((2, np.shape(x0)[1])) if twist0 is None else twist0])
        z = np.zeros(np.shape(x0)[1]) if bristle0 is None else bristle0
        rows = drive_kernel.pack_drive_rows([model])
        return drive_tangent.state_tangents(x, z, torque, period / substeps, substeps, rows, bristle0 is not None)
    n = 4 if bristle0 is None else 5
    return _tangents(model, x0, torque, period, substeps, bristle0, np.eye(n, tangent.STATE))


def parameter_sensitivities(
    model: Model, x0, torque, period: float, substeps: int, bristle0, rows: np.ndarray, torques: list
) -> tuple[np.ndarray, np.ndarray]:
    """(the angles (horizon, 2, W) of :func:`integrate_windows` of ``model`` alone; their derivatives
    (horizon, 2, W, K) along K parameter directions from the same initial states): direction k changes the packed
    parameters by ``rows[k]`` (:func:`~.surrogate_tangent.flat` of ``model``) and the arm torque by ``torques[k]``
    (steps, W) [N m], or not where None; the RK4's exact forward sensitivities, in one pass."""
    seeds = np.zeros((len(rows), tangent.STATE))
    return _tangents(model, x0, torque, period, substeps, bristle0, seeds, rows, torques)


def _tangents(model, x0, torque, period, substeps, bristle0, seeds, rows=None, torques=None):
    """:func:`~.surrogate_tangent.tangents` of ``model`` from ``x0`` and ``bristle0`` (None: zero)."""
    z = np.zeros(np.shape(x0)[1]) if bristle0 is None else bristle0
    packed = kernel.pack(model)
    return tangent.tangents(x0, z, torque, period / substeps, substeps, packed, seeds, rows, torques)


def same_branches(model: Model, other: Model) -> bool:
    """Whether the surrogate is differentiable along the way from ``model`` to ``other``: the kernel takes the same
    branches for both (friction kinds, Stribeck curves, LuGre's bristle damping, the unmodelled terms' joints and
    library terms, the input chain's forms), no threshold dead zone's width differs (its torque jumps where the
    width crosses a command) and neither has a drive of its own state (the parameters' tangent kernel has no
    drive: a drive model's parameter columns are differenced)."""
    if model.has_drive or other.has_drive:  # the coupling law is not smooth
        return False
    rows, others = kernel.pack(model), kernel.pack(other)
    for row, changed in zip(rows[1:3], others[1:3]):
        if row[kernel.F_KIND] != changed[kernel.F_KIND] or row[kernel.F_STRIBECK] != changed[kernel.F_STRIBECK]:
            return False
        if (row[kernel.F_SIGMA1] == 0.0) != (changed[kernel.F_SIGMA1] == 0.0):
            return False
    if rows[3].shape != others[3].shape or not np.array_equal(rows[3][:, :2], others[3][:, :2]):
        return False
    forms = ("deadzone_form", "saturation_form")
    if any(getattr(model, name) != getattr(other, name) for name in forms):
        return False
    return model.deadzone_form != "threshold" or model.deadzone == other.deadzone


def load_kernel() -> None:
    """Compile the kernel's functions for the argument types of :func:`predict_windows` and
    :func:`state_sensitivities` in this process (or load them from numba's cache), e.g. before worker processes
    are forked, which then inherit them instead of each compiling or loading its own. Their checked variants too
    (a window from a non-finite state runs checked): a fit whose prediction diverges needs them, and a worker that
    compiled one itself would do so mid-run, in every worker that meets such a fit."""
    model = Model(
        1e-3, 1e-4, 5e-5, 1e-2, JointFrictionParameters.dahl(1e-3, 1e-3, sigma0=1.0), JointFrictionParameters()
    )
    command, starts = np.zeros(HISTORY + 8), np.array([HISTORY])
    bristle_path(command, model.arm_friction, 1e-3)
    for x0 in (np.zeros((4, 1)), np.full((4, 1), np.nan)):
        predict_windows(model.replace(lag=1e-3), x0, command, starts, 3, 1e-3, 1, np.zeros(1))
        state_sensitivities(model, x0, np.zeros((2, 1)), 1e-3, 1, np.zeros(1))
    geared = model.replace(rotor_share=0.5, drive_backlash=1e-3)
    predict_windows(geared, np.zeros((4, 1)), command, starts, 3, 1e-3, 1)
    state_sensitivities(geared, np.zeros((4, 1)), np.zeros((2, 1)), 1e-3, 1, np.zeros(1), np.zeros((2, 1)))
