"""The gap metric: k-step-ahead output error over short windows, from states estimated by smoothing.

Each log is cut into consecutive windows of ``horizon`` samples (multiple shooting). A window's initial state is
first estimated from the measured angles by a centred Savitzky-Golay smoother (angle and derivative), with a
Dahl or LuGre arm's bristle state integrated along the smoothed arm path and a drive's twist read from the command
and that path (:func:`~furuta_drake.effects.surrogate.twist_starts`), then refined for each model by
Levenberg-Marquardt steps on the window's residuals (a step is kept only where the re-simulated residual
falls), so every model is judged with its own best initial states, and nothing depends on the rig's controller
or integrator. The model then predicts the angles over the window from the logged command (held over each sample).
Residuals are measured minus predicted angles in counts of the rig file's encoder. The horizon is short enough that
the upright's unstable pole amplifies initial-state errors by at most e^1.5 and at most 0.25 s. A window holds at least
``MIN_WINDOW`` samples: a log that comes near the upright at a rate so low that these span more than twice the
horizon (an error at a window's start grown e^3 times) cannot show an effect there and is refused, naming the
rate that would.

    gap = sqrt(max(mean over windows, samples and both angles of r^2 - sigma_0^2, 0))   [counts]

where sigma_0^2 is the variance the rig file's own sensor adds (``Windows.floor``: 1/12 count^2 for its encoder's
rounding, and a noise the rig file states). The gap measures what a model *predicts*: the same floor is taken off
for every model, so a model lowers the gap only by predicting the angles better. Variance a model claims (a
coarser encoder, measurement noise, a jittering delay's draws) is never taken off; it is judged on its own
signature (:mod:`~furuta_drake.diagnosis.selection.sensor`, :mod:`~furuta_drake.diagnosis.selection.jitter_fit`). A
jittering delay's variance of each sample, sigma_j^2(n) = sum_k g_nk^2 v_k (the window's impulse responses g_nk and the
command's variance v_k over the delay, :mod:`~furuta_drake.effects.jitter`), is computed here for that judgement.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from functools import partial

import numpy as np
from scipy.signal import savgol_filter

from furuta_drake.diagnosis.logs.load import RunLog, WindowResiduals
from furuta_drake.effects.jitter import command_variance, impulse_energy, response_variance
from furuta_drake.effects.surrogate import (
    HISTORY,
    INPUT_CHAIN,
    Model,
    WindowInputs,
    initial_states,
    predict_batch,
    sensor_variance,
    twist_starts,
)
from furuta_drake.effects.surrogate_tangent import flat
from furuta_drake.effects.vocabulary import rig_model
from furuta_drake.errors import LogError
from furuta_drake.rig import RigParameters, encoder_resolution, linearized_upright

MAX_HORIZON_S = 0.25
MIN_WINDOW = 5  # samples of a window at the least
SLOW_RATE_MARGIN = 2.0  # a log near the upright is refused when MIN_WINDOW samples span this many horizons
UPRIGHT_RADIUS = 0.5  # [rad] a log comes near the upright when its |theta| (wrapped) falls below this
IMPULSES = 24  # command impulses simulated per window for a jittering delay's variance (the others shifted)
SMOOTHING_S = 0.03  # Savitzky-Golay window for the initial states [s]


def gap_metric_definition(horizon_s: float) -> str:
    return (
        f"k-step output error: RMS of measured minus predicted theta and phi over {horizon_s * 1e3:.0f} ms "
        f"windows started from Savitzky-Golay-smoothed states refined per model and window by "
        f"Levenberg-Marquardt steps (the arm's bristle state too, for Dahl or LuGre friction), in encoder "
        f"counts of the rig file, less the variance the rig file's own sensor adds (the same for every model)"
    )


def upright_pole(rig: RigParameters) -> float:
    """lambda_u [1/s]: the unstable pole of the nominal model at the upright."""
    A, _ = linearized_upright(rig)
    return float(max(np.linalg.eigvals(A).real))


def horizon_seconds(rig: RigParameters) -> float:
    """min(0.25 s, 1.5 / lambda_u), lambda_u the unstable upright pole of the nominal model."""
    return float(min(MAX_HORIZON_S, 1.5 / upright_pole(rig)))


def check_rate(log: RunLog, rig: RigParameters) -> None:
    """Raise LogError when ``log`` comes near the upright at a rate whose shortest window spans more than
    ``SLOW_RATE_MARGIN`` horizons, saying why and what rate would do."""
    horizon_s, shortest = horizon_seconds(rig), MIN_WINDOW * log.sample_period
    near_upright = np.abs(np.angle(np.exp(1j * log.theta))) < UPRIGHT_RADIUS
    if shortest <= SLOW_RATE_MARGIN * horizon_s or not near_upright.any():
        return
    pole = upright_pole(rig)
    raise LogError(
        f"{log.name}: at {1 / log.sample_period:.3g} Hz a gap window of {MIN_WINDOW} samples lasts "
        f"{shortest * 1e3:.0f} ms, over which the upright's instability ({pole:.3g} 1/s) grows an error at the "
        f"window's start {np.exp(pole * shortest):.0f} times: near the upright (this log's theta comes within "
        f"{UPRIGHT_RADIUS:g} rad of it) no effect can show; log at {MIN_WINDOW / (SLOW_RATE_MARGIN * horizon_s):.3g} "
        f"Hz or faster, or diagnose runs that stay away from the upright"
    )


@dataclass
class Windows:
    """Windows of one or more logs, with what every model evaluation needs. Each log keeps its own sample
    period and horizon (logs at 250 Hz and 1 kHz can be diagnosed together)."""

    logs: list[RunLog]
    horizons: list[int]  # per log: samples per window
    starts: list[np.ndarray]  # per log: start indices
    initial_states: list[np.ndarray]  # per log: (4, W)
    measured: list[np.ndarray]  # per log: (horizon, 2, W) measured angles
    arm_paths: list[np.ndarray]  # per log: the smoothed arm angle [rad] at every sample
    floor: float = 1.0 / 12.0  # the variance the rig file's own sensor adds to a measured angle [counts^2]

    @property
    def count(self) -> int:
        return int(sum(s.size for s in self.starts))

    def subset(self, max_windows: int, seed: int = 0) -> Windows:
        """At most ``max_windows`` windows, drawn evenly over the logs (for fitting speed)."""
        if self.count <= max_windows:
            return self
        rng = np.random.default_rng(seed)
        keep = [
            np.sort(rng.choice(s.size, max(1, round(max_windows * s.size / self.count)), replace=False))
            for s in self.starts
        ]
        return Windows(
            self.logs,
            self.horizons,
            [s[k] for s, k in zip(self.starts, keep)],
            [x[:, k] for x, k in zip(self.initial_states, keep)],
            [m[:, :, k] for m, k in zip(self.measured, keep)],
            self.arm_paths,
            self.floor,
        )

    def batches(self) -> list[Batch]:
        """The windows as one array problem per (sample period, horizon): fewer, wider surrogate calls."""
        groups: dict[tuple[float, int], list[int]] = {}
        for i, (log, horizon) in enumerate(zip(self.logs, self.horizons)):
            groups.setdefault((round(log.sample_period, 9), horizon), []).append(i)
        out = []
        for (period, horizon), members in groups.items():
            commands, starts, offset = [], [], 0
            for i in members:
                command = self.logs[i].torque_command
                # Pad each log with its first command so a delayed window never reads the previous log.
                commands.append(np.concatenate([np.full(COMMAND_PAD, command[0]), command]))
                starts.append(self.starts[i] + offset + COMMAND_PAD)
                offset += COMMAND_PAD + command.size
            out.append(
                Batch(
                    members,
                    period,
                    horizon,
                    np.concatenate(commands),
                    np.concatenate(starts),
                    np.concatenate([self.initial_states[i] for i in members], axis=1),
                    np.concatenate([self.measured[i] for i in members], axis=2),
                    np.cumsum([0] + [self.starts[i].size for i in members]),
                )
            )
        return out


COMMAND_PAD = HISTORY  # samples of padding between logs in a batch: a window never reads the previous log


@dataclass
class Batch:
    """The windows of the logs ``members`` that share a sample period and horizon, concatenated."""

    members: list[int]
    period: float
    horizon: int
    command: np.ndarray  # the members' torque commands, padded and concatenated
    starts: np.ndarray  # (W,) window starts in ``command``
    initial_states: np.ndarray  # (4, W)
    measured: np.ndarray  # (horizon, 2, W)
    bounds: np.ndarray  # member j's windows are [bounds[j], bounds[j + 1])

    @property
    def inputs(self) -> WindowInputs:
        """The batch as the surrogate reads it (:func:`~furuta_drake.effects.surrogate.predict_batch`)."""
        return WindowInputs(self.command, self.starts, self.horizon, self.period, substeps_for(self.period))


def window_samples(period: float, rig: RigParameters) -> tuple[int, int]:
    """(samples per window, samples of the smoothing filter) of a log sampled every ``period`` [s]; a log needs
    more than one window plus a smoothing filter at each end."""
    return max(MIN_WINDOW, int(round(horizon_seconds(rig) / period))), max(5, int(round(SMOOTHING_S / period)) | 1)


def make_windows(logs: list[RunLog], rig: RigParameters) -> Windows:
    """Cut every log into consecutive windows of the rig's horizon, with smoothed initial states; the floor is the
    variance the rig file's own sensor adds (its encoder's rounding, and a noise or coarser encoder it states)."""
    horizon_s = horizon_seconds(rig)
    horizons, starts, states, measured, paths = [], [], [], [], []
    for log in logs:
        check_rate(log, rig)
        horizon, smooth = window_samples(log.sample_period, rig)
        if log.time.size <= horizon + 2 * smooth:
            raise LogError(
                f"{log.name}: {log.time.size} samples ({log.time.size * log.sample_period:.3g} s) are too "
                f"short for one gap window of this rig: {horizon} samples ({horizon_s * 1e3:.0f} ms) "
                f"plus {SMOOTHING_S * 1e3:.0f} ms of smoothing on each side; without --heldout part of "
                f"each log is held out and the rest trains, so give longer logs"
            )
        angles = np.vstack([log.theta, log.phi])
        position = savgol_filter(angles, smooth, 3, axis=1)
        velocity = savgol_filter(angles, smooth, 3, deriv=1, delta=log.sample_period, axis=1)
        first, last = smooth, log.time.size - horizon - smooth
        s = np.arange(first, max(first, last), horizon)
        horizons.append(horizon)
        paths.append(position[1])
        starts.append(s)
        states.append(np.vstack([position[:, s], velocity[:, s]]))
        measured.append(np.stack([angles[:, s + k] for k in range(horizon)]))
    return Windows(logs, horizons, starts, states, measured, paths, sensor_variance(rig_model(rig), rig.counts_per_rev))


def with_hidden_states(model: Model, windows: Windows, batch: Batch, x: np.ndarray) -> np.ndarray:
    """The batch's window states ``x`` (4, W and any hidden rows: 4 + 1 with a bristle, + 2 with a twist) laid out
    for ``model`` (:attr:`~furuta_drake.effects.surrogate.Model.hidden_states`): rows it lacks start at zero (the
    bristle) or from the log (the twist, :func:`~furuta_drake.effects.surrogate.twist_starts`), rows it has no use
    for are dropped."""
    if x.shape[0] == 4 + model.hidden_states:
        return x
    rows = [x[:4]]
    if model.arm_friction.has_bristles:
        rows.append(x[4:5] if x.shape[0] in (5, 7) else np.zeros((1, x.shape[1])))
    if model.has_drive:
        rows.append(x[-2:] if x.shape[0] >= 6 else _per_member(windows, batch, partial(_twists, model)))
    return np.vstack(rows)


def window_states(model: Model, windows: Windows, batch: Batch) -> np.ndarray:
    """The batch's windows' initial states for ``model``: the smoothed ones (4, W), then its hidden states
    (:attr:`~furuta_drake.effects.surrogate.Model.hidden_states`) read from each log
    (:func:`~furuta_drake.effects.surrogate.initial_states`)."""
    return _per_member(windows, batch, partial(_states, model))


def _per_member(windows: Windows, batch: Batch, of_log) -> np.ndarray:
    """``of_log(windows, i)`` of the batch's members, side by side."""
    return np.concatenate([of_log(windows, i) for i in batch.members], axis=1)


