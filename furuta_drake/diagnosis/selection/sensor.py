"""The sensor's signature: what the encoders add to the angles, read apart from the dynamic model and judged on
held-out windows by a proper score (stage 5 of the diagnosis).

A coarser encoder and measurement noise change no prediction: they explain the residuals' floor, not their
shape. So they are read from what only a sensor makes, the residuals' content at the highest frequencies the
samples hold and its correlation from sample to sample, and never from the size of the residuals, which a model
error makes as well.

Signature. The lag-L third differences of a window's residuals r (counts),

    t_k = r_(k+3L) - 3 r_(k+2L) + 3 r_(k+L) - r_k,        L = 1, 2,

cancel every misfit whose acceleration is constant over the stencil. Where the applied command holds, a model
error's acceleration changes only with the state, slowly: the stencils kept are those over which the command (at
the model's delay) changes by less than could move the angles by ``LEAK_COUNTS`` over a sample, were the whole
change missing from the model; at friction reversals and other sharp events the differences that lie beyond
``TRIM_SIGMAS`` robust spreads are left out. First-order noise n_k = a n_(k-1) + sqrt(1 - a^2) sigma e_k gives

    E t_k^2 = sigma^2 g(a^L),   g(x) = 20 - 30 x + 12 x^2 - 2 x^3          (white noise: 20 sigma^2)

and the rounding to an encoder step q adds 20 q^2 / 12 where the noise comes before the rounding (the logged
angles then lie on the encoder's grid; noise of a count or more makes the rounding error white) or, where the
logs lie off the grid (noise added after the rounding), the third differences of the rounding of the predicted
angle itself. The refit of each window's initial state takes a share of the noise out of its residuals: each
stencil's expectation is scaled by kappa_k = 1 - |D Q|^2 / |D|^2 (Q an orthonormal basis of the window's state
sensitivities, D the stencil), which makes the size read unbiased at every sample rate.

Sizes (train windows). The white noise's variance is the lag-1 mean square less the rounding's, over the kappas;
the first-order noise's coefficient a solves g(a^2) / g(a) = m_2 / m_1 (the lag-2 and lag-1 mean squares less the
rounding's), its tau = -T / log(a). Intervals come from a bootstrap of the windows. The coarser encoder is the grid
the angle increments lie on (the largest k <= ``MAX_GRID`` dividing all of them, in counts of the rig file).

Score (held-out windows). Each hypothesis (the rig file's sensor; white noise; first-order noise) predicts the
variance of every third difference; a window's score is the sum of their Gaussian log densities (a composite log
score: proper for each difference, so a variance claimed too large costs as much as one too small). A noise is
accepted when its score beats the rig file's sensor with a 5 % bootstrap lower bound above 0 over the held-out
windows, its size is at least ``NOISE_FLOOR_COUNTS`` and at most ``NOISE_PLAUSIBLE_COUNTS`` (an optical encoder
does not misread by many counts: such a size is a model error, and is said to be one); its first-order form when
that beats the white one the same way and its tau is shorter than the window (a correlation as long as the window
cannot be told from a model error). A coarser encoder is accepted when at least ``ON_GRID_SHARE`` of the held-out
increments lie on its grid, with at least ``GRID_MIN_STEPS`` of them (the log score of the increments under the
rig file's encoder, which puts 1 / k of them on that grid by chance, is then lower by more than
GRID_MIN_STEPS log 2).

What a sensor effect accounts for: the variance it adds to each held-out residual beyond the rig file's own
sensor, through the window's refit (sigma^2 times the share of its covariance the projection leaves), reported
apart from what the predictions remove.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import brentq

from furuta_drake.diagnosis.gap.metric import Windows, projected_residuals
from furuta_drake.diagnosis.selection.rule import LOWER_BOUND_QUANTILE
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import Effect
from furuta_drake.rig import encoder_resolution

LEAK_COUNTS = 0.5  # a stencil is steady when the command's change there could move an angle by less [counts]
TRIM_SIGMAS = 6.0  # third differences beyond this many robust spreads (plus one count) are a sharp event's
NOISE_FLOOR_COUNTS = 0.5  # a noise smaller than this is no finding [counts of the rig file's encoder]
NOISE_PLAUSIBLE_COUNTS = 5.0  # an optical encoder's noise larger than this is a model error [counts]
CORRELATED_MIN_PERIODS = 1.0  # a first-order noise's tau must exceed this many sample periods
A_MAX = 0.999  # the largest first-order coefficient read
ON_GRID_SHARE = 0.99  # share of held-out increments that must lie on a coarser grid
GRID_MIN_STEPS = 20  # non-zero held-out increments needed to read a grid
MAX_GRID = 64  # the coarsest grid tried [counts of the rig file's encoder]
LAGS = (1, 2)
VARIANCE_FLOOR = 1e-6  # [counts^2]: no third difference is predicted exactly
THIRD = np.array([-1.0, 3.0, -3.0, 1.0])  # the third difference's taps on r_k, r_(k+L), r_(k+2L), r_(k+3L)


def third_difference_gain(x):
    """g(x) = E t^2 / sigma^2 of first-order noise whose coefficient over the stencil's lag is x (module docstring)."""
    return 20.0 - 30.0 * x + 12.0 * x * x - 2.0 * x**3


