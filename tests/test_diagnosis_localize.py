"""Localisation of the gap on synthetic residuals whose answer is known by construction."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.diagnosis.gap.localize import REGIMES, band_power, localize
from furuta_drake.diagnosis.logs.load import WindowResiduals

DT = 0.001


def make_windows(
    residual_fn,
    *,
    n_windows=20,
    length=0.25,
    theta_fn=lambda t: 0.0 * t,
    phi_dot_fn=lambda t: np.sin(2 * math.pi * 0.5 * t),
    saturated_fn=None,
    log="run.csv",
    noise=0.0,
    seed=0,
):
    """Contiguous windows over one log; the residual (counts) and the predicted state are functions of time."""
    rng = np.random.default_rng(seed)
    samples = int(round(length / DT))
    windows = []
    for k in range(n_windows):
        t = (k * samples + np.arange(samples)) * DT
        residual = np.asarray(residual_fn(t), float) + noise * rng.uniform(-0.5, 0.5, (samples, 2))
        state = np.column_stack([theta_fn(t), np.zeros_like(t), np.zeros_like(t), phi_dot_fn(t)])
        saturated = np.zeros(samples, bool) if saturated_fn is None else saturated_fn(t)
        windows.append(
            WindowResiduals(
                log_name=log, time=t, residual=residual, state=state, torque=np.zeros(samples), saturated=saturated
            )
        )
    return windows


def regime(result, name):
    return next(r for r in result["regimes"] if r["regime"] == name)


def band(result, low):
    return next(b for b in result["frequency_bands"] if b["low_hz"] == low)


def test_residual_at_arm_velocity_reversals_is_attributed_to_them():
    # phi_dot = sin(pi t) reverses at t = 1, 2, 3, 4 s (it starts from 0 at t = 0), at boundaries between
    # windows; the phi residual lives within 30 ms of each reversal only.
    def residual(t):
        near = (np.abs(((t + 0.5) % 1.0) - 0.5) < 0.03) & (t > 0.5) & (t < 4.5)
        return np.column_stack([np.zeros_like(t), np.where(near, 6.0, 0.0)])

    result = localize(make_windows(residual, noise=1.0))
    reversal = regime(result, "arm velocity reversal")
    assert reversal["share_of_gap"] > 0.97
    assert reversal["share_of_samples"] == pytest.approx(0.08, abs=0.002)  # 4 reversals x 100 ms in 5 s
    assert regime(result, "near-zero arm speed")["share_of_gap"] > 0.97
    assert regime(result, "high arm speed")["share_of_gap"] < 0.03
    assert result["signals"]["phi"] > 0.98
    assert result["basis"].startswith("excess")
    assert all(w["why"].startswith("phi error, at ") for w in result["windows"])


def test_a_20_hz_residual_falls_in_the_10_30_hz_band():
    result = localize(make_windows(lambda t: np.column_stack([3 * np.sin(2 * math.pi * 20 * t), 0 * t])))
    assert band(result, 10.0)["share_of_gap"] > 0.95
    assert result["frequency_bands"][-1]["high_hz"] == pytest.approx(500.0)
    assert sum(b["share_of_gap"] for b in result["frequency_bands"]) == pytest.approx(1.0)
    assert result["signals"]["theta"] == pytest.approx(1.0)


def test_sensor_noise_is_not_counted_as_gap():
    # A 2 Hz error of 0.3 count amplitude under encoder noise of the expected variance (1/12 count^2, which is
    # twice the sinusoid's power): after removing the expected noise the 1-3 Hz band holds the gap.
    windows = make_windows(
        lambda t: np.column_stack([0.3 * np.sin(2 * math.pi * 2 * t + 0.3)] * 2),
        n_windows=40,
        length=2.0,
        noise=1.0,
        seed=3,
    )
    result = localize(windows)
    assert band(result, 1.0)["share_of_gap"] > 0.8
    raw = localize(windows, noise_variance=0.0)
    assert band(raw, 1.0)["share_of_gap"] < 0.5  # the noise spreads over every band when not removed


def test_worst_windows_are_merged_and_explained():
    # Windows 6 and 7 (1.5-2.0 s) of the hanging run carry a large theta error.
    def residual(t):
        bad = (t >= 1.5) & (t < 2.0)
        return np.column_stack([np.where(bad, 5.0 + 2.0 * (t - 1.5), 0.0), 0 * t])

    windows = make_windows(residual, theta_fn=lambda t: math.pi + 0.1 * np.sin(t), noise=1.0)
    result = localize(windows)
    assert len(result["windows"]) == 1
    worst = result["windows"][0]
    assert worst["log"] == "run.csv"
    assert (worst["start"], worst["end"]) == pytest.approx((1.5, 1.999))
    assert worst["share_of_gap"] > 0.95
    assert worst["why"].startswith("theta error") and "hanging" in worst["why"]
    assert regime(result, "hanging")["share_of_samples"] == 1.0


def test_saturation_and_pose_regimes():
    def residual(t):
        return np.column_stack([np.zeros_like(t), np.where((t % 1.0) < 0.2, 4.0, 0.0)])

    windows = make_windows(
        residual, theta_fn=lambda t: 0.05 * np.sin(3 * t), saturated_fn=lambda t: (t % 1.0) < 0.2, noise=1.0
    )
    result = localize(windows)
    saturation = regime(result, "torque saturation")
    assert saturation["share_of_gap"] > 0.97 and saturation["share_of_samples"] == pytest.approx(0.2, abs=1e-3)
    assert regime(result, "upright")["share_of_gap"] == pytest.approx(1.0)
    assert regime(result, "swinging")["share_of_gap"] == 0.0
    assert [r["regime"] for r in result["regimes"]] == list(REGIMES)


def test_after_block_has_the_same_shape_and_sees_the_remaining_gap():
    before = make_windows(lambda t: np.column_stack([0 * t, 5 * np.sin(2 * math.pi * 20 * t)]), noise=1.0)
    after = make_windows(lambda t: np.column_stack([2 * np.sin(2 * math.pi * 0.5 * t), 0 * t]), noise=1.0)
    result = localize(before, after)
    assert set(result["after"]) == set(result) - {"after"}
    assert result["signals"]["phi"] > 0.95 and result["after"]["signals"]["theta"] > 0.95
    assert band(result, 10.0)["share_of_gap"] > 0.9
    # 0.25 s windows resolve 4 Hz: the 0.5 Hz error shares the DC bin between the 0-1 and 1-3 Hz bands.
    assert band(result["after"], 0.0)["share_of_gap"] + band(result["after"], 1.0)["share_of_gap"] > 0.95


def test_no_excess_over_the_sensor_floor_falls_back_to_raw_shares():
    result = localize(make_windows(lambda t: np.zeros((len(t), 2)), noise=0.5))  # variance 1/48 < 1/12
    assert result["basis"].startswith("squared residual")
    assert sum(result["signals"].values()) == pytest.approx(1.0)
    assert result["windows"]


@settings(max_examples=25, deadline=None)
@given(
    n=st.integers(8, 400), period=st.sampled_from([0.001, 0.004]), noise=st.floats(0.0, 0.5), seed=st.integers(0, 1000)
)
def test_band_powers_add_up_to_the_excess_squared_residual(n, period, noise, seed):
    # Parseval: the bands split the window's sum of r^2 minus n times the sensor variance, per signal.
    rng = np.random.default_rng(seed)
    t = np.arange(n) * period
    residual = rng.normal(0, 2, (n, 2))
    window = WindowResiduals("w.csv", t, residual, np.zeros((n, 4)), np.zeros(n), np.zeros(n, bool))
    edges, power = band_power(window, noise)
    assert edges[-1] == pytest.approx(0.5 / period) and np.all(np.diff(edges) > 0)
    np.testing.assert_allclose(power.sum(axis=0), (residual**2).sum(axis=0) - n * noise, rtol=1e-9, atol=1e-9)