def _states(model: Model, windows: Windows, i: int) -> np.ndarray:
    log = windows.logs[i]
    return initial_states(
        model, windows.initial_states[i], windows.arm_paths[i], log.torque_command, log.sample_period, windows.starts[i]
    )


def _twists(model: Model, windows: Windows, i: int) -> np.ndarray:
    log = windows.logs[i]
    return twist_starts(model, windows.arm_paths[i], log.torque_command, log.sample_period, windows.starts[i])


def substeps_for(period: float) -> int:
    """RK4 substeps so that the integration step is at most 1 ms."""
    return max(1, int(np.ceil(period / 1e-3 - 1e-9)))


GAUSS_NEWTON_STEPS = 3
PLAY_STEP_FACTOR = 2  # a model with a play takes this many times the steps: its screened twist is a coarse start
# and a rattling rotor's residual is far from linear in it
TWIST_SCALES = (0.1, 10.0)  # [rad, rad/s]: a step of the drive's twist or its rate this large weighs one count^2
LM_DAMPING = 1e-3  # initial Levenberg-Marquardt damping, relative to the normal matrix' diagonal


def residuals(model: Model, windows: Windows, nominal_counts: int) -> list[np.ndarray]:
    """Per log: (horizon, 2, W) measured minus predicted angles [counts of the nominal encoder], after
    ``GAUSS_NEWTON_STEPS`` Levenberg-Marquardt steps on each window's initial state (variable projection: every
    model is judged with its own best initial states; the sensitivities are the integration's exact forward
    sensitivities, and the residual is re-simulated from the refined states)."""
    return projected_residuals(model, windows, nominal_counts, sensitivities=False)[0]


