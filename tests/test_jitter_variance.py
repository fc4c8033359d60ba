"""The variance a jittering delay adds to the predicted angles (:mod:`furuta_drake.effects.jitter`): the command's
variance over the delay, and its response through the window's impulse responses."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from test_form_starts import nominal_windows  # noqa: F401  (the fixture)

from furuta_drake.diagnosis.gap.metric import IMPULSES, evaluate_gap, make_windows
from furuta_drake.diagnosis.selection.jitter_fit import jitter_claim
from furuta_drake.effects.jitter import command_variance, impulse_energy, response_variance
from furuta_drake.effects.surrogate import Model, _delayed_command, integrate_windows, predict_windows, window_torques
from furuta_drake.effects.vocabulary import Effect, apply_effects
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.rig import RIGS, encoder_resolution

PERIOD = 1e-3  # [s]
FINE_COUNTS = 2**24  # an encoder whose rounding is far below a jitter's effect


def _jitter(model: Model, delay: float, spread: float) -> Model:
    return apply_effects(model, {"input_delay": Effect("jitter", (delay, spread))})


@pytest.mark.parametrize("delay, spread", [(3e-3, 0.87e-3), (0.4e-3, 0.5e-3), (6.2e-3, 2.3e-3)])
def test_the_command_variance_is_the_variance_over_the_uniform_delay_of_the_sample_mean(delay, spread):
    """v_k against a fine midpoint quadrature over the delay of the held command's exact mean over sample k."""
    command = np.random.default_rng(1).normal(0.2, 1.0, 120)
    model = _jitter(Model.from_rig(RIGS["lund"]()), delay, spread)
    half = math.sqrt(3.0) * spread
    delays = delay - half + 2 * half * (np.arange(4000) + 0.5) / 4000
    starts = np.arange(30, 100)[None, :]
    means = np.array([_delayed_command(command, starts, 0.0, PERIOD, PERIOD, d)[0] for d in delays])
    assert command_variance(command, PERIOD, model)[30:100] == pytest.approx(means.var(axis=0), rel=1e-3, abs=1e-9)


def _response_variance(model: Model, x0, command, starts, horizon: int, substeps: int, stride: int = 1):
    """:func:`response_variance` [rad^2] of the windows ``predict_windows`` predicts from ``x0`` (4, W), the
    impulses simulated at every ``stride``-th sample."""

    def predict(part, copies, change):
        torque = window_torques(model, command, np.tile(starts[part], copies), horizon, PERIOD, substeps, change)
        return integrate_windows([model], np.tile(x0[:, part], copies), torque, PERIOD, substeps)

    v = command_variance(command, PERIOD, model)[starts[None, :] + np.arange(horizon - 1)[:, None]]
    size = float(np.sqrt(np.mean(v))) or 1e-3
    return response_variance(impulse_energy(predict, horizon - 1, starts.size, size, None, stride), v)


def _double_integrator() -> Model:
    """The arm alone as a double integrator: no coupling to the pendulum (c = 0, the pendulum resting upright), no
    friction, no back-EMF: a phi'' = tau."""
    free = JointFrictionParameters()
    return Model.from_rig(RIGS["lund"]()).replace(
        coupling=0.0, arm_friction=free, pendulum_friction=free, back_emf_damping=0.0
    )


@pytest.mark.parametrize("substeps", [1, 2])
def test_a_double_integrator_gains_the_sum_of_its_squared_impulse_responses_times_the_command_variance(substeps):
    """A unit torque over sample k moves phi at sample n > k by (n - k - 1/2) T^2 / a (RK4 is exact on a
    polynomial): the predicted variance is sum_k that squared times v_k; theta does not move."""
    model = _jitter(_double_integrator(), 3e-3, 0.87e-3)
    command = np.random.default_rng(2).normal(0.0, 0.05, 600)
    starts, horizon = np.array([300, 420]), 60
    x0 = np.zeros((4, 2))
    variance = _response_variance(model, x0, command, starts, horizon, substeps)
    v = command_variance(command, PERIOD, model)
    a = model.arm_inertia_total
    n, k = np.arange(horizon)[:, None], np.arange(horizon - 1)[None, :]
    g = np.where(k < n, (n - k - 0.5) * PERIOD**2 / a, 0.0)
    expected = np.stack([g**2 @ v[s + np.arange(horizon - 1)] for s in starts], axis=1)
    assert variance[:, 1] == pytest.approx(expected, rel=1e-6, abs=1e-30)
    assert np.all(variance[:, 0] == 0.0)


def test_a_delay_without_spread_adds_no_variance():
    model = apply_effects(Model.from_rig(RIGS["lund"]()), {"input_delay": Effect("fixed", (3e-3,))})
    command = np.random.default_rng(3).normal(0.0, 0.05, 400)
    assert np.all(command_variance(command, PERIOD, model) == 0.0)
    assert np.all(_response_variance(model, np.zeros((4, 1)), command, np.array([300]), 40, 1) == 0.0)


