"""Fit candidate effects on the train windows and measure them on the held-out windows (stage 3 of the diagnosis).

A fit is bounded least squares of the k-step residuals (``scipy.optimize.least_squares``) from the best of
several starts where the cost is multimodal, once per form of the new effect; the form with the lower train cost
is kept. The cost re-projects the windows' initial states for every parameter vector (variable projection); its
Jacobian is Kaufman's approximation (the residuals' change at the projected states, with the part the states
could absorb projected out), its columns from the integration's exact forward sensitivities (:func:`_columns`).
A screen (:func:`screen_task`) is the same least squares from the best start, stopped after a few evaluations on
the windows that rank the starts: a step fits fully only the candidates whose screen comes near the best one's.

Parameter intervals come from a block bootstrap over the train windows, linearised at the fit: each resample of
windows (a window is a block: its residuals are correlated) takes one Gauss-Newton step from the fit with the
resampled windows' normal equations, and the 2.5-97.5 % range of the steps, taken relative to the step of all
windows, is the 95 % interval.

The sensor effects (a coarser encoder, measurement noise) change no prediction and are not fitted here: they are
read from the data and judged by their own rule (:mod:`~furuta_drake.diagnosis.selection.sensor`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from furuta_drake.diagnosis.gap.metric import (
    GapResult,
    Windows,
    evaluate_gap,
    fixed_state_residuals_of,
    parameter_slopes_of,
    project_out_states,
    projected_residuals,
    state_jacobians,
    window_excess,
)
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.diagnosis.selection.jitter_fit import heldout_jitter, spread_by_likelihood
from furuta_drake.diagnosis.selection.jumps import bootstrap_argmin, line_search
from furuta_drake.diagnosis.selection.rule import Bootstrap, beyond_resolution
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects.surrogate import Model, same_branches
from furuta_drake.effects.vocabulary import CANDIDATES, Effect, Scales, apply_effects, causal_spread, form_starts

JACOBIAN_STEP = 1e-3  # relative finite-difference step of the parameter sensitivities
BOUND_TOLERANCE = 1e-3  # a parameter within this fraction of its range from a bound is "at" it
INTERVAL = (2.5, 97.5)  # percentiles of the 95 % parameter intervals
COST_TOLERANCE = 1e-4  # a fit stops when a step lowers its cost by less than this share (scipy's ftol)
SCREEN_STEPS = 1  # Levenberg-Marquardt steps of the windows' initial states when a fit's starts are ranked
SCREEN_EVALUATIONS = 4  # cost evaluations of a candidate's screen on the start windows (:func:`screen_task`)


@dataclass
class FitResult:
    """A fitted group of effects (one name, or the names of a stepwise model joined by '+')."""

    name: str
    effects: dict[str, Effect]  # effect name -> fitted form and parameters (SI)
    train_gap: float  # [counts]
    heldout: GapResult | None  # the model's gap on the held-out windows (None: not evaluated)
    samples: dict[str, np.ndarray] = field(default_factory=dict)  # effect -> (resamples, params) bootstrap
    at_bounds: list[str] = field(default_factory=list)  # "effect.param (lower|upper)" fitted at a search bound
    failure: str = ""  # why the fit or its held-out prediction failed ("" when it did not)
    train_excess: float = float("nan")  # mean excess squared residual on the train windows before the gap's clip
    # [counts^2]: orders fits that both reach the floor (a gap of 0)
    screened: str = ""  # why the candidate was screened out: its values are a screen's, not a fit's ("": fitted)


@dataclass(frozen=True)
class FitTask:
    """What one fit needs; ``fixed``: effects the model already holds (fitted again from their values, or kept
    as they are when ``frozen``), then ``new``: the effect to add (from ``start`` when given, in its form, else
    in every form from ``starts``' start of that form when it holds one, else from the form's own starts)."""

    new: str
    fixed: dict[str, Effect]
    model: Model
    train: Windows
    heldout: Windows | None
    logs: tuple[RunLog, ...]
    nominal_counts: int
    settings: DiagnosisSettings
    fixed_samples: dict[str, np.ndarray] = field(default_factory=dict)  # the fixed effects' earlier bootstrap
    frozen: bool = False
    start: Effect | None = None
    starts: dict[str, list[float]] = field(default_factory=dict)  # form -> the start a screen found best
    regressed: dict = field(default_factory=dict)  # the train logs' equation-error starts (Scales.regressed)

    @property
    def name(self) -> str:
        return "+".join([*self.fixed, self.new])


COMMAND_QUANTILES = (0.1, 0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9, 0.97)  # of |command|: starts of the forms
# whose cost jumps where their parameter crosses a logged command (Scales.command_levels)


def scales_of(logs, model: Model, regressed: dict | None = None) -> Scales:
    """The rig's and the logs' scales (with the equation-error starts ``regressed``, when given)."""
    magnitudes = np.abs(np.concatenate([log.torque_command for log in logs]))
    return Scales(
        torque=model.gravity_torque,
        command=max(float(np.max(magnitudes)), 1e-9),
        arm_inertia=model.arm_inertia_total,
        pendulum_inertia=model.pendulum_inertia_total,
        period=float(np.median([log.sample_period for log in logs])),
        command_levels=tuple(float(q) for q in np.quantile(magnitudes, COMMAND_QUANTILES)),
        regressed=regressed or {},
        drive_inertia=model.rotor_share * (1.0 - model.rotor_share) * model.arm_inertia_total,
    )


def fit_task(task: FitTask) -> FitResult:
    """Fit ``task.fixed`` with ``task.new`` added on the train windows (every form of the new effect, the best
    kept), evaluate the result on the held-out windows, and bootstrap its parameters."""
    forms = [task.start.form] if task.start is not None else [form.name for form in _fitted(task.new).forms]
    fits = {form: _least_squares(task, {task.new: form}) for form in forms}
    effects, at_bound, samples, _ = _named_fit(task, fits)
    return _evaluated(task, effects, samples, at_bound)


@dataclass(frozen=True)
class Screen:
    """A candidate's screen (:func:`screen_task`)."""

    effects: dict[str, Effect]  # the model's effects at the screen's end, the new one in its best form
    starts: dict[str, list[float]]  # form -> its best start (a full fit goes on from there: ``FitTask.starts``)
    excess: float  # the start windows' mean excess squared residual at the screen's end [counts^2]