def _state_jacobian(model: Model, x: np.ndarray, torque: np.ndarray, inputs: WindowInputs, count: float):
    """(the predicted angles (h, 2, W) of windows from their initial states x (n, W) under their arm torque
    ``torque``; the residuals' sensitivities (h, 2, W, n) [counts per unit of state] to x): the integration's exact
    forward sensitivities, one surrogate pass."""
    prediction = predict_batch(model, x, inputs, torque, states=True)
    return prediction.angles, prediction.slopes / count


def projected_residuals(
    model: Model, windows: Windows, nominal_counts: int, sensitivities: bool = True, steps: int = GAUSS_NEWTON_STEPS
):
    """:func:`residuals`, per log the refined initial states (4, W), or (5, W) with the arm's bristle state for a
    Dahl or LuGre arm (near a stick the bristle is a hidden state like the velocities: its value read from the
    arm path is only the start), and per log the residuals' sensitivities to them (h, 2, W, 4 or 5) [counts per
    unit of state] at the refined states (None per log without ``sensitivities``).

    Each window takes ``steps`` Levenberg-Marquardt steps (``PLAY_STEP_FACTOR`` times as many from the screened
    twists of a drive with a play, :func:`_screened_twists`) with its own damping: a step is kept only
    where the re-simulated residual falls (near a friction stick or a swing's turning point a linearised step can
    overshoot), and the window's damping shrinks 3x after a kept step and grows 10x, to at least 1 (about half
    the Gauss-Newton step), after a refused one. A trial whose sensitivities a later step or the caller would read
    if it is kept is simulated with them, in the one pass that gives its angles (most trials are kept; each
    window's prediction depends on its own state and command alone); the input chain once per batch. The steps
    are written here because scipy's least-squares solvers take one problem at a time: batched over
    windows, every window's step costs one surrogate call for all of them."""
    count = encoder_resolution(nominal_counts)
    out, states, jacobians = [None] * len(windows.logs), [None] * len(windows.logs), [None] * len(windows.logs)
    for batch in windows.batches():
        x, r, J = _refined(model, window_states(model, windows, batch), batch, count, sensitivities, steps)
        for j, i in enumerate(batch.members):
            part = slice(batch.bounds[j], batch.bounds[j + 1])
            out[i], states[i] = r[:, :, part], x[:, part]
            jacobians[i] = J[:, :, part] if sensitivities else None
    return out, states, jacobians


