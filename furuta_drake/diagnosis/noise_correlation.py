"""The correlation time of measurement noise that an interface low-passes before it logs.

First-order (AR(1)) noise n_k = a n_(k-1) + sqrt(1 - a^2) sigma e_k, a = exp(-T / tau), gives the lag-L second
differences n_(k+L) - 2 n_k + n_(k-L) the variance

    V_L = sigma^2 (6 - 8 a^L + 2 a^(2L))        (white noise: 6 sigma^2 at every lag)

and the rounding to the encoder's step adds 6 step^2 / 12 to each, as in the white estimate (the rounding of a
motion that crosses counts at most samples is independent from sample to sample; a slow one's adds less, and
the correlation time read is then too long). The ratio V_2 / V_1 = (1 + a)(3 - a^2) / (3 - a) rises from 1
(white) towards 2 (a slow drift) and gives a; V_1 then gives sigma. Both are steep functions of that ratio: a
few percent on it moves sigma by about 10 % and tau by about 20 % at a = 0.67. A smooth motion adds
a^2 dt^4 L^4, far below the noise at the two shortest lags wherever the noise is read at all
(:func:`furuta_drake.diagnosis.fit.noise_estimate` extrapolates it away where it is not).
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import brentq

from furuta_drake.effects.vocabulary import Effect

CORRELATED_MIN_PERIODS = 1.0  # the correlated form is read when tau exceeds this many sample periods (shorter:
# the noise is white to the second differences, a within a factor e of white's 0)
BLOCK = 100  # samples of a bootstrap block
A_MAX = 0.999  # the largest a read (tau of 1000 periods: beyond, the noise is a drift the states absorb)


def lag_ratio(a):
    """V_2 / V_1 of first-order noise of coefficient ``a`` (the module docstring)."""
    return (1.0 + a) * (3.0 - a * a) / (3.0 - a)


def coefficient(ratio: float) -> float:
    """The a in [0, ``A_MAX``] of :func:`lag_ratio` ``ratio`` (0 at or below 1, ``A_MAX`` at or above its ratio)."""
    if ratio <= 1.0:
        return 0.0
    if ratio >= lag_ratio(A_MAX):
        return A_MAX
    return float(brentq(lambda a: lag_ratio(a) - ratio, 0.0, A_MAX))


def _squares(signals: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Per centre sample the squared lag-1 and lag-2 second differences [counts^2] of ``signals`` (each in counts,
    at one sample period; those shorter than a lag-2 stencil left out), samples beyond 6 robust sigmas of either
    left out."""
    first, second = [], []
    for values in signals:
        if values.size >= 5:
            first.append(values[3:-1] - 2 * values[2:-2] + values[1:-3])
            second.append(values[4:] - 2 * values[2:-2] + values[:-4])
    d1, d2 = np.concatenate(first), np.concatenate(second)
    keep = np.ones(d1.size, dtype=bool)
    for d in (d1, d2):
        centre = np.median(d)
        keep &= np.abs(d - centre) <= 6.0 * (1.4826 * np.median(np.abs(d - centre)) + 1.0)
    return (d1[keep] - np.median(d1)) ** 2, (d2[keep] - np.median(d2)) ** 2


def _read(v1, v2, rounding: float, period: float) -> tuple[float, float]:
    """(sigma [counts], tau [s]) from the mean squares ``v1``, ``v2`` of the lag-1 and lag-2 second differences
    less the ``rounding`` variance 6 step^2 / 12 in each."""
    white1, white2 = max(v1 - rounding, 1e-12), max(v2 - rounding, 0.0)
    a = coefficient(white2 / white1)
    sigma = np.sqrt(white1 / (6.0 - 8.0 * a + 2.0 * a * a))
    return float(sigma), float(-period / np.log(a)) if a > 0 else 0.0


def correlated_noise_estimate(
    signals: list[np.ndarray], period: float, count: float, step: float, floor: float, resamples: int, seed: int
) -> tuple[Effect | None, np.ndarray]:
    """The ``correlated`` form of ``measurement_noise`` (noise_std [rad], correlation_time [s]) read from
    ``signals`` (angles or their residuals in counts of ``count`` rad, sampled every ``period`` s, on a grid of
    ``step`` counts), and ``resamples`` bootstrap values (resamples, 2) over blocks of ``BLOCK`` samples; (None,
    empty) when the noise is below ``floor`` counts or its correlation time below ``CORRELATED_MIN_PERIODS``
    sample periods (the white form's estimate stands)."""
    s1, s2 = _squares(signals)
    rounding = 6.0 * step**2 / 12.0
    sigma, tau = _read(np.mean(s1), np.mean(s2), rounding, period)
    if sigma < floor or tau < CORRELATED_MIN_PERIODS * period:
        return None, np.empty((0, 2))
    blocks = max(1, s1.size // BLOCK)
    size = s1.size // blocks
    sums1, sums2 = (s[: blocks * size].reshape(blocks, size).sum(axis=1) for s in (s1, s2))
    draws = np.random.default_rng(seed).integers(0, blocks, (resamples, blocks))
    samples = np.array(
        [_read(sums1[d].mean() / size, sums2[d].mean() / size, rounding, period) for d in draws]
    ).reshape(-1, 2)
    samples[:, 0] *= count
    return Effect("correlated", (sigma * count, tau)), samples