def test_the_variance_matches_the_spread_of_angles_under_delays_drawn_every_sample():
    """The nonlinear model swinging while hanging, its friction on: the angles' variance over 400 runs whose
    every sample draws its own delay (the held command read at the drawn delay, applied without a delay) against
    the first-order prediction (a sampled variance of 400 runs is within about 15 % at two sigma)."""
    model = _jitter(Model.from_rig(RIGS["lund"]()), 3e-3, 0.87e-3)
    rng = np.random.default_rng(4)
    time = np.arange(700) * PERIOD
    command = 0.04 * np.sin(2 * np.pi * 3.0 * time) + rng.normal(0.0, 0.01, time.size)
    start, horizon = np.array([400]), 150
    x0 = np.array([[math.pi - 0.3], [0.1], [1.0], [0.5]])
    predicted = _response_variance(model, x0, command, start, horizon, 1)
    half, samples = math.sqrt(3.0) * 0.87e-3, np.arange(time.size)[None, :]
    delays = 3e-3 + half * rng.uniform(-1.0, 1.0, (400, time.size))
    applied = np.array([_delayed_command(command, samples, 0.0, PERIOD, PERIOD, d[None, :])[0] for d in delays])
    fixed = model.replace(delay=0.0, delay_spread=0.0)
    runs = np.stack([predict_windows(fixed, x0, u, start, horizon, PERIOD, 1)[:, :, 0] for u in applied])
    sampled = runs.var(axis=0)
    late = slice(horizon // 2, horizon)  # where the variance has grown past the first samples
    assert sampled[late] == pytest.approx(predicted[late, :, 0], rel=0.2)


def test_the_true_jittering_delay_claims_what_its_draws_add_and_its_gap_keeps_it(nominal_windows):  # noqa: F811
    """The hanging run's windows, their angles the model's response to a command read at a delay drawn anew every
    sample (a fine encoder): the variance the true jittering delay claims for each window's residuals, once each
    window's start is refitted, is their mean square to first order (24 draws: their sampled mean square is within
    about a tenth of its expectation; the prediction runs somewhat above it on these windows, hence the tolerance);
    the gap, which measures predictions, keeps that mean square: a claimed variance is never taken off it."""
    rig, logs, windows = nominal_windows
    hanging = make_windows([log for log in logs if log.name.startswith("hanging")], rig)
    model = _jitter(Model.from_rig(rig), 3e-3, 0.87e-3).replace(counts_per_rev=FINE_COUNTS)
    fixed, count = model.replace(delay=0.0, delay_spread=0.0), encoder_resolution(FINE_COUNTS)
    rng = np.random.default_rng(5)
    claimed, raw, excess = [], [], []
    for _ in range(24):
        (batch,) = hanging.batches()
        drawn = 3e-3 + math.sqrt(3.0) * 0.87e-3 * rng.uniform(-1.0, 1.0, batch.command.size)
        samples = np.arange(batch.command.size)[None, :]
        applied = _delayed_command(batch.command, samples, 0.0, PERIOD, PERIOD, drawn[None, :])[0]
        predicted = predict_windows(fixed, batch.initial_states, applied, batch.starts, batch.horizon, PERIOD, 1)
        measured = dataclasses.replace(hanging, measured=[np.round(predicted / count) * count])
        result = evaluate_gap(model, measured, FINE_COUNTS)
        excess.append(result.per_window.mean() + hanging.floor)
        raw.append(np.mean([(r[1:] ** 2).mean() for r in result.residuals]))
        claimed.append(jitter_claim(model, measured, FINE_COUNTS)[1].mean())
    assert np.mean(claimed) == pytest.approx(np.mean(raw), rel=0.3)
    assert np.mean(excess) == pytest.approx(np.mean(raw), rel=1e-9)


def test_a_model_without_a_spread_keeps_the_sensor_only_gap(nominal_windows):  # noqa: F811
    """No jitter, no variance beside the sensor's: the gap is exactly the mean squared residual less the encoder's
    1/12 count^2."""
    rig, _, windows = nominal_windows
    model = apply_effects(Model.from_rig(rig), {"input_delay": Effect("fixed", (3e-3,))})
    result = evaluate_gap(model, windows, rig.counts_per_rev)
    per_window = np.concatenate([(r[1:] ** 2).mean(axis=(0, 1)) for r in result.residuals]) - 1.0 / 12.0
    assert np.array_equal(result.per_window, per_window)
    assert result.gap == math.sqrt(max(per_window.mean(), 0.0))


def test_impulses_shifted_between_simulated_ones_give_the_variance_of_every_impulse_simulated():
    """The nonlinear model swinging while hanging, its friction on: over a few samples the operating point moves
    little, so an impulse's response shifted in time stands for its neighbours' (the gap simulates one in
    ``IMPULSES`` per window)."""
    model = _jitter(Model.from_rig(RIGS["lund"]()), 3e-3, 0.87e-3)
    time = np.arange(700) * PERIOD
    command = 0.04 * np.sin(2 * np.pi * 3.0 * time) + np.random.default_rng(4).normal(0.0, 0.01, time.size)
    x0 = np.array([[math.pi - 0.3], [0.1], [1.0], [0.5]])
    every = _response_variance(model, x0, command, np.array([400]), 150, 1)
    shifted = _response_variance(model, x0, command, np.array([400]), 150, 1, stride=-(-149 // IMPULSES))
    late = slice(75, 150)
    assert shifted[late] == pytest.approx(every[late], rel=0.05)