def state_jacobians(model: Model, windows: Windows, states: list[np.ndarray], nominal_counts: int) -> list[np.ndarray]:
    """Per log the residuals' sensitivities (h, 2, W, n) [counts per unit of state] at the windows' initial
    ``states`` (per log (n, W), laid out for ``model``): at the refined states of :func:`projected_residuals`,
    what it returns with ``sensitivities``, to the last bit (each window's column depends on its own state and
    command alone), for a caller that needs them at some of its evaluations only."""
    count = encoder_resolution(nominal_counts)
    out = [None] * len(windows.logs)
    for batch in windows.batches():
        x = np.concatenate([states[i] for i in batch.members], axis=1)
        J = predict_batch(model, x, batch.inputs, states=True).slopes / count
        for j, i in enumerate(batch.members):
            out[i] = J[:, :, batch.bounds[j] : batch.bounds[j + 1]]
    return out


def _refined(model: Model, x: np.ndarray, batch: Batch, count: float, sensitivities: bool, steps: int):
    """:func:`projected_residuals` of one batch from the initial states x (n, W) with ``steps`` steps: the refined
    states, their residuals (h, 2, W) and, with ``sensitivities``, the residuals' sensitivities (h, 2, W, n)."""
    n, W = x.shape
    prior = np.zeros(n)
    bristles = model.arm_friction.has_bristles
    if bristles:  # while the arm slides its bristle is saturated and unobservable: damp its step (a move
        bound = model.arm_friction.bristle_bound  # over its whole range weighs one count^2)
        prior[4] = 1.0 / bound**2
    if model.has_drive:  # inside the backlash the twist is free of the arm: damp its steps the same way
        prior[-2:] = 1.0 / np.square(TWIST_SCALES)
    inputs = batch.inputs
    torque = inputs.torque(model)
    if model.has_drive and model.drive_backlash > 0:
        x = _screened_twists(model, x, torque, batch, count)
        steps = PLAY_STEP_FACTOR * steps
    angles, J = _state_jacobian(model, x, torque, inputs, count)
    r = (batch.measured - angles) / count
    cost = np.nansum(r**2, axis=(0, 1))
    damping = np.full(W, LM_DAMPING)
    for step in range(steps):
        Jw = J.transpose(2, 0, 1, 3).reshape(W, -1, n)
        normal = Jw.transpose(0, 2, 1) @ Jw
        diagonal = np.einsum("wii->wi", normal)
        normal = normal + (damping[:, None] * diagonal + prior + 1e-9)[:, :, None] * np.eye(n)
        gradient = (Jw.transpose(0, 2, 1) @ np.nan_to_num(r.transpose(2, 0, 1).reshape(W, -1, 1)))[..., 0]
        trial = x + np.linalg.solve(normal, gradient[..., None])[..., 0].T
        if bristles:
            trial[4] = np.clip(trial[4], -bound, bound)
        needed = sensitivities or step < steps - 1  # a kept trial's sensitivities are read after this step
        if needed:
            angles, J_trial = _state_jacobian(model, trial, torque, inputs, count)
        else:
            angles = predict_batch(model, trial, inputs, torque).angles
        r_trial = (batch.measured - angles) / count
        cost_trial = np.nansum(r_trial**2, axis=(0, 1))
        better = cost_trial < cost
        if needed:
            J = np.where(better[None, None, :, None], J_trial, J)
        x, r = np.where(better, trial, x), np.where(better, r_trial, r)
        cost = np.where(better, cost_trial, cost)
        damping = np.where(better, damping / 3.0, np.maximum(damping * 10.0, 1.0))
    return x, r, J