def lag_ratio(a):
    """g(a^2) / g(a): the lag-2 over the lag-1 mean square of first-order noise of coefficient ``a``; 1 for white
    noise, rising towards 2 as a approaches 1."""
    return third_difference_gain(a * a) / third_difference_gain(a)


def coefficient(ratio: float) -> float:
    """The a in [0, ``A_MAX``] whose :func:`lag_ratio` is ``ratio`` (0 at or below 1, ``A_MAX`` at or above its)."""
    if not ratio > 1.0:
        return 0.0
    if ratio >= lag_ratio(A_MAX):
        return A_MAX
    return float(brentq(lambda a: lag_ratio(a) - ratio, 0.0, A_MAX))


@dataclass(frozen=True)
class Hypothesis:
    """A sensor: the grid step q and the noise's sigma [counts of the rig file's encoder] and first-order coefficient a
    (0: white)."""

    step: float
    sigma: float = 0.0
    a: float = 0.0


@dataclass
class Signature:
    """The third differences of a set of windows' residuals (module docstring), per lag: their values [counts], the
    index of their window, their refit factor kappa, and the rounding's own contribution [counts^2] where the log
    lies off the grid (NaN on the grid, where the rounding is white)."""

    windows: int
    values: dict[int, np.ndarray]
    window: dict[int, np.ndarray]
    kappa: dict[int, np.ndarray]
    sawtooth: dict[int, np.ndarray]
    bases: list[np.ndarray]  # per log (h, 2, W, n): an orthonormal basis of each window's state sensitivities
    extra: dict[int, np.ndarray] = field(default_factory=dict)  # the same stencils' third differences of other
    # residuals (an injected noise), when asked for

    def variances(self, lag: int, hypothesis: Hypothesis) -> np.ndarray:
        """The variance [counts^2] ``hypothesis`` predicts for every lag-``lag`` third difference."""
        noise = hypothesis.sigma**2 * third_difference_gain(hypothesis.a**lag)
        saw, kappa = self.sawtooth[lag], self.kappa[lag]
        rounding = np.where(np.isnan(saw), kappa * 20.0 * hypothesis.step**2 / 12.0, saw)
        return np.maximum(kappa * noise + rounding, VARIANCE_FLOOR)

    def injected(self, size: float) -> Signature:
        """The signature with ``size`` times the ``extra`` residuals' third differences added (an injected noise)."""
        return replace(self, values={lag: self.values[lag] + size * self.extra[lag] for lag in LAGS})

    def scores(self, hypothesis: Hypothesis) -> np.ndarray:
        """Each window's log score of its third differences under ``hypothesis`` (the Gaussian log densities summed)."""
        out = np.zeros(self.windows)
        for lag in LAGS:
            v = self.variances(lag, hypothesis)
            np.add.at(out, self.window[lag], -0.5 * (self.values[lag] ** 2 / v + np.log(2.0 * np.pi * v)))
        return out

    def sums(self, lag: int, step: float) -> tuple[np.ndarray, np.ndarray]:
        """Per window, the sum of the lag-``lag`` squared third differences less the rounding's contribution at a grid
        of ``step`` counts, and the sum of their kappas: what the sizes are read from."""
        rounding = self.variances(lag, Hypothesis(step))
        excess, kappa = np.zeros(self.windows), np.zeros(self.windows)
        np.add.at(excess, self.window[lag], self.values[lag] ** 2 - rounding)
        np.add.at(kappa, self.window[lag], self.kappa[lag])
        return excess, kappa