def screen_task(task: FitTask) -> Screen:
    """A cheap first fit of ``task.new``: in each form, its best start (as :func:`fit_task` ranks them) and
    ``SCREEN_EVALUATIONS`` cost evaluations of the least squares on the start windows from there; the form with
    the least excess is the screen's. The selection fits fully only the candidates whose screen comes within reach
    of the best one's (:meth:`~furuta_drake.diagnosis.selection.stepwise.Stepwise.screened_fits`); the others keep their
    screen (:func:`after_screen`), its values no fit's and without intervals."""
    screens = {form.name: _screened(task, {task.new: form.name}) for form in _fitted(task.new).forms}
    best = min(screens, key=lambda form: screens[form][2])
    return Screen(screens[best][1], {form: screen[0] for form, screen in screens.items()}, screens[best][2])


def after_screen(job: tuple[FitTask, Screen | None, bool]) -> FitResult:
    """A screened candidate (``task``, its ``screen``, whether to ``fit`` it fully): its full fit from the starts
    its screen ranked (from every start without a screen), else the screen's effects on the train and held-out
    windows."""
    task, screen, fit = job
    if fit:
        return fit_task(task if screen is None else dataclasses.replace(task, starts=screen.starts))
    return _evaluated(task, screen.effects, {}, [])


def _fitted(name: str):
    """The candidate ``name``, which must be one the least squares fit."""
    candidate = CANDIDATES[name]
    if not candidate.fit:
        raise ValueError(f"{name} is a sensor effect: it is read from the data, not fitted")
    return candidate