TWIST_SCREEN = (-1.0, 0.0, 1.0)  # twists screened at a window's start, in backlash half-widths
TWIST_RATE_SCREEN = (0.5, 1.0, 2.0, 4.0)  # their rates screened, either sign, in play widths per window (2 b / T)


def _screened_twists(model: Model, x: np.ndarray, torque: np.ndarray, batch: Batch, count: float):
    """``x`` with each window's twist [delta, delta'] the best of its estimate and the twists ``TWIST_SCREEN``
    across the backlash, each at the estimate's rate, at rest against the arm (delta' = 0) and at the rates
    ``TWIST_RATE_SCREEN`` either way: inside the play the arm does not feel the twist until a flank touches, so the
    residual is flat in it there and a linearised step cannot find the flank the rotor sits on, nor the rate at
    which a rattling rotor crosses the play (a window's rotor can cross it a few times in either direction, and
    where it strikes a flank decides the rest of the window); at a window that starts at a command's reversal the
    estimate's rate (of a twist that jumps across the play) is no start either. The screen's predictions all run in
    one call."""
    n, W = x.shape
    width = 2.0 * model.drive_backlash / ((batch.inputs.horizon - 1) * batch.inputs.period)
    rates = [x[-1], np.zeros(W)] + [np.full(W, sign * k * width) for k in TWIST_RATE_SCREEN for sign in (1.0, -1.0)]
    trials = [x]
    for share in TWIST_SCREEN:
        for rate in rates:
            trial = x.copy()
            trial[-2], trial[-1] = share * model.drive_backlash, rate
            trials.append(trial)
    every = np.hstack(trials)
    angles = predict_batch(model, every, batch.inputs, np.tile(torque, (1, len(trials)))).angles
    r = (np.tile(batch.measured, (1, 1, len(trials))) - angles) / count
    cost = np.nansum(r**2, axis=(0, 1)).reshape(len(trials), W)
    best = np.argmin(cost, axis=0)
    return every[:, best * W + np.arange(W)]