def on_grid(log, count: float) -> bool:
    """Whether the log's angle increments are whole counts of ``count`` rad (the noise, if any, came before the
    rounding)."""
    steps = np.diff(np.concatenate([log.theta, log.phi])) / count
    moved = steps[np.abs(steps) > 0.5]
    return moved.size == 0 or float(np.mean(np.abs(moved - np.round(moved)) < 1e-3)) >= ON_GRID_SHARE


def _steady(log, model: Model, starts: np.ndarray, rows: int, span: int, count: float) -> np.ndarray:
    """(rows, W): whether the stencil of ``span`` samples from each window row is steady (module docstring)."""
    period = log.sample_period
    a, b, c = model.arm_inertia_total, model.pendulum_inertia_total, abs(model.coupling)
    reach = period**2 * max(b, c) / max(a * b - c * c, 1e-30) / count  # counts per N m of command change
    jumps = np.abs(np.diff(log.torque_command)) * reach > LEAK_COUNTS
    late = int(np.ceil((model.delay + np.sqrt(3.0) * model.delay_spread) / period - 1e-9))
    marks = np.concatenate([[0], np.cumsum(jumps)])
    first = starts[None, :] + np.arange(rows)[:, None] - late - 2
    last = first + span + 2
    lo, hi = np.clip(first, 0, jumps.size), np.clip(last, 0, jumps.size)
    return marks[hi] == marks[lo]


def signature(model: Model, windows: Windows, nominal_counts: int) -> Signature:
    """The third differences of ``model``'s residuals on ``windows`` (module docstring)."""
    raw, _, jacobians = projected_residuals(model, windows, nominal_counts)
    return signature_of(model, windows, raw, jacobians, nominal_counts)


def signature_of(model: Model, windows: Windows, raw, jacobians, nominal_counts: int, extra=None) -> Signature:
    """The third differences of residuals ``raw`` (per log (h, 2, W) [counts]) of ``model`` on ``windows``, whose
    state sensitivities are ``jacobians`` (per log (h, 2, W, n)); with ``extra`` (other residuals of the same
    shapes) also theirs on the same stencils (``Signature.extra``)."""
    count = encoder_resolution(nominal_counts)
    values, window, kappa, sawtooth, others = ({lag: [] for lag in LAGS} for _ in range(5))
    offset, bases = 0, []
    extra = extra if extra is not None else [None] * len(raw)
    for log, starts, r, J, measured, x in zip(windows.logs, windows.starts, raw, jacobians, windows.measured, extra):
        h, _, W, n = J.shape
        basis = np.linalg.qr(np.nan_to_num(J).transpose(2, 0, 1, 3).reshape(W, 2 * h, n))[0]
        basis = basis.reshape(W, h, 2, n).transpose(1, 2, 0, 3)  # (h, 2, W, n)
        bases.append(basis)
        grid = on_grid(log, count)
        rounding = None if grid else np.round(measured / count - r) - (measured / count - r)
        for lag in LAGS:
            rows = h - 3 * lag
            if rows <= 0:
                continue
            t = sum(tap * r[i * lag : i * lag + rows] for i, tap in enumerate(THIRD))  # (rows, 2, W)
            dq = sum(tap * basis[i * lag : i * lag + rows] for i, tap in enumerate(THIRD))
            k = 1.0 - np.sum(dq**2, axis=-1) / 20.0
            keep = _steady(log, model, starts, rows, 3 * lag, count)[:, None, :] & np.isfinite(t)
            keep = np.broadcast_to(keep, t.shape)
            if grid:
                saw = np.full(t.shape, np.nan)
            else:
                e = sum(tap * rounding[i * lag : i * lag + rows] for i, tap in enumerate(THIRD))
                saw = np.broadcast_to(np.mean(e**2, axis=(0, 1), keepdims=True), t.shape)
            index = np.broadcast_to(offset + np.arange(W), t.shape)
            if x is not None:
                others[lag].append(sum(tap * x[i * lag : i * lag + rows] for i, tap in enumerate(THIRD))[keep])
            values[lag].append(t[keep])
            window[lag].append(index[keep])
            kappa[lag].append(np.clip(k, 0.05, 1.0)[keep])
            sawtooth[lag].append(saw[keep])
        offset += W

    def joined(parts):
        return {lag: np.concatenate(parts[lag]) if parts[lag] else np.empty(0) for lag in LAGS}

    out = Signature(offset, joined(values), joined(window), joined(kappa), joined(sawtooth), bases)
    if extra[0] is not None:
        out.extra = joined(others)
    _trim(out)
    return out


