"""The sensor's signature: sizes read from the residuals' third differences apart from any smooth model error,
unbiased through the refit of each window's initial state, and judged on held-out windows by a proper score that
charges a variance claimed too large as well as one too small."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from furuta_drake.diagnosis.gap.metric import make_windows
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.diagnosis.selection.rule import Bootstrap
from furuta_drake.diagnosis.selection.sensor import (
    NOISE_FLOOR_COUNTS,
    NOISE_PLAUSIBLE_COUNTS,
    Hypothesis,
    coefficient,
    grid_of,
    lag_ratio,
    read_sensors,
    signature,
    third_difference_gain,
)
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects.surrogate import Model
from furuta_drake.rig import RIGS, encoder_resolution

COUNTS, PERIOD = 2048, 2e-3
COUNT = encoder_resolution(COUNTS)
SETTINGS = DiagnosisSettings(interval_resamples=200)


def _rig():
    return RIGS["qube_servo2"]().replace(counts_per_rev=COUNTS, sample_period=PERIOD, motor=None)


def _ar1(rng, n: int, sigma: float, a: float) -> np.ndarray:
    """First-order noise of std ``sigma`` and coefficient ``a`` per sample, from its stationary law."""
    out = np.empty(n)
    out[0] = rng.normal(0.0, sigma)
    drive = rng.normal(0.0, sigma * math.sqrt(1.0 - a * a), n)
    for k in range(1, n):
        out[k] = a * out[k - 1] + drive[k]
    return out


def _logs(seed: int, sigma_counts: float = 0.0, tau: float = 0.0, before: bool = False, grid: int = 1, runs: int = 2):
    """``runs`` 8 s logs of a swing no model of the rig predicts (a smooth misfit of hundreds of counts, crossing a
    count at most samples), with first-order noise of ``sigma_counts`` counts and correlation time ``tau`` [s]
    (0: white), added after the rounding or, ``before``, ahead of a rounding to ``grid`` counts."""
    rng = np.random.default_rng(seed)
    t = np.arange(4000) * PERIOD
    a = math.exp(-PERIOD / tau) if tau > 0 else 0.0
    logs = []
    for run in range(runs):
        angles = np.column_stack([0.5 * np.sin(12.0 * t + run), 0.6 * np.sin(9.0 * t + 1.0 + run)])
        noise = np.column_stack([_ar1(rng, t.size, sigma_counts * COUNT, a) for _ in range(2)])
        step = grid * COUNT
        read = np.round((angles + noise) / step) * step if before else np.round(angles / step) * step + noise
        logs.append(RunLog(f"run{run}.csv", "", t, read[:, 0], read[:, 1], "torque", np.zeros(t.size), PERIOD))
    return logs


def _read(logs, held):
    rig = _rig()
    train, heldout = make_windows(logs, rig), make_windows(held, rig)
    bootstrap = Bootstrap(heldout.count, 1000, 0)
    grid, noise = read_sensors(Model.from_rig(rig), train, heldout, COUNTS, SETTINGS, bootstrap)
    return grid, noise


def _sigma_counts(finding) -> tuple[float, float, float]:
    low, high = np.percentile(finding.samples[:, 0], [2.5, 97.5]) / COUNT
    return finding.effect.values[0] / COUNT, low, high


@pytest.mark.parametrize("a", [0.0, 0.5, 0.9])
def test_the_third_differences_of_first_order_noise_have_the_stated_variance(a):
    """E t_L^2 = sigma^2 g(a^L): the sum over the stencil's taps (-1, 3, -3, 1) of the noise's covariances
    a^|i - j| (Monte Carlo over 400 000 samples)."""
    noise = _ar1(np.random.default_rng(1), 400_000, 1.0, a)
    for lag in (1, 2):
        t = noise[3 * lag :] - 3 * noise[2 * lag : -lag] + 3 * noise[lag : -2 * lag] - noise[: -3 * lag]
        assert np.mean(t**2) == pytest.approx(third_difference_gain(a**lag), rel=0.02)
    assert third_difference_gain(0.0) == 20.0  # white: 1 + 9 + 9 + 1


@given(a=st.floats(0.0, 0.99))
def test_the_lag_ratio_gives_back_the_coefficient(a):
    assert coefficient(lag_ratio(a)) == pytest.approx(a, abs=1e-6)


@pytest.mark.parametrize("before", [False, True])
@pytest.mark.parametrize("sigma", [1.0, 2.5])
def test_white_noise_is_read_unbiased_beside_a_large_smooth_misfit(sigma, before):
    """The model predicts none of a 0.5 rad swing; the third differences still read the noise, added before the
    rounding (the angles on the grid, the rounding white) or after it (off the grid, the rounding the swing's own),
    and its 95 % interval holds the truth."""
    grid, noise = _read(_logs(2, sigma, before=before), _logs(3, sigma, before=before))
    estimate, low, high = _sigma_counts(noise)
    assert noise.accepted and noise.effect.form == "white" and not grid.accepted
    assert low < sigma < high
    assert estimate == pytest.approx(sigma, rel=0.05)


def test_a_smooth_misfit_alone_reads_no_noise():
    grid, noise = _read(_logs(4), _logs(5))
    assert not noise.accepted and not grid.accepted
    assert noise.effect.values[0] / COUNT < NOISE_FLOOR_COUNTS


def test_noise_low_passed_over_a_few_samples_is_named_with_its_correlation_time():
    """First-order noise of 1.5 counts and 5 ms (2.5 sample periods): its lag structure shows the correlation;
    tau's interval holds the truth."""
    _, noise = _read(_logs(6, 1.5, tau=0.005, runs=3), _logs(7, 1.5, tau=0.005, runs=3))
    assert noise.accepted and noise.effect.form == "correlated"
    sigma, tau = noise.effect.values
    low, high = np.percentile(noise.samples[:, 1], [2.5, 97.5])
    assert low < 0.005 < high
    assert sigma / COUNT == pytest.approx(1.5, rel=0.2)


def test_a_correlation_as_long_as_the_window_is_not_named():
    """Noise low-passed over 2 s drifts like a model error within a window: it is never named correlated."""
    _, noise = _read(_logs(8, 3.0, tau=2.0), _logs(9, 3.0, tau=2.0))
    assert noise.effect.form == "white"


def test_noise_of_many_counts_on_an_encoder_is_called_a_misfit():
    sigma = 3.0 * NOISE_PLAUSIBLE_COUNTS
    _, noise = _read(_logs(10, sigma), _logs(11, sigma))
    assert not noise.accepted
    assert "model error" in noise.note


def test_the_score_charges_a_variance_claimed_too_large_as_much_as_one_too_small():
    """The held-out log score of white noise of 1.5 counts is highest near the truth: half or twice it score lower,
    as does the rig file's bare rounding."""
    rig = _rig()
    windows = make_windows(_logs(12, 1.5), rig)
    sig = signature(Model.from_rig(rig), windows, COUNTS)
    score = {s: sig.scores(Hypothesis(1.0, s)).sum() for s in (0.0, 0.75, 1.5, 3.0)}
    assert score[1.5] > score[0.75] > score[0.0]
    assert score[1.5] > score[3.0]


def test_a_coarser_encoder_is_read_from_the_grid_its_increments_lie_on():
    """Angles rounded to 4 counts of the rig file's encoder (its 2048 counts read as 512) with noise ahead of the
    rounding: the grid is read exactly and the held-out increments all lie on it."""
    logs = _logs(13, 0.3, before=True, grid=4)
    assert grid_of(logs, COUNTS) == 4
    assert grid_of(_logs(14, 0.3, before=True), COUNTS) == 1
    grid, _ = _read(logs, _logs(15, 0.3, before=True, grid=4))
    assert grid.accepted and grid.effect.values == (COUNTS / 4,)
    assert np.mean(grid.claimed) == pytest.approx((16 - 1) / 12.0, rel=0.1)  # the extra rounding variance