def project_out_states(change: np.ndarray, state_jacobian: np.ndarray) -> np.ndarray:
    """``change`` (h, 2, W) of a log's residuals, or (h, 2, K, W) K changes of each window, minus its least-squares
    fit on the window's state sensitivities (h, 2, W, 4): what a change of the model's parameters does to the
    residuals once the initial states are re-projected (Kaufman's approximation of the variable-projection
    Jacobian). The normal matrix takes a ridge of 1e-9 of its mean diagonal: exact sensitivities can be exactly
    degenerate (a stuck arm's velocities and bristle can move the angles along one direction only)."""
    h, _, W, n = state_jacobian.shape
    Jw = state_jacobian.transpose(2, 0, 1, 3).reshape(W, -1, n)
    gram = Jw.transpose(0, 2, 1) @ Jw
    normal = gram + 1e-9 * (np.einsum("wii->w", gram) / n + 1.0)[:, None, None] * np.eye(n)
    if change.ndim == 4:
        cw = change.transpose(3, 0, 1, 2).reshape(W, -1, change.shape[2])
        fitted = Jw @ np.linalg.solve(normal, Jw.transpose(0, 2, 1) @ cw)
        return change - fitted.reshape(W, h, 2, -1).transpose(1, 2, 3, 0)
    cw = change.transpose(2, 0, 1).reshape(W, -1)
    fitted = (Jw @ np.linalg.solve(normal, Jw.transpose(0, 2, 1) @ cw[..., None]))[..., 0]
    return change - fitted.reshape(W, h, 2).transpose(1, 2, 0)


def parameter_slopes_of(
    model: Model, shifted: list[Model], steps: list[float], windows: Windows, states: list[np.ndarray], counts: int
) -> list[list[np.ndarray]]:
    """Per model of ``shifted`` (``model`` with one parameter moved by its entry of ``steps``), per log the change
    (horizon, 2, W) of :func:`fixed_state_residuals` [counts] per unit of that parameter, to first order: the
    change of the packed parameters and of the input chain's arm torque by differences of those cheap mappings
    (no integration), carried through the integration by its exact forward sensitivities, every parameter in one
    surrogate pass per batch. Each shifted model takes the kernel's branches of ``model``
    (:func:`~furuta_drake.effects.surrogate.same_branches`)."""
    count = encoder_resolution(counts)
    rows = np.stack([(flat(other) - flat(model)) / step for other, step in zip(shifted, steps)])
    chain = tuple(getattr(model, name) for name in INPUT_CHAIN)
    out = [[None] * len(windows.logs) for _ in shifted]
    for batch in windows.batches():
        x = np.concatenate([states[i] for i in batch.members], axis=1)
        inputs = batch.inputs
        torque = inputs.torque(model)
        torques = [
            None
            if tuple(getattr(other, name) for name in INPUT_CHAIN) == chain
            else (inputs.torque(other) - torque) / step
            for other, step in zip(shifted, steps)
        ]
        slopes = predict_batch(model, x, inputs, torque, directions=(rows, torques)).slopes
        for k in range(len(shifted)):
            for j, i in enumerate(batch.members):
                out[k][i] = -slopes[:, :, batch.bounds[j] : batch.bounds[j + 1], k] / count
    return out