def _trim(sig: Signature) -> None:
    """Leave out, per lag, the third differences beyond ``TRIM_SIGMAS`` robust spreads (plus one count) of their
    median: a friction reversal's or an impact's, which no sensor makes."""
    for lag in LAGS:
        t = sig.values[lag]
        if t.size == 0:
            continue
        centre = np.median(t)
        keep = np.abs(t - centre) <= TRIM_SIGMAS * (1.4826 * np.median(np.abs(t - centre)) + 1.0)
        for part in (sig.values, sig.window, sig.kappa, sig.sawtooth, sig.extra):
            if lag in part:
                part[lag] = part[lag][keep]


def refit_share(sig: Signature, a: float = 0.0) -> np.ndarray:
    """Per window, the share of a first-order noise's variance (coefficient ``a`` per sample; 0: white) that its
    residuals keep past the start once the window's initial state is refitted: the mean over the samples past the
    start of diag((I - P) S (I - P)), S the noise's correlation matrix and P the projection on the window's state
    sensitivities (module docstring)."""
    out = []
    for basis in sig.bases:
        h = basis.shape[0]
        lags = np.abs(np.arange(h)[:, None] - np.arange(h)[None, :])
        S = a**lags if a > 0 else np.eye(h)
        SQ = np.einsum("ij,jawn->iawn", S, basis)  # (h, 2, W, n)
        M = np.einsum("iawm,iawn->wmn", basis, SQ)
        cross = np.einsum("iawn,iawn->iaw", SQ, basis)
        back = np.einsum("iawm,wmn,iawn->iaw", basis, M, basis)
        out.append(np.mean((1.0 - 2.0 * cross + back)[1:], axis=(0, 1)))
    return np.concatenate(out) if out else np.empty(0)


@dataclass
class SensorFinding:
    """A sensor effect read from the data and judged on the held-out windows: its :class:`Effect`, bootstrap
    samples (resamples, params), each held-out window's log-score gain over the rig file's sensor [nats] and the
    5 % bootstrap lower bound of their mean, whether it is accepted (and, when it is not, why), and the variance it
    adds to each held-out window's residuals beyond the rig file's sensor [counts^2]."""

    name: str
    effect: Effect
    samples: np.ndarray
    gain: np.ndarray
    lower_bound: float
    accepted: bool
    claimed: np.ndarray
    note: str = ""

    @property
    def score_gain(self) -> float:
        """The mean log-score gain per held-out window [nats]."""
        return float(np.mean(self.gain)) if self.gain.size else 0.0


def grid_steps(logs, nominal_counts: int) -> np.ndarray:
    """The logs' non-zero angle increments in counts of the rig file's encoder (rounded)."""
    count = encoder_resolution(nominal_counts)
    steps = np.concatenate([np.round(np.diff(np.concatenate([log.theta, log.phi])) / count) for log in logs])
    return np.abs(steps[steps != 0])


def grid_of(logs, nominal_counts: int) -> int:
    """The largest k <= ``MAX_GRID`` such that ``ON_GRID_SHARE`` of the logs' non-zero angle increments are
    multiples of k counts of the rig file's encoder (1: none coarser; also with fewer than ``GRID_MIN_STEPS``)."""
    steps = grid_steps(logs, nominal_counts)
    if steps.size < GRID_MIN_STEPS:
        return 1
    return next((k for k in range(MAX_GRID, 1, -1) if np.mean(steps % k == 0) >= ON_GRID_SHARE), 1)


def grid_score(logs, nominal_counts: int, k: int) -> tuple[float, int]:
    """(the log score of the logs' non-zero increments under a grid of k counts less that under the rig file's
    encoder [nats], their number): on the grid with probability ``ON_GRID_SHARE`` against 1 / k by chance."""
    steps = grid_steps(logs, nominal_counts)
    on = int(np.sum(steps % k == 0))
    off = steps.size - on
    return float(on * np.log(ON_GRID_SHARE * k) + off * np.log((1.0 - ON_GRID_SHARE) * k / (k - 1))), steps.size