def _evaluated(task: FitTask, effects: dict[str, Effect], samples: dict, at_bound: list[str]) -> FitResult:
    """The FitResult of ``task``'s model with ``effects``: its gaps on the train and held-out windows."""
    model = apply_effects(task.model, effects)
    train = evaluate_gap(model, task.train, task.nominal_counts)
    heldout = None if task.heldout is None else evaluate_gap(model, task.heldout, task.nominal_counts)
    if heldout is not None and not np.isfinite(heldout.gap):
        raise FloatingPointError(f"{task.name}: the fitted model's prediction diverged on held-out windows")
    names = (*task.fixed, task.new)
    return FitResult(
        task.name,
        {name: effects[name] for name in names},
        train.gap,
        heldout,
        samples,
        at_bound,
        train_excess=float(train.per_window.mean()),
    )


def _named_fit(task: FitTask, fits: dict) -> tuple:
    """The fit of the form of lowest train cost, or, of a form that nests a simpler one (``Form.simpler``: a
    jittering delay), that form when the residuals' variance shows its extra parameter, else the simpler one. A
    jitter's expected command is a moving average of the command, which a lag or a filter also gives: what tells a
    jitter is the variance its draws add, so its spread is the one of largest likelihood below the causal limit
    (:func:`~furuta_drake.effects.vocabulary.causal_spread`), and it is named when that spread is credited
    (:mod:`~furuta_drake.diagnosis.selection.jitter_fit`). Where the least squares show the spread too (its 95 %
    interval off the bound, more removed than the floor resolves,
    :func:`~furuta_drake.diagnosis.selection.rule.beyond_resolution`: a fine encoder sees the expected command's
    smoothing), their spread is reported, the sharper reading."""
    nesting = [name for name in fits if CANDIDATES[task.new].form(name).simpler in fits]
    if not nesting:
        return fits[min(fits, key=lambda form: fits[form][3])]
    form = CANDIDATES[task.new].form(nesting[0])
    low, high = (bound[-1] for bound in form.bounds(scales_of(task.logs, task.model)))
    effects, at_bound, samples, cost = fits[form.name]
    delay, spread = effects[task.new].values
    settings = task.settings
    effects = {**effects, task.new: Effect(form.name, (delay, min(spread, causal_spread(delay))))}
    evidence = spread_by_likelihood(
        apply_effects(task.model, effects),
        fit_windows(task.train, settings)[0],
        task.nominal_counts,
        (low, high),
        samples[task.new].shape[0],
        settings.seed,
    )
    if not evidence.credited or not _credited_heldout(task, effects, evidence.spread):
        return fits[form.simpler]
    off_bound = np.percentile(samples[task.new][:, -1], INTERVAL[0]) > low + BOUND_TOLERANCE * (high - low)
    if off_bound and spread <= causal_spread(delay) and beyond_resolution(fits[form.simpler][3] - cost):
        return fits[form.name]  # the mean shows the spread too (a fine encoder): the least squares' is sharper
    samples = {**samples, task.new: np.column_stack([samples[task.new][:, :-1], evidence.samples])}
    effects = {**effects, task.new: Effect(form.name, (delay, evidence.spread))}
    spread_label = f"{task.new}.{form.params[-1]} "
    return effects, [label for label in at_bound if not label.startswith(spread_label)], samples, cost


def _credited_heldout(task: FitTask, effects: dict[str, Effect], spread: float) -> bool:
    """Whether the jittering delay of ``effects`` with ``spread`` beats a constant variance on the held-out windows
    (:func:`~furuta_drake.diagnosis.selection.jitter_fit.heldout_jitter`); True when the task has none."""
    if task.heldout is None:
        return True
    delay = effects[task.new].values[0]
    model = apply_effects(task.model, {**effects, task.new: Effect("jitter", (delay, spread))})
    settings = task.settings
    bootstrap = Bootstrap(task.heldout.count, settings.bootstrap, settings.seed)
    return heldout_jitter(model, task.train, task.heldout, task.nominal_counts, bootstrap, settings.seed).credited


def fit_windows(train: Windows, settings: DiagnosisSettings) -> tuple[Windows, Windows]:
    """(the train windows a fit uses, drawn seeded; of those, the windows that rank its starts and carry a screen)."""
    windows = train.subset(settings.fit_windows, settings.seed)
    return windows, windows.subset(settings.start_windows, seed=settings.seed + 1)