def fixed_state_residuals(
    model: Model, windows: Windows, states: list[np.ndarray], nominal_counts: int
) -> list[np.ndarray]:
    """Per log: measured minus predicted angles [counts] from given initial states (those of
    :func:`projected_residuals`, no refinement)."""
    return fixed_state_residuals_of([model], windows, states, nominal_counts)[0]


MODELS_PER_CALL = 16  # models integrated in one surrogate call by fixed_state_residuals_of (bounds its memory)


def fixed_state_residuals_of(
    models: list[Model], windows: Windows, states: list[np.ndarray], nominal_counts: int
) -> list[list[np.ndarray]]:
    """:func:`fixed_state_residuals` of each of ``models``, up to ``MODELS_PER_CALL`` of those holding the same
    number of unmodelled torque terms and the same hidden states in one surrogate call per batch (the parameter steps
    of a finite-difference Jacobian); ``states`` laid out for each (:func:`with_hidden_states`)."""
    count = encoder_resolution(nominal_counts)
    out = [[None] * len(windows.logs) for _ in models]
    alike: dict[tuple[int, bool, bool], list[int]] = {}
    for k, model in enumerate(models):
        layout = (len(model.unmodelled_terms), model.has_drive, model.arm_friction.has_bristles)
        alike.setdefault(layout, []).append(k)
    calls = [group[i : i + MODELS_PER_CALL] for group in alike.values() for i in range(0, len(group), MODELS_PER_CALL)]
    for batch in windows.batches():
        x = np.concatenate([states[i] for i in batch.members], axis=1)
        W, inputs = x.shape[1], batch.inputs
        for call in calls:
            laid = with_hidden_states(models[call[0]], windows, batch, x)
            predicted = predict_batch([models[k] for k in call], np.tile(laid, (1, len(call))), inputs).angles
            for slot, k in enumerate(call):
                r = (batch.measured - predicted[:, :, slot * W : (slot + 1) * W]) / count
                for j, i in enumerate(batch.members):
                    out[k][i] = r[:, :, batch.bounds[j] : batch.bounds[j + 1]]
    return out


@dataclass
class GapResult:
    gap: float  # [counts]
    per_signal: dict[str, float]  # gap of theta and phi alone [counts]
    per_window: np.ndarray  # each window's excess mean squared residual over the floor [counts^2]
    sensor_variance: float  # the floor taken off [counts^2]
    residuals: list[np.ndarray]
    initial_states: list[np.ndarray]  # per log (4, W), refined for this model, and its hidden states' rows


