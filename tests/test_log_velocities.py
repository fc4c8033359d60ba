"""A log's velocity columns are left unused because the window start states do not need them: each window's state
is refined on its own angles, so a logged velocity (even the true one) would only change the first guess, and a
controller's filtered difference, lagging the motion, is a worse first guess than the smoother's."""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.diagnosis.log_velocities import recorded, velocity_error, with_starts
from benchmarks.diagnosis.low_rate import RATES
from furuta_drake.diagnosis.gap.metric import evaluate_gap, make_windows
from furuta_drake.effects.surrogate import Model


@pytest.fixture(scope="module")
def qube_125hz():
    """A noiseless 8 s QUBE run at 125 Hz under the bang-bang command, nominal = truth."""
    return recorded("qube_servo2", (), RATES["125Hz"], (1,))


def test_a_logged_velocity_does_not_change_the_refined_start_states(qube_125hz):
    rig, logs, velocities = qube_125hz
    windows = make_windows(logs, rig)
    nominal = Model.from_rig(rig)
    smoothed = evaluate_gap(nominal, windows, rig.counts_per_rev)
    for source in ("true", "filtered 50", "filtered 300", "20 ms late"):
        started = evaluate_gap(nominal, with_starts(windows, velocities, source), rig.counts_per_rev)
        assert started.gap == pytest.approx(smoothed.gap, abs=1e-3)  # counts
        moved = np.concatenate(
            [(a[2:4] - b[2:4]).ravel() for a, b in zip(started.initial_states, smoothed.initial_states)]
        )
        assert np.sqrt(np.mean(moved**2)) < 0.02  # rad/s, against start errors of 0.2-4 rad/s


def test_a_controllers_filtered_difference_is_a_worse_start_than_the_smoother(qube_125hz):
    rig, logs, velocities = qube_125hz
    windows = make_windows(logs, rig)
    smoothed = velocity_error(windows.initial_states, velocities, windows)
    for source in ("filtered 50", "filtered 300"):  # lags of 20 ms and 3 ms behind a swinging pendulum
        lagging = with_starts(windows, velocities, source)
        assert velocity_error(lagging.initial_states, velocities, windows) > 2.0 * smoothed
