"""The measurement-noise estimate at a low sample rate under a bang-bang command: the motion's own acceleration
(a dt^2 per sample, several counts at 125 Hz) is not taken for noise, and real noise is still found."""

from __future__ import annotations

import math

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.diagnosis.fit import NOISE_FLOOR_COUNTS, noise_estimate
from furuta_drake.diagnosis.logs import RunLog

COUNTS = 2048
COUNT = 2 * math.pi / COUNTS
PERIOD = 0.008  # 125 Hz


def bang_bang_log(seed: int, accel: float, noise_counts: float, seconds: float = 16.0) -> RunLog:
    """Both angles driven by a +-accel [rad/s^2] bang-bang acceleration switching after 25-75 ms (exact
    piecewise-quadratic motion, the command held between samples), plus white noise, rounded to the encoder."""
    rng = np.random.default_rng(seed)
    n = int(seconds / PERIOD)
    switches = np.cumsum(rng.uniform(0.025, 0.075, size=int(seconds / 0.025) + 2))
    times = np.arange(n) * PERIOD
    command = (-1.0) ** np.searchsorted(switches, times, side="right")
    angles = []
    for gain in (accel, -0.4 * accel):
        velocity = np.cumsum(np.concatenate([[0.0], gain * command[:-1] * PERIOD]))
        position = np.cumsum(np.concatenate([[0.0], velocity[:-1] * PERIOD + 0.5 * gain * command[:-1] * PERIOD**2]))
        noisy = position + rng.normal(0.0, noise_counts * COUNT, n)
        angles.append(np.round(noisy / COUNT) * COUNT)
    return RunLog("bb.csv", "bb.csv", times, angles[0], angles[1], "torque", 0.03 * command, PERIOD)


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 10_000), accel=st.floats(100.0, 600.0))
def test_bang_bang_motion_alone_is_not_noise(seed, accel):
    # a dt^2 is 2-10 counts per sample here: taken as noise, it would be sigma ~ 1-4 counts.
    assert accel * PERIOD**2 / COUNT > 2.0
    assert noise_estimate([bang_bang_log(seed, accel, 0.0)], COUNTS)[0] == 0.0


@settings(max_examples=10, deadline=None)
@given(seed=st.integers(0, 10_000), sigma=st.floats(3.0, 6.0))
def test_noise_under_bang_bang_motion_is_still_found(seed, sigma):
    estimate = noise_estimate([bang_bang_log(seed, 300.0, sigma)], COUNTS)[0] / COUNT
    assert estimate > NOISE_FLOOR_COUNTS
    assert abs(estimate - sigma) < 0.25 * sigma