class _Problem:
    """The least squares of every fitted parameter of ``task.model`` with ``task.fixed`` (from their values) and the
    new effect in the form ``new_form``: the stacked parameters' names, sizes, bounds and starts, the effects and
    the model at a parameter vector, and the fit and start windows."""

    def __init__(self, task: FitTask, new_form: dict[str, str]):
        self.task = task
        self.scales = scales_of(task.logs, task.model, task.regressed)
        self.forms, self.sensors = _forms(task, new_form, self.scales)
        self.names, self.sizes, self.low, self.high, self.starts = _stacked(self.forms, self.scales)
        self.span = self.high - self.low
        self.base = apply_effects(task.model, self.sensors)
        self.windows, self.start_windows = fit_windows(task.train, task.settings)

    def effects_at(self, x) -> dict[str, Effect]:
        out, i = {}, 0
        for name, size in zip(self.names, self.sizes):
            out[name] = Effect(self.forms[name][0], tuple(x[i : i + size]))
            i += size
        return out

    def model_at(self, x) -> Model:
        return apply_effects(self.base, self.effects_at(x))

    def best_start(self) -> np.ndarray:
        counts = self.task.nominal_counts
        return _best_start(self.starts, self.low, self.high, self.model_at, self.start_windows, counts)

    def residuals(self, windows: Windows) -> Residuals:
        return Residuals(self.model_at, windows, self.task.nominal_counts, self.span, self.high)

    def solve(self, residuals: Residuals, start: np.ndarray, max_nfev: int):
        """``scipy.optimize.least_squares`` of ``residuals`` from ``start`` (trust region reflective, in the bounds)."""
        return least_squares(
            residuals.cost,
            start,
            jac=residuals.jacobian,
            bounds=(self.low, self.high),
            x_scale=np.maximum(self.span, 1e-12) / 10.0,
            max_nfev=max_nfev,
            ftol=COST_TOLERANCE,
            method="trf",
        )


def _least_squares(task: FitTask, new_form: dict[str, str]):
    """Least squares of every fitted parameter of ``task.model`` with ``task.fixed`` (started from their values)
    and the new effect in the form ``new_form`` (from the best of its starts); returns (effects, at_bounds,
    bootstrap samples per effect, the mean squared residual [counts^2])."""
    settings, counts = task.settings, task.nominal_counts
    problem = _Problem(task, new_form)
    names, sizes, low, high, span = problem.names, problem.sizes, problem.low, problem.high, problem.span
    residuals = problem.residuals(problem.windows)
    result = problem.solve(residuals, problem.best_start(), settings.max_nfev)
    x, total, profiles = result.x, float(2.0 * result.cost), {}
    if not task.frozen:  # a fit beside frozen earlier effects only ranks the candidate; its refit searches
        x, total, profiles = _search_jumps(
            residuals.cost, result, new_form, names, sizes, (low, high), problem.scales.command_levels
        )
    linearised = residuals.linearised
    at_fit = linearised if "x" in linearised and np.array_equal(linearised["x"], x) else None
    samples = _jump_samples(
        bootstrap_samples(problem.model_at, x, problem.windows, counts, span, low, high, settings, at_fit),
        profiles,
        residuals.last,
        settings,
    )
    split, i = {name: task.fixed_samples[name] for name in problem.sensors if name in task.fixed_samples}, 0
    for name, size in zip(names, sizes):
        split[name] = samples[:, i : i + size]
        i += size
    return (
        {**problem.sensors, **problem.effects_at(x)},
        at_bounds(names, [problem.forms[n][0] for n in names], x, low, high),
        split,
        total / result.fun.size,  # the mean squared residual [counts^2]
    )