def jitter_energy(model: Model, windows: Windows, states, jacobians, nominal_counts: int):
    """Per log (horizon, 2, horizon - 1, W) the squared impulse responses g_nk^2 [counts^2 per N m^2] of the
    windows from their refined initial ``states`` (:func:`~furuta_drake.effects.jitter.impulse_energy`), with the
    share the refit of each window's initial state absorbs projected out (:func:`project_out_states` on the
    residuals' state sensitivities ``jacobians``: a window's own best start takes most of a smooth response)."""
    count = encoder_resolution(nominal_counts)
    out = [None] * len(windows.logs)
    for batch in windows.batches():
        x = np.concatenate([states[i] for i in batch.members], axis=1)
        J = np.concatenate([jacobians[i] for i in batch.members], axis=2)
        inputs, samples = batch.inputs, batch.horizon - 1
        v = command_variance(batch.command, batch.period, model)[batch.starts[None, :] + np.arange(samples)[:, None]]
        size = float(np.sqrt(np.mean(v))) or 1e-3 * float(np.std(batch.command)) or 1e-9  # the deviation's size

        def predict(part, copies, change, x=x, inputs=inputs):
            tiled = dataclasses.replace(inputs, starts=np.tile(inputs.starts[part], copies))
            return predict_batch(model, np.tile(x[:, part], copies), tiled, tiled.torque(model, change)).angles / count

        def residual_of(responses, part, J=J):
            return project_out_states(responses, J[:, :, part])

        stride = max(1, -(-samples // IMPULSES))
        energy = impulse_energy(predict, samples, x.shape[1], size, residual_of, stride)
        for j, i in enumerate(batch.members):
            out[i] = energy[..., batch.bounds[j] : batch.bounds[j + 1]]
    return out


def jitter_variances(model: Model, windows: Windows, energy) -> list[np.ndarray] | None:
    """Per log (horizon, 2, W) the variance sigma_j^2 [counts^2] a jittering delay of ``model`` adds to each
    residual (module docstring) from the windows' :func:`jitter_energy`; None without a spread."""
    if model.delay_spread <= 0:
        return None
    out = []
    for log, starts, e in zip(windows.logs, windows.starts, energy):
        v = command_variance(log.torque_command, log.sample_period, model)  # the first command held before the log
        out.append(response_variance(e, v[starts[None, :] + np.arange(e.shape[2])[:, None]]))
    return out


def model_jitter(model: Model, windows: Windows, nominal_counts: int, refined=None) -> list[np.ndarray] | None:
    """Per log (horizon, 2, W) the variance [counts^2] ``model``'s jittering delay adds to each residual
    (:func:`jitter_variances` of the :func:`jitter_energy` at the model's refined initial states: ``refined`` =
    (states, sensitivities) of :func:`projected_residuals`, computed when None); None without a spread."""
    if model.delay_spread <= 0:
        return None
    states, jacobians = refined if refined is not None else projected_residuals(model, windows, nominal_counts)[1:]
    return jitter_variances(model, windows, jitter_energy(model, windows, states, jacobians, nominal_counts))


def squared_excess(r: list[np.ndarray]) -> list[np.ndarray]:
    """Per log the squared residuals (horizon - 1, 2, W) [counts^2] past each window's start."""
    return [x[1:] ** 2 for x in r]  # row 0 is the start


def window_excess(r: list[np.ndarray], variance: float) -> np.ndarray:
    """Each window's mean squared residual less the floor ``variance`` [counts^2]."""
    return np.concatenate([x.mean(axis=(0, 1)) for x in squared_excess(r)]) - variance


def gap_from_residuals(r: list[np.ndarray], floor: float, initial_states: list[np.ndarray]) -> GapResult:
    """The gap and its parts from per-log (horizon, 2, W) residuals [counts] and the rig file's sensor variance
    ``floor`` [counts^2]."""
    squared = squared_excess(r)
    per_window = window_excess(r, floor)
    samples = sum(x.shape[0] * x.shape[2] for x in squared)
    per_signal = {
        name: float(np.sqrt(max(sum(x[:, i].sum() for x in squared) / samples - floor, 0.0)))
        for i, name in enumerate(("theta", "phi"))
    }
    return GapResult(float(np.sqrt(max(per_window.mean(), 0.0))), per_signal, per_window, floor, r, initial_states)


def evaluate_gap(model: Model, windows: Windows, nominal_counts: int) -> GapResult:
    """The gap of ``model``'s predictions on ``windows`` (see the module docstring), from the surrogate."""
    r, states, _ = projected_residuals(model, windows, nominal_counts, sensitivities=False)
    return gap_from_residuals(r, windows.floor, states)


def window_residuals(result: GapResult, windows: Windows, rig: RigParameters) -> list[WindowResiduals]:
    """The residuals as :class:`WindowResiduals` for the localisation and the plots; the states are the
    measured angles and their smoothed derivatives (the regimes are read from them)."""
    out = []
    for log, horizon, starts, r in zip(windows.logs, windows.horizons, windows.starts, result.residuals):
        command = log.torque_command
        smooth = max(5, int(round(SMOOTHING_S / log.sample_period)) | 1)
        velocity = savgol_filter(np.vstack([log.theta, log.phi]), smooth, 3, deriv=1, delta=log.sample_period, axis=1)
        for w, start in enumerate(starts):
            index = start + np.arange(horizon)
            state = np.vstack([log.theta[index], log.phi[index], velocity[:, index]]).T
            out.append(
                WindowResiduals(
                    log_name=log.name,
                    time=log.time[index],
                    residual=r[:, :, w],
                    state=state,
                    torque=command[index],
                    saturated=np.abs(command[index]) >= 0.98 * rig.torque_limit,
                )
            )
    return out
