"""Forms real drivers have: a delay that jitters from sample to sample (the model applies its expected command).
Each true parameter is recovered from the default starts at two sizes. (Noise low-passed with a correlation time,
the sensor's form, is in test_sensor.py.)"""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_form_starts import _surrogate_measured, nominal_windows  # noqa: F401  (the fixture)

from furuta_drake.diagnosis.selection.fit import FitTask, fit_task
from furuta_drake.diagnosis.settings import FAST
from furuta_drake.effects.surrogate import Model, _delayed_command, expected_command, expected_command_points
from furuta_drake.effects.vocabulary import Effect, apply_effects
from furuta_drake.errors import ConfigError
from furuta_drake.rig import RIGS

PERIOD = 1e-3  # [s]
FINE_COUNTS = 2**24  # an encoder whose rounding is far below a jitter's effect


def _model(delay: float, spread: float) -> Model:
    return apply_effects(Model.from_rig(RIGS["lund"]()), {"input_delay": Effect("jitter", (delay, spread))})


@settings(max_examples=25, deadline=None)
@given(
    delay=st.floats(0.5e-3, 8e-3),
    spread=st.floats(0.25e-3, 2e-3),
    substeps=st.sampled_from([1, 2, 4]),
    seed=st.integers(0, 1000),
)
def test_a_jittering_delay_applies_the_command_averaged_over_its_uniform_delay(delay, spread, substeps, seed):
    """The expected command over [t, t + dt) is the mean over delays uniform on delay +- sqrt(3) spread of the
    held command delayed by each (a fine midpoint quadrature of the fixed delay's exact substep mean)."""
    command = np.random.default_rng(seed).normal(0.1, 1.0, 400)
    starts, dt = np.array([[200, 300]]), PERIOD / substeps
    t = (np.arange(30) * dt)[:, None]
    half = math.sqrt(3.0) * spread
    delays = delay - half + 2 * half * (np.arange(2000) + 0.5) / 2000
    quadrature = np.mean([_delayed_command(command, starts, t, dt, PERIOD, d) for d in delays], axis=0)
    exact = expected_command(command, starts, t, dt, PERIOD, _model(delay, spread))
    assert np.max(np.abs(exact - quadrature)) < 1e-3 * np.max(np.abs(command))


def test_the_replayed_expected_command_is_linear_between_its_points_and_matches_the_surrogate():
    """The Drake replay's piecewise-linear command, averaged over each sample, equals the surrogate's."""
    command = np.random.default_rng(3).normal(0.0, 1.0, 300)
    model = _model(3.3e-3, 0.7e-3)
    times, values = expected_command_points(command, PERIOD, model)
    samples = np.arange(10, 250)
    midpoints = (samples[:, None] + (np.arange(64) + 0.5) / 64) * PERIOD  # 64 parts of each sample
    replayed = np.interp(midpoints, times, values).mean(axis=1)
    surrogate = expected_command(command, np.array([[0]]), (samples * PERIOD)[:, None], PERIOD, PERIOD, model)
    assert np.max(np.abs(replayed - surrogate[:, 0])) < 1e-3


@pytest.mark.parametrize("counts", [FINE_COUNTS, 4096])
def test_a_command_smoothed_without_draws_is_not_read_as_a_jitter(nominal_windows, counts):  # noqa: F811
    """The expected command of a jittering delay (2 ms +- sqrt(3) 0.8 ms) applied as it is, with no draw from sample
    to sample: a moving average of the command, which a lag or a filter also gives. Its residuals hold no variance
    a jitter's draws would add, so the delay is not named a jitter, on a fine encoder or the rig's; the fixed delay
    sits within a quarter sample of the average's centre."""
    rig, logs, windows = nominal_windows
    synthetic = _surrogate_measured(_model(2e-3, 0.8e-3), windows, counts)
    fit = fit_task(FitTask("input_delay", {}, Model.from_rig(rig), synthetic, None, logs, counts, FAST))
    assert fit.effects["input_delay"].form == "fixed"
    assert abs(fit.effects["input_delay"].values[0] - 2e-3) < 0.25 * PERIOD  # near the moving average's centre


@pytest.mark.parametrize("counts", [FINE_COUNTS, 4096])
def test_a_fixed_delay_is_named_fixed(nominal_windows, counts):  # noqa: F811
    """A delay with no spread, read by a fine encoder or the rig's: the jittering form is named only when its
    spread's interval stays off its lower bound and the spread removes more than the floor resolves (at the rig's
    encoder a spread of two samples fits the rounding slightly better); the delay's interval holds the truth."""
    rig, logs, windows = nominal_windows
    truth = apply_effects(Model.from_rig(rig), {"input_delay": Effect("fixed", (3e-3,))})
    synthetic = _surrogate_measured(truth, windows, counts)
    fit = fit_task(FitTask("input_delay", {}, Model.from_rig(rig), synthetic, None, logs, counts, FAST))
    assert fit.effects["input_delay"].form == "fixed"
    low, high = np.percentile(fit.samples["input_delay"][:, 0], [2.5, 97.5])
    assert low <= 3e-3 <= high


@pytest.mark.parametrize(
    "spread, message",
    [(0.0, r"delay_spread must be positive"), (0.0018, r"delay_spread must be at most delay / sqrt\(3\)")],
)
def test_a_rig_file_jitter_needs_a_positive_spread_that_keeps_the_delay_above_zero(spread, message):
    """A 3 ms delay uniform on 3 ms +- sqrt(3) 1.8 ms would reach -0.12 ms: a command not yet sent."""
    from furuta_drake.effects.vocabulary import rig_effects

    class Rig:
        effects = {"input_delay": {"form": "jitter", "delay": 0.003, "delay_spread": spread}}

    with pytest.raises(ConfigError, match=r"effects\.input_delay\." + message):
        rig_effects(Rig())


def test_an_actuator_lag_is_not_read_as_a_jittering_delay(nominal_windows):  # noqa: F811
    """A 12 ms first-order lag smooths the command as a wide uniform delay's moving average does; the residuals'
    variance that such a jitter would claim is a misfit of the mean, its spread pressed against the top of the
    range, so the delay that stands in for the lag is a fixed one."""
    rig, logs, windows = nominal_windows
    synthetic = _surrogate_measured(Model.from_rig(rig).replace(lag=0.012), windows, 4096)
    fit = fit_task(FitTask("input_delay", {}, Model.from_rig(rig), synthetic, None, logs, 4096, FAST))
    assert fit.effects["input_delay"].form == "fixed"