def _screened(task: FitTask, new_form: dict[str, str]) -> tuple[list[float], dict[str, Effect], float]:
    """The screen of the new effect in the form ``new_form`` (:func:`screen_task`): its best start, the effects
    after ``SCREEN_EVALUATIONS`` cost evaluations on the start windows from there, and the start windows' mean
    excess squared residual [counts^2] with them."""
    problem = _Problem(task, new_form)
    start = problem.best_start()
    residuals = problem.residuals(problem.start_windows)
    result = problem.solve(residuals, start, SCREEN_EVALUATIONS)
    if not np.array_equal(residuals.last["x"], result.x):  # the solver's last evaluation was a refused step
        residuals.cost(result.x)
    excess = window_excess(residuals.last["raw"], problem.start_windows.floor).mean()
    return list(start), {**problem.sensors, **problem.effects_at(result.x)}, float(excess)


def _forms(task: FitTask, new_form: dict[str, str], scales: Scales) -> tuple[dict, dict]:
    """Per fitted effect its form and starts (a fixed effect from its values, the new one from ``task.start``, a
    screen's start of its form in ``task.starts``, or its form's starts), and the effects held as they are (sensor
    effects, or every fixed one when frozen)."""
    forms = (
        {}
        if task.frozen
        else {name: (effect.form, [list(effect.values)]) for name, effect in task.fixed.items() if CANDIDATES[name].fit}
    )
    for name, form_name in new_form.items():
        if task.start is not None:
            starts = [list(task.start.values)]
        elif form_name in task.starts:
            starts = [list(task.starts[form_name])]
        else:
            starts = form_starts(name, CANDIDATES[name].form(form_name), scales)
        forms[name] = (form_name, starts)
    sensors = {name: effect for name, effect in task.fixed.items() if task.frozen or not CANDIDATES[name].fit}
    return forms, sensors


def _stacked(forms: dict, scales: Scales):
    """The fitted parameters stacked in one vector: (effect names, their sizes, lower and upper bounds, every
    combination of the effects' starts)."""
    names = tuple(forms)
    lows, highs, sizes, starts = [], [], [], [[]]
    for name in names:
        low, high = CANDIDATES[name].form(forms[name][0]).bounds(scales)
        lows, highs, sizes = lows + low, highs + high, sizes + [len(low)]
        starts = [s + list(t) for s in starts for t in forms[name][1]]
    return names, sizes, np.array(lows), np.array(highs), starts


def _best_start(starts: list, low: np.ndarray, high: np.ndarray, model_at, windows: Windows, counts: int) -> np.ndarray:
    """The start (clipped inside the bounds) of least squared residual on the start ``windows``, each window's
    initial state refined by ``SCREEN_STEPS`` Levenberg-Marquardt steps (the first step takes the smoothed states'
    error off, the later ones polish a ranking they rarely change); the only one without a ranking."""
    span = high - low
    candidates = [np.clip(np.array(start, dtype=float), low + 1e-9 * span, high - 1e-9 * span) for start in starts]
    if len(candidates) == 1:
        return candidates[0]

    def ranked(x) -> float:
        r = projected_residuals(model_at(x), windows, counts, sensitivities=False, steps=SCREEN_STEPS)[0]
        return float(np.sum(_flat(r) ** 2))

    return min(candidates, key=ranked)


class Residuals:
    """A fit's residuals on ``windows`` as a function of its parameters (the initial states' share projected out,
    :func:`~furuta_drake.diagnosis.gap.metric.projected_residuals`) and their Jacobian (:func:`_columns`), for
    ``scipy.optimize.least_squares``. ``last`` keeps the last evaluation (residuals, states, ``x``),
    ``linearised`` the last Jacobian's with its columns and the states' sensitivities (the bootstrap at the fit
    reuses them). The states' sensitivities are simulated for the Jacobian alone: a trial step the solver refuses,
    and a line search's evaluation, never need them."""

    def __init__(self, model_at, windows: Windows, counts: int, span, high):
        self.model_at, self.windows, self.counts, self.span, self.high = model_at, windows, counts, span, high
        self.last, self.linearised = {}, {}

    def cost(self, x) -> np.ndarray:
        raw, states, _ = projected_residuals(self.model_at(x), self.windows, self.counts, sensitivities=False)
        self.last.clear()
        self.last.update(raw=raw, states=states, x=np.array(x))
        return _flat(raw)

    def jacobian(self, x) -> np.ndarray:
        last = self.last
        if "x" not in last or not np.array_equal(last["x"], x):
            self.cost(x)
        last["state_jacobians"] = state_jacobians(self.model_at(x), self.windows, last["states"], self.counts)
        last["columns"] = _columns(self.model_at, x, self.windows, last, self.counts, self.span, self.high)
        self.linearised.clear()
        self.linearised.update(last)
        return np.column_stack([_flat(column) for column in last["columns"]])


