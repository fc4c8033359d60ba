"""Every form's fit reaches its own best from the default starts: for every fitted (effect, form) of the
vocabulary, on windows whose measurements are the surrogate's own prediction with the effect at two sizes, read
by the rig's encoder (no other error), the fit's cost is no higher than the true parameters' own, and every true
parameter is recovered (to a few per cent, or inside its 95 % interval where the encoder's rounding pins it
loosely). The sensor effects, estimated from the logs directly, recover a coarser encoder and white noise at two
sizes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from benchmarks.diagnosis.suite import run_configs
from furuta_drake.diagnosis.gap.metric import evaluate_gap, make_windows, substeps_for
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.diagnosis.selection.fit import FitTask, fit_task, interval, scales_of
from furuta_drake.diagnosis.selection.rule import Bootstrap
from furuta_drake.diagnosis.selection.sensor import read_sensors
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects.surrogate import Model, predict_windows
from furuta_drake.effects.vocabulary import CANDIDATES, Effect, Scales, apply_effects
from furuta_drake.rig import RIGS, encoder_resolution
from furuta_drake.simulate import simulate

# The diagnosis' default fit (its windows, starts and steps), with fewer bootstrap resamples.
SETTINGS = DiagnosisSettings(interval_resamples=100, detection_limits=False)
RELATIVE = 0.05  # a recovered parameter is within this fraction of the truth, or inside its 95 % interval
# The friction law's shape (where its torque turns, and the Stribeck curve's breakaway level, which trades off
# against its velocity: a presliding fit well above the true level can cost less than the truth) moves the prediction
# by less than the encoder's rounding over most of these runs: within this fraction of the truth, or inside its
# 95 % interval.
SHAPE = {"presliding": 0.3, "regularization_velocity": 0.3, "stribeck_velocity": 0.3, "static": 0.3}
COST_SLACK = 0.01  # [counts^2]: the fit's mean squared residual exceeds the truth's by at most this


def _truths(s: Scales) -> dict[tuple[str, str], list[list[float]]]:
    """Two true parameter vectors per (effect, form), in the form's order, at the suite's sizes (fractions of
    m g l, of the lumped inertias, of the sample period, of the largest command)."""
    T, a, b, P, u = s.torque, s.arm_inertia, s.pendulum_inertia, s.period, s.command
    return {
        ("arm_coulomb_friction", "presliding"): [[0.05 * T, 2.5e-3], [0.1 * T, 1e-3]],
        ("arm_coulomb_friction", "smooth"): [[0.05 * T, 0.01], [0.1 * T, 0.03]],
        ("arm_viscous_friction", ""): [[0.8 * a], [1.6 * a]],
        ("arm_stribeck", "presliding"): [[0.04 * T, 0.08 * T, 0.1, 2.5e-3], [0.04 * T, 0.12 * T, 0.6, 2.5e-3]],
        ("arm_stribeck", "smooth"): [[0.04 * T, 0.08 * T, 0.1, 0.01], [0.04 * T, 0.12 * T, 0.6, 0.01]],
        ("friction_asymmetry", "presliding"): [[0.03 * T, 0.0525 * T, 2.5e-3], [0.03 * T, 0.075 * T, 2.5e-3]],
        ("friction_asymmetry", "smooth"): [[0.03 * T, 0.0525 * T, 0.01], [0.03 * T, 0.075 * T, 0.03]],
        ("pendulum_friction", ""): [[0.004 * T, 0.3 * b], [0.008 * T, 0.6 * b]],
        ("input_delay", "fixed"): [[3.0 * P], [8.3 * P]],
        ("torque_gain_error", ""): [[0.8], [1.35]],
        ("actuator_deadzone", "subtract"): [[0.03 * T], [0.06 * T]],
        ("actuator_deadzone", "threshold"): [[0.03 * T], [0.06 * T]],
        ("actuator_lag", ""): [[0.006], [0.05]],
        ("actuator_saturation", "hard"): [[0.35 * u], [0.6 * u]],
        ("actuator_saturation", "smooth"): [[0.35 * u], [0.6 * u]],
        ("arm_spring", "linear"): [[0.25 * T, 0.05], [0.5 * T, -0.1]],
        ("arm_spring", "cubic"): [[0.25 * T, 1.0 * T, 0.05], [0.5 * T, 2.0 * T, -0.1]],
        ("inertia_mismatch", ""): [[0.85, 1.2, 1.1, 1.2], [0.7, 1.4, 1.2, 1.4]],
    }


# a jittering delay's spread moves these windows by a fraction of a count: its forms are recovered with a fine
# encoder in test_driver_sensor_forms.py
FINE_ENCODER_FORMS = {("input_delay", "jitter")}
# The drive's effects need a rig with a drive (the Lund rig has none): tests/test_drive_diagnosis.py fits them.
FITTED = [
    (name, form.name)
    for name, c in CANDIDATES.items()
    if c.fit and not c.drive
    for form in c.forms
    if (name, form.name) not in FINE_ENCODER_FORMS
]
FRICTION_LAWS = {"arm_coulomb_friction", "arm_stribeck", "friction_asymmetry"}  # 5-20 s a fit: end to end
CASES = [
    pytest.param(name, form, size, marks=[pytest.mark.slow] if name in FRICTION_LAWS else [])
    for name, form in FITTED
    for size in (0, 1)
]


@pytest.fixture(scope="module")
def nominal_windows():
    """Windows of the suite's two 3 s Lund runs (balancing under LQR, hanging under an open-loop multisine) on
    the nominal rig in Drake."""
    rig = RIGS["lund"]()
    logs = []
    for name, config in run_configs(rig, 7, 3.0).items():
        result = simulate(config)
        logs.append(RunLog(f"{name}.csv", "", result.time, *result.measured[:, :2].T, "torque", result.torque, 1e-3))
    return rig, tuple(logs), make_windows(logs, rig)


def _surrogate_measured(model: Model, windows, counts: int):
    """``windows`` whose measured angles are ``model``'s prediction from their initial states, read by an encoder
    of ``counts`` per revolution (rounded to whole counts)."""
    count = encoder_resolution(counts)
    measured = [None] * len(windows.logs)
    for batch in windows.batches():
        predicted = predict_windows(
            model,
            batch.initial_states,
            batch.command,
            batch.starts,
            batch.horizon,
            batch.period,
            substeps_for(batch.period),
        )
        for j, i in enumerate(batch.members):
            measured[i] = np.round(predicted[:, :, batch.bounds[j] : batch.bounds[j + 1]] / count) * count
    return dataclasses.replace(windows, measured=measured)


def _mean_square(model: Model, windows, counts: int) -> float:
    """The mean squared k-step residual [counts^2] of ``model`` (its excess over the sensor's variance)."""
    return float(np.mean(evaluate_gap(model, windows, counts).per_window))


def test_every_fitted_form_has_truths():
    assert set(_truths(Scales(1.0, 1.0, 1.0, 1.0, 1e-3))) == set(FITTED)


@pytest.mark.parametrize("effect, form, size", CASES)
def test_every_form_reaches_its_own_best_from_the_default_starts(nominal_windows, effect, form, size):
    rig, logs, windows = nominal_windows
    nominal = Model.from_rig(rig)
    true_values = _truths(scales_of(logs, nominal))[(effect, form)][size]
    truth = apply_effects(nominal, {effect: Effect(form, tuple(true_values))})
    synthetic = _surrogate_measured(truth, windows, rig.counts_per_rev)
    fit = fit_task(FitTask(effect, {}, nominal, synthetic, None, logs, rig.counts_per_rev, SETTINGS))
    fitted = fit.effects[effect]
    found = apply_effects(nominal, {effect: fitted})
    counts = rig.counts_per_rev
    assert _mean_square(found, synthetic, counts) <= _mean_square(truth, synthetic, counts) + COST_SLACK
    names = CANDIDATES[effect].form(fitted.form).params  # a nested form (a linear spring) may fit as its parent
    for param, true in zip(CANDIDATES[effect].form(form).params, true_values):
        assert param in names, f"{fitted.form} form fitted"
        i = names.index(param)
        low, high = interval(fit.samples[effect][:, i])
        assert abs(fitted.values[i] - true) <= SHAPE.get(param, RELATIVE) * abs(true) or low <= true <= high, param


def _read(logs, counts: int, coarse: int = 1, noise_counts: float = 0.0, seed: int = 0):
    """``logs`` with their angles read again: white noise of ``noise_counts`` counts of an encoder of ``counts``
    per revolution added, then rounded to ``coarse`` of its counts."""
    count, rng = encoder_resolution(counts), np.random.default_rng(seed)

    def read(angle):
        noisy = angle + noise_counts * count * rng.standard_normal(angle.size)
        return np.round(noisy / (coarse * count)) * coarse * count

    return tuple(dataclasses.replace(log, theta=read(log.theta), phi=read(log.phi)) for log in logs)


def _sensor_fit(name: str, logs, rig, windows) -> float:
    """The sensor effect ``name`` read beside the nominal model (judged on the same windows), its main value."""
    bootstrap = Bootstrap(windows.count, 200, 0)
    findings = read_sensors(Model.from_rig(rig), windows, windows, rig.counts_per_rev, SETTINGS, bootstrap)
    return next(finding for finding in findings if finding.name == name).effect.values[0]


@pytest.mark.parametrize("coarse", [4, 16])
def test_a_coarser_encoder_is_read_from_the_angle_increments(nominal_windows, coarse):
    rig, logs, windows = nominal_windows
    coarse_logs = _read(logs, rig.counts_per_rev, coarse)
    read = _sensor_fit("encoder_quantization", coarse_logs, rig, make_windows(coarse_logs, rig))
    assert read == rig.counts_per_rev / coarse


@pytest.mark.parametrize("noise_counts", [1.5, 4.0])
def test_white_noise_is_read_from_the_third_differences(nominal_windows, noise_counts):
    rig, logs, windows = nominal_windows
    noisy = _read(logs, rig.counts_per_rev, noise_counts=noise_counts, seed=3)
    sigma = _sensor_fit("measurement_noise", noisy, rig, make_windows(noisy, rig))  # read from their residuals
    assert sigma == pytest.approx(noise_counts * encoder_resolution(rig.counts_per_rev), rel=0.1)