_A_GRID = np.linspace(0.0, A_MAX, 2001)


def _coefficients(ratio: np.ndarray) -> np.ndarray:
    """:func:`coefficient` of every ratio (interpolated on a fine grid of a: the ratio rises with a)."""
    return np.interp(ratio, lag_ratio(_A_GRID), _A_GRID, left=0.0, right=A_MAX)


@dataclass(frozen=True)
class NoiseReading:
    """The noise read from train windows: white sigma and first-order (sigma, a), each with its bootstrap draws
    (the first entry of every array is the reading on all windows) [counts; -]."""

    white: np.ndarray
    sigma: np.ndarray
    a: np.ndarray


def read_noise(sig: Signature, step: float, resamples: int, seed: int) -> NoiseReading:
    """The noise sizes of the train signature ``sig`` with the rounding of a grid of ``step`` counts taken off (module
    docstring), on all windows and on ``resamples`` bootstrap draws of them."""
    W = sig.windows
    weights = np.vstack([np.ones(W), np.random.default_rng(seed).multinomial(W, np.full(W, 1.0 / W), resamples)])
    means = {}
    for lag in LAGS:
        excess, kappa = sig.sums(lag, step)
        means[lag] = (weights @ excess) / np.maximum(weights @ kappa, 1e-12)
    white = np.sqrt(np.maximum(means[1] / 20.0, 0.0))
    a = _coefficients(means[2] / np.where(means[1] > 0, means[1], np.inf))
    sigma = np.sqrt(np.maximum(means[1] / third_difference_gain(a), 0.0))
    return NoiseReading(white, sigma, a)


NOISE_WINDOWS = 400  # train windows (a seeded draw) the noise is read on
FORMS = ("white", "correlated")


def _lower_bound(bootstrap, gain: np.ndarray) -> float:
    """The 5 % bootstrap lower bound of the mean of per-window ``gain`` over the held-out windows."""
    return float(np.quantile(bootstrap.means(gain), LOWER_BOUND_QUANTILE))


def _window_grid_gain(windows: Windows, nominal_counts: int, k: int) -> tuple[np.ndarray, np.ndarray]:
    """Per window: the log-score gain of its non-zero angle increments under a grid of k counts over the rig file's
    encoder (:func:`grid_score`) [nats], and how many lie on that grid."""
    count = encoder_resolution(nominal_counts)
    gains, on = [], []
    for measured in windows.measured:
        steps = np.abs(np.round(np.diff(measured, axis=0) / count))
        moved = steps != 0
        hits = np.sum(moved & (steps % k == 0), axis=(0, 1))
        misses = np.sum(moved, axis=(0, 1)) - hits
        gains.append(hits * np.log(ON_GRID_SHARE * k) + misses * np.log((1.0 - ON_GRID_SHARE) * k / (k - 1)))
        on.append(hits)
    return np.concatenate(gains), np.concatenate(on)


def read_sensors(model: Model, train: Windows, heldout: Windows, nominal_counts: int, settings, bootstrap):
    """The sensor effects read from ``train`` beside ``model`` (the final dynamic model, with the rig file's sensor)
    and judged on ``heldout`` (module docstring): the coarser encoder's and the noise's :class:`SensorFinding`,
    accepted or not; ``bootstrap`` resamples the held-out windows."""
    count = encoder_resolution(nominal_counts)
    rig_step = encoder_resolution(model.counts_per_rev) / count
    held = signature(model, heldout, nominal_counts)
    white_share = refit_share(held)
    resamples = settings.interval_resamples
    k = grid_of(train.logs, nominal_counts)
    coarser = k > rig_step * (1.0 + 1e-9)
    step = float(k) if coarser else rig_step
    grid = _grid_finding(heldout, nominal_counts, k if coarser else 1, rig_step, white_share, bootstrap, resamples)
    if not grid.accepted:
        step = rig_step
    noise = _noise_finding(model, train, heldout, nominal_counts, step, held, bootstrap, settings)
    return [grid, noise]