def _search_jumps(cost, result, new_form: dict, names: tuple, sizes: list, bounds, levels):
    """The least-squares ``result``'s parameters and cost, with the parameter of a new form at which the cost jumps
    found by :func:`~furuta_drake.diagnosis.selection.jumps.line_search` from there; and per such parameter's index, the
    search's profile of residuals."""
    x, total, profiles = result.x, float(2.0 * result.cost), {}
    for name, form in new_form.items():
        jump = CANDIDATES[name].form(form).jump
        if jump is not None:
            i = sum(sizes[: names.index(name)]) + jump
            x, total, profiles[i] = line_search(cost, x, i, bounds[0][i], bounds[1][i], levels)
    return x, total, profiles


def _jump_samples(samples: np.ndarray, profiles: dict, last: dict, settings: DiagnosisSettings) -> np.ndarray:
    """``samples`` with the bootstrap of every searched parameter replaced by the block bootstrap of its search
    (:func:`~furuta_drake.diagnosis.selection.jumps.bootstrap_argmin`; the linearised step cannot move it)."""
    if not profiles:
        return samples
    shapes = [raw.shape for raw in last["raw"]]  # (horizon, 2, W) per log, as the flat residuals hold them

    def per_window(flat: np.ndarray) -> np.ndarray:
        out, i = [], 0
        for h, s, w in shapes:
            n = (h - 1) * s * w
            out.append(np.sum(flat[i : i + n].reshape(h - 1, s, w) ** 2, axis=(0, 1)))
            i += n
        return np.concatenate(out)

    windows = sum(shape[2] for shape in shapes)
    rng = np.random.default_rng(settings.seed)
    weights = rng.multinomial(windows, np.full(windows, 1.0 / windows), settings.interval_resamples)
    out = samples.copy()
    for i, profile in profiles.items():
        out[:, i] = bootstrap_argmin(profile, per_window, weights, rng)
    return out


def _columns(model_at, x, windows: Windows, last: dict, counts: int, span, high) -> list[list[np.ndarray]]:
    """Per parameter, the per-log residual change (horizon, 2, W) per unit of the parameter, at the initial
    states of ``last``, with what the states could absorb projected out (Kaufman). A column is exact where the
    surrogate is differentiable along the parameter's step
    (:func:`~furuta_drake.diagnosis.gap.metric.parameter_slopes_of`: the packed parameters' and the arm torque's changes
    over the step carried through the integration's forward sensitivities, every such column in one surrogate pass),
    else a finite difference of the residuals (every such column's model in one surrogate call): a threshold dead zone's
    width, whose cost jumps where it crosses a command, and a step that changes the kernel's branches
    (:func:`~furuta_drake.effects.surrogate.same_branches`: a friction kind, a Stribeck curve, LuGre's bristle damping).
    Every column is projected in one solve per window."""
    steps, models = [], []
    for i in range(x.size):
        step = JACOBIAN_STEP * max(abs(x[i]), span[i] * 1e-3)
        if x[i] + step > high[i]:
            step = -step
        shifted = x.copy()
        shifted[i] += step
        steps.append(step)
        models.append(model_at(shifted))
    model, changes = model_at(x), [None] * x.size
    exact = [i for i in range(x.size) if same_branches(model, models[i])]
    differenced = [i for i in range(x.size) if i not in exact]
    if exact:
        slopes = parameter_slopes_of(
            model, [models[i] for i in exact], [steps[i] for i in exact], windows, last["states"], counts
        )
        for i, change in zip(exact, slopes):
            changes[i] = change
    if differenced:
        shifted_r = fixed_state_residuals_of([models[i] for i in differenced], windows, last["states"], counts)
        for i, r in zip(differenced, shifted_r):
            changes[i] = [(new - old) / steps[i] for new, old in zip(r, last["raw"])]
    logs = range(len(last["raw"]))
    stacked = [np.stack([change[log] for change in changes], axis=2) for log in logs]  # (h, 2, K, W) per log
    projected = [project_out_states(c, J) for c, J in zip(stacked, last["state_jacobians"])]
    return [[projected[log][:, :, i] for log in logs] for i in range(x.size)]


