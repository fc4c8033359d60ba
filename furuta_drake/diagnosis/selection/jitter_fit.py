"""The spread of a jittering input delay, read from the residuals' variance by likelihood.

A jittering delay's spread barely moves the predicted mean (the expected command is smooth in the spread), so
least squares cannot find it on a coarse encoder. Its signature is the variance sigma_j^2(n; s) its draws add to
each residual sample n (:mod:`furuta_drake.effects.jitter`). With the residuals r_n of the mean prediction and the
sensor's variance sigma_s^2, the spread s maximises the Gaussian log-likelihood of the windows' residuals

    l(s) = -1/2 sum_n [r_n^2 / (sigma_s^2 + sigma_j^2(n; s)) + log(sigma_s^2 + sigma_j^2(n; s))],

which penalises a predicted variance that is too large as well as one too small. Any extra variance raises l, so
the jitter is *credited* only when it beats an unstructured one, sigma_s^2 + c with a constant c >= 0 fitted the
same way, by more than chance: the 5 % lower bound of l(s) - l(c) over a bootstrap of windows must be positive,
and the spread's 95 % interval must stay off the ends of its search range (one pressed against the range's top
is variance claimed for a misfit of the mean: an actuator lag read as a jitter's moving average; the causal limit
below it is physics and may be reached). The residuals must then hold extra variance *where*
the jitter puts it (after each command change, through the window's impulse responses), not merely extra
variance. A uniform delay cannot reach below zero, so the spread is at most the mean delay over sqrt(3).

The same comparison is then made on the held-out windows (:func:`heldout_jitter`): the spread credited on the
train windows is named only when the held-out residuals' log-likelihood under its variance of each sample beats
that under the constant variance fitted on the train windows, with a 5 % bootstrap lower bound above 0. A
likelihood is a proper score: a variance claimed too large costs as much as one too small.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from furuta_drake.diagnosis.gap.metric import (
    Windows,
    jitter_energy,
    jitter_variances,
    projected_residuals,
    squared_excess,
)
from furuta_drake.diagnosis.selection.rule import LOWER_BOUND_QUANTILE
from furuta_drake.effects.surrogate import Model, sensor_variance
from furuta_drake.effects.vocabulary import causal_spread

GRID = 41  # spreads and constant variances on which the likelihood is evaluated (log-spaced)
JITTER_WINDOWS = 400  # train windows (a seeded draw) the held-out judgement's constant variance is fitted on


@dataclass(frozen=True)
class SpreadEvidence:
    """The spread of largest likelihood [s], its bootstrap samples, and whether it is credited (module docstring)."""

    spread: float
    samples: np.ndarray
    credited: bool


def spread_by_likelihood(
    model: Model, windows: Windows, nominal_counts: int, bounds: tuple[float, float], resamples: int, seed: int
) -> SpreadEvidence:
    """The spread of ``model``'s jittering delay within ``bounds`` [s] that maximises the likelihood of its
    residuals on ``windows``, from ``resamples`` seeded bootstrap draws of the windows (module docstring)."""
    low, high = bounds[0], min(bounds[1], causal_spread(model.delay))
    if high <= low:
        return SpreadEvidence(low, np.full(resamples, low), False)
    r, states, jacobians = projected_residuals(model, windows, nominal_counts)
    energy = jitter_energy(model, windows, states, jacobians, nominal_counts)
    squares = squared_excess(r)
    sensor = sensor_variance(model, nominal_counts)
    spreads = np.geomspace(low, high, GRID)
    structured = np.stack(
        [
            _window_likelihoods(
                squares, [sensor + v[1:] for v in jitter_variances(model.replace(delay_spread=s), windows, energy)]
            )
            for s in spreads
        ]
    )
    excess = max(float(np.mean(np.concatenate([x.ravel() for x in squares]))) - sensor, 1e-12)
    constants = np.concatenate([[0.0], np.geomspace(1e-3 * excess, 10.0 * excess, GRID)])
    unstructured = np.stack(
        [_window_likelihoods(squares, [np.full_like(x, sensor + c) for x in squares]) for c in constants]
    )
    W = structured.shape[1]
    rng = np.random.default_rng(seed)
    weights = np.vstack([np.ones(W), rng.multinomial(W, np.full(W, 1.0 / W), resamples)])
    best, alternative = weights @ structured.T, weights @ unstructured.T  # (1 + resamples, grid)
    chosen = best.argmax(axis=1)
    gain = best.max(axis=1) - alternative.max(axis=1)
    samples = spreads[chosen[1:]]
    inside = np.percentile(samples, 2.5) > low and np.percentile(samples, 97.5) < bounds[1] * (1.0 - 1e-9)
    credited = bool(np.quantile(gain[1:], LOWER_BOUND_QUANTILE) > 0.0 and inside)
    return SpreadEvidence(float(spreads[chosen[0]]), samples, credited)


@dataclass(frozen=True)
class HeldoutJitter:
    """A jittering delay judged on held-out windows: each window's log-likelihood gain over the constant variance
    [nats], the 5 % bootstrap lower bound of its mean, and the mean variance the draws add to each window's
    residuals [counts^2]."""

    gain: np.ndarray
    lower_bound: float
    claimed: np.ndarray

    @property
    def credited(self) -> bool:
        return self.lower_bound > 0.0


def jitter_claim(model: Model, windows: Windows, nominal_counts: int) -> tuple[list, np.ndarray]:
    """``model``'s squared residuals on ``windows`` past each start and the variance its jittering delay adds to each
    of them (per log (horizon - 1, 2, W) [counts^2]), and each window's mean of that variance."""
    r, states, jacobians = projected_residuals(model, windows, nominal_counts)
    energy = jitter_energy(model, windows, states, jacobians, nominal_counts)
    variances = [v[1:] for v in jitter_variances(model, windows, energy)]
    return list(zip(squared_excess(r), variances)), np.concatenate([v.mean(axis=(0, 1)) for v in variances])


def heldout_jitter(
    model: Model, train: Windows, heldout: Windows, nominal_counts: int, bootstrap, seed: int
) -> HeldoutJitter:
    """``model``'s jittering delay judged on ``heldout`` (module docstring): the constant variance is the one of
    largest likelihood on (at most ``JITTER_WINDOWS`` of) the train windows; ``bootstrap`` resamples the held-out
    windows."""
    sensor = sensor_variance(model, nominal_counts)
    r = projected_residuals(model, train.subset(JITTER_WINDOWS, seed), nominal_counts, sensitivities=False)[0]
    constant = max(float(np.mean(np.concatenate([x.ravel() for x in squared_excess(r)]))) - sensor, 0.0)
    pairs, claimed = jitter_claim(model, heldout, nominal_counts)
    squares = [x for x, _ in pairs]
    structured = _window_likelihoods(squares, [sensor + v for _, v in pairs])
    unstructured = _window_likelihoods(squares, [np.full_like(x, sensor + constant) for x in squares])
    gain = structured - unstructured
    return HeldoutJitter(gain, float(np.quantile(bootstrap.means(gain), LOWER_BOUND_QUANTILE)), claimed)


def _window_likelihoods(squares: list[np.ndarray], variances: list[np.ndarray]) -> np.ndarray:
    """Each window's Gaussian log-likelihood (up to a constant) of its squared residuals (samples, 2, W) under the
    variances of each sample [counts^2]."""
    return np.concatenate([-0.5 * (x / v + np.log(v)).sum(axis=(0, 1)) for x, v in zip(squares, variances)])