def _grid_finding(heldout, nominal_counts, k, rig_step, white_share, bootstrap, resamples) -> SensorFinding:
    """The coarser encoder of k counts judged on the held-out increments (module docstring)."""
    counts_read = nominal_counts / k
    samples = np.full((resamples, 1), counts_read)
    if k <= 1:
        zero = np.zeros(heldout.count)
        return SensorFinding("encoder_quantization", Effect("", (counts_read,)), samples, zero, 0.0, False, zero)
    gain, on = _window_grid_gain(heldout, nominal_counts, k)
    total = int(np.sum(on))
    steps = grid_steps(heldout.logs, nominal_counts)
    share = float(np.mean(steps % k == 0)) if steps.size else 0.0
    lower = _lower_bound(bootstrap, gain)
    accepted = steps.size >= GRID_MIN_STEPS and share >= ON_GRID_SHARE and lower > 0.0
    note = (
        ""
        if accepted
        else f"{share:.0%} of {steps.size} held-out increments lie on a grid of {k} counts ({total} in the windows)"
    )
    claimed = (k**2 - rig_step**2) / 12.0 * white_share
    return SensorFinding(
        "encoder_quantization", Effect("", (counts_read,)), samples, gain, lower, accepted, claimed, note
    )


def _noise_finding(model, train, heldout, nominal_counts, step, held, bootstrap, settings) -> SensorFinding:
    """The measurement noise read on the train windows and judged on the held-out ones (module docstring)."""
    count = encoder_resolution(nominal_counts)
    period = float(np.median([log.sample_period for log in heldout.logs]))
    sig = signature(model, train.subset(NOISE_WINDOWS, settings.seed), nominal_counts)
    reading = read_noise(sig, step, settings.interval_resamples, settings.seed)
    rig_a = np.exp(-period / model.noise_correlation_time) if model.noise_correlation_time > 0 else 0.0
    rig = Hypothesis(step, model.noise_std / count, rig_a)
    base = held.scores(rig)
    white = Hypothesis(step, reading.white[0])
    first = Hypothesis(step, reading.sigma[0], reading.a[0])
    gain_white, gain_first = held.scores(white) - base, held.scores(first) - base
    tau = -period / np.log(np.clip(reading.a, 1e-300, A_MAX))
    window = float(np.median(heldout.horizons)) * period
    plausible = {
        name: NOISE_FLOOR_COUNTS <= h.sigma <= NOISE_PLAUSIBLE_COUNTS
        for name, h in (("white", white), ("correlated", first))
    }
    first_ok = (
        plausible["correlated"]
        and tau[0] >= CORRELATED_MIN_PERIODS * period
        and np.percentile(tau[1:], 97.5) < window
        and _lower_bound(bootstrap, gain_first - gain_white) > 0.0
        and _lower_bound(bootstrap, gain_first) > 0.0
    )
    rig_claim = rig.sigma**2 * refit_share(held, rig.a)
    if first_ok:
        effect = Effect("correlated", (first.sigma * count, float(tau[0])))
        samples = np.column_stack([reading.sigma[1:] * count, tau[1:]])
        claimed = np.maximum(first.sigma**2 * refit_share(held, first.a) - rig_claim, 0.0)
        return SensorFinding(
            "measurement_noise", effect, samples, gain_first, _lower_bound(bootstrap, gain_first), True, claimed
        )
    lower = _lower_bound(bootstrap, gain_white)
    accepted = plausible["white"] and lower > 0.0
    largest = max(white.sigma, first.sigma)
    note = ""
    if largest > NOISE_PLAUSIBLE_COUNTS:
        note = (
            f"the residuals' fastest part reads as noise of {largest:.1f} counts, more than an optical encoder "
            f"misreads ({NOISE_PLAUSIBLE_COUNTS:g} counts): a model error, not noise"
        )
    elif not accepted and white.sigma >= NOISE_FLOOR_COUNTS:
        note = f"noise of {white.sigma:.2f} counts does not score better on the held-out windows than the rig file's"
    claimed = np.maximum(white.sigma**2 * refit_share(held) - rig_claim, 0.0) if accepted else np.zeros(held.windows)
    effect = Effect("white", (white.sigma * count,))
    return SensorFinding(
        "measurement_noise", effect, reading.white[1:, None] * count, gain_white, lower, accepted, claimed, note
    )