def bootstrap_samples(
    model_at, x, windows: Windows, counts: int, span, low, high, settings: DiagnosisSettings, at_fit: dict | None
) -> np.ndarray:
    """(resamples, params) bootstrap of the fitted parameters over ``windows`` (module docstring); ``at_fit``: the
    residuals, states and Jacobian columns the fit computed at ``x`` on these windows, when it did."""
    if at_fit is None:
        at_fit = dict(zip(("raw", "states", "state_jacobians"), projected_residuals(model_at(x), windows, counts)))
        at_fit["columns"] = _columns(model_at, x, windows, at_fit, counts, span, high)
    last, columns = at_fit, at_fit["columns"]
    normal, gradient = [], []
    for i, raw in enumerate(last["raw"]):  # per log: the windows' normal equations
        J = np.stack([np.nan_to_num(column[i][1:]) for column in columns], axis=-1)  # (h - 1, 2, W, n)
        r = np.nan_to_num(raw[1:], nan=1e6)
        Jw = J.transpose(2, 0, 1, 3).reshape(J.shape[2], -1, J.shape[3])  # (W, (h - 1) 2, n)
        normal.append(Jw.transpose(0, 2, 1) @ Jw)
        gradient.append((Jw.transpose(0, 2, 1) @ r.transpose(2, 0, 1).reshape(r.shape[2], -1, 1))[..., 0])
    normal, gradient = np.concatenate(normal), np.concatenate(gradient)
    W = normal.shape[0]
    rng = np.random.default_rng(settings.seed)
    weights = np.vstack([np.ones(W), rng.multinomial(W, np.full(W, 1.0 / W), settings.interval_resamples)])
    H = np.einsum("bw,wij->bij", weights, normal)
    ridge = 1e-9 * np.maximum(np.einsum("bii->bi", H), 1e-300)
    steps = -np.linalg.solve(
        H + ridge[:, :, None] * np.eye(x.size), np.einsum("bw,wi->bi", weights, gradient)[..., None]
    )[..., 0]
    return np.clip(x + steps[1:] - steps[0], low, high)


def interval(samples: np.ndarray) -> tuple[float, float]:
    """The 95 % interval of bootstrap ``samples`` of one parameter."""
    low, high = np.percentile(samples, INTERVAL)
    return float(low), float(high)


def at_bounds(names: tuple[str, ...], forms: list[str], x: np.ndarray, low: np.ndarray, high: np.ndarray) -> list[str]:
    """The fitted parameters that ended at a bound of their search range, as "effect.param (lower|upper)": an
    accepted effect stretched to its range's edge may stand in for another effect of a similar shape."""
    labels = [f"{name}.{param}" for name, form in zip(names, forms) for param in CANDIDATES[name].form(form).params]
    tolerance = BOUND_TOLERANCE * (high - low)
    return [f"{label} (lower)" for label, v, lo, t in zip(labels, x, low, tolerance) if v - lo <= t] + [
        f"{label} (upper)" for label, v, hi, t in zip(labels, x, high, tolerance) if hi - v <= t
    ]


def _flat(r: list[np.ndarray]) -> np.ndarray:
    """Per-log residuals (horizon, 2, W) as one vector for the least squares (the start row 0 left out); a
    diverged prediction costs 1e6 counts."""
    return np.nan_to_num(np.concatenate([v[1:].ravel() for v in r]), nan=1e6, posinf=1e6, neginf=-1e6)
