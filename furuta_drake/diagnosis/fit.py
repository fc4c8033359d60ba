"""Fit each candidate on the train windows: bounded least squares of the k-step residuals
(``scipy.optimize.least_squares`` from the best of several starts where the cost is multimodal), in parallel over
candidates. The cost re-projects the windows' initial states for every parameter vector (variable projection);
its Jacobian is Kaufman's approximation (the residuals' change at the projected states, with the part the
states could absorb projected out), so a column costs one batch prediction.

The sensor effects are estimated from the data directly, because no trajectory can fit white noise:
``encoder_quantization`` from the grid the angle increments lie on (the largest k such that every increment is
a multiple of k counts of the rig's encoder), ``measurement_noise`` from the robust spread of the angles' second
differences (white noise sigma gives a second difference of std sqrt(6) sigma, quantisation of a smooth motion
almost none).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from furuta_drake.diagnosis.candidates import CANDIDATES, Scales, apply_effects
from furuta_drake.diagnosis.gap import (
    Windows, evaluate_gap, fixed_state_residuals, project_out_states, projected_residuals, residuals,
)
from furuta_drake.diagnosis.logs import RunLog
from furuta_drake.diagnosis.parallel import map_in_processes
from furuta_drake.diagnosis.surrogate import Model

FIT_WINDOWS = 40  # windows of the train logs used in the least squares (evenly drawn, seeded)
START_WINDOWS = 16  # of those, the windows that rank the starts of a fit
MAX_NFEV = 20  # cost evaluations of one least-squares fit (Jacobians not counted)
JACOBIAN_STEP = 1e-3  # relative finite-difference step of the parameter sensitivities
NOISE_FLOOR_COUNTS = 0.5  # a noise estimate below this many counts is no evidence of noise


@dataclass
class FitResult:
    name: str  # a candidate, or "a+b" for a pair
    effects: dict[str, list[float]]  # effect name -> fitted parameters (SI)
    train_gap: float  # [counts]
    success: bool
    message: str
    at_bounds: list[str] = field(default_factory=list)  # "effect.param (lower|upper)" fitted at a search bound


def scales_of(logs: list[RunLog], model: Model) -> Scales:
    command = max(float(np.max(np.abs(log.torque_command))) for log in logs)
    return Scales(torque=model.d, command=max(command, 1e-9), arm_inertia=model.a, pendulum_inertia=model.b,
                  period=float(np.median([log.sample_period for log in logs])))


def quantization_estimate(logs: list[RunLog], nominal_counts: int) -> float:
    """Counts per revolution the angle increments support: nominal / k for the largest k <= 64 dividing every
    non-zero increment (in nominal counts), or the nominal counts when none does."""
    count = 2 * np.pi / nominal_counts
    steps = np.concatenate([np.round(np.diff(np.concatenate([log.theta, log.phi])) / count) for log in logs])
    steps = np.abs(steps[(steps != 0)])
    if steps.size < 20:
        return float(nominal_counts)
    for k in range(64, 1, -1):
        if np.mean(steps % k == 0) > 0.99:
            return float(nominal_counts / k)
    return float(nominal_counts)


def noise_estimate(logs: list[RunLog], nominal_counts: int) -> float:
    """White measurement noise sigma [rad] from the variance of the angles' second differences: white noise
    sigma gives 6 sigma^2, the rounding to the encoder's step (independent once the noise spans a step) 6 step^2 / 12
    more, which is subtracted (the step from :func:`quantization_estimate`); outliers (the motion's own jerks) beyond 6 robust sigmas are left out. 0 when
    below ``NOISE_FLOOR_COUNTS`` counts. (A median absolute deviation of these integer counts would be
    quantised itself: it reads 1.2 counts for a noise of 1.5.)"""
    count = 2 * np.pi / nominal_counts
    second = np.concatenate([np.diff(angle, 2) / count for log in logs for angle in (log.theta, log.phi)])
    centre = np.median(second)
    spread = 1.4826 * np.median(np.abs(second - centre)) + 1.0
    kept = second[np.abs(second - centre) <= 6.0 * spread]
    step = nominal_counts / quantization_estimate(logs, nominal_counts)  # [counts]
    sigma = float(np.sqrt(max(np.mean((kept - centre) ** 2) / 6.0 - step**2 / 12.0, 0.0)))
    return sigma * count if sigma >= NOISE_FLOOR_COUNTS else 0.0


def _joint(names: tuple[str, ...], scales: Scales, fitted: dict[str, list[float]]):
    lows, highs, sizes = [], [], []
    for name in names:
        low, high = CANDIDATES[name].bounds(scales)
        lows += low
        highs += high
        sizes.append(len(low))
    starts = [[]]
    for name in names:
        own = CANDIDATES[name].starts(scales)
        options = [fitted[name]] if name in fitted else own
        starts = [s + list(t) for s in starts for t in options]
    return np.array(lows), np.array(highs), sizes, starts


def _split(names, sizes, x) -> dict[str, list[float]]:
    out, i = {}, 0
    for name, size in zip(names, sizes):
        out[name] = [float(v) for v in x[i:i + size]]
        i += size
    return out


def fit_effects(names: tuple[str, ...], model: Model, windows: Windows, logs: list[RunLog],
                nominal_counts: int, fitted: dict[str, list[float]] | None = None) -> FitResult:
    """Fit the candidates ``names`` jointly (one name: a single candidate) on ``windows``. ``fitted``: single
    fits of some members; the starts then combine each such member's fit with every other member's own
    starts (a partner that alone fitted to nothing still starts from its candidate starts)."""
    scales = scales_of(logs, model)
    fixed = {}
    for name in names:
        if not CANDIDATES[name].fit:
            fixed[name] = [quantization_estimate(logs, nominal_counts) if name == "encoder_quantization"
                           else noise_estimate(logs, nominal_counts)]
    fitted_names = tuple(n for n in names if CANDIDATES[n].fit)
    base = apply_effects(model, fixed)
    subset = windows.subset(FIT_WINDOWS)
    if not fitted_names:
        gap = evaluate_gap(base, windows, nominal_counts).gap
        return FitResult("+".join(names), fixed, gap, True, "estimated from the data")
    low, high, sizes, starts = _joint(fitted_names, scales, fitted or {})
    span = high - low

    last = {}

    def model_at(x):
        return apply_effects(base, _split(fitted_names, sizes, x))

    def cost(x):
        r, states, state_jacobians = projected_residuals(model_at(x), subset, nominal_counts)
        last.update(x=np.array(x), states=states, raw=r, state_jacobians=state_jacobians, r=_flat(r))
        return last["r"]

    def jacobian(x):
        if "x" not in last or not np.array_equal(last["x"], x):
            cost(x)
        columns = []
        for i in range(x.size):
            step = JACOBIAN_STEP * max(abs(x[i]), span[i] * 1e-3)
            if x[i] + step > high[i]:
                step = -step
            shifted = x.copy()
            shifted[i] += step
            shifted_r = fixed_state_residuals(model_at(shifted), subset, last["states"], nominal_counts)
            change = [project_out_states(new - old, J)
                      for new, old, J in zip(shifted_r, last["raw"], last["state_jacobians"])]
            columns.append(_flat(change) / step)
        return np.column_stack(columns)

    # Several starts where the cost is multimodal: the least squares runs from the one with the lowest cost on
    # a smaller draw of windows (a start only has to land in the right basin).
    candidates = [np.clip(np.array(start, dtype=float), low + 1e-9 * span, high - 1e-9 * span) for start in starts]
    screen = subset.subset(START_WINDOWS, seed=1)
    x0 = candidates[0] if len(candidates) == 1 else min(candidates, key=lambda x: _squared_gap(
        model_at(x), screen, nominal_counts))
    result = least_squares(cost, x0, jac=jacobian, bounds=(low, high), x_scale=np.maximum(span, 1e-12) / 10.0,
                           max_nfev=MAX_NFEV, method="trf")
    x, success, message = result.x, bool(result.success), result.message
    effects = {**fixed, **_split(fitted_names, sizes, x)}
    gap = evaluate_gap(apply_effects(model, effects), windows, nominal_counts).gap
    return FitResult("+".join(names), effects, gap, success, str(message),
                     at_bounds(fitted_names, x, low, high))


BOUND_TOLERANCE = 1e-3  # a parameter within this fraction of its range from a bound is "at" it


def at_bounds(names: tuple[str, ...], x: np.ndarray, low: np.ndarray, high: np.ndarray) -> list[str]:
    """The fitted parameters that ended at a bound of their search range, as "effect.param (lower|upper)": an
    accepted effect stretched to its range's edge may stand in for another effect of a similar shape."""
    labels = [f"{name}.{param}" for name in names for param in CANDIDATES[name].params]
    tolerance = BOUND_TOLERANCE * (high - low)
    return ([f"{label} (lower)" for label, v, lo, t in zip(labels, x, low, tolerance) if v - lo <= t]
            + [f"{label} (upper)" for label, v, hi, t in zip(labels, x, high, tolerance) if hi - v <= t])


def _flat(r: list[np.ndarray]) -> np.ndarray:
    """Per-log residuals as one vector for the least squares; a diverged prediction costs 1e6 counts."""
    return np.nan_to_num(np.concatenate([v[1:].ravel() for v in r]), nan=1e6, posinf=1e6, neginf=-1e6)


def _squared_gap(model: Model, windows: Windows, nominal_counts: int) -> float:
    return float(np.sum(_flat(residuals(model, windows, nominal_counts)) ** 2))


def _fit_task(args):
    return fit_effects(*args)


def fit_all(groups: list[tuple[str, ...]], model: Model, windows: Windows, logs: list[RunLog],
            nominal_counts: int, workers: int | None = None, progress=None,
            fitted: dict | None = None) -> dict[str, FitResult]:
    """Fit every group of candidates (a 1-tuple for a single effect) in parallel processes; ``fitted``: group
    -> single fits of its members to start from (see :func:`fit_effects`)."""
    tasks = [(group, model, windows, logs, nominal_counts, (fitted or {}).get(group)) for group in groups]
    report = None if progress is None else (lambda result: progress(result.name))
    return {result.name: result for result in map_in_processes(_fit_task, tasks, workers, report)}
