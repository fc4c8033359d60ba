"""Every form's fit reaches its own best from the default starts: the forms whose cost jumps where their
parameter crosses a logged command (a dead zone's width, a saturation's limit) recover the true parameter on
windows whose measurements are the surrogate's own prediction with the effect, read by the rig's encoder (no
other error), at two sizes; a threshold's 95 % interval (the bootstrap of its line search) holds it."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from benchmarks.suite import run_configs
from furuta_drake.diagnosis.fit import FitTask, fit_task, scales_of
from furuta_drake.diagnosis.gap import make_windows, substeps_for
from furuta_drake.diagnosis.logs import RunLog
from furuta_drake.diagnosis.settings import FAST
from furuta_drake.effects.surrogate import Model, predict_windows
from furuta_drake.effects.vocabulary import Effect, apply_effects
from furuta_drake.rig import RIGS, encoder_resolution
from furuta_drake.simulate import simulate


@pytest.fixture(scope="module")
def nominal_windows():
    """Windows of a 3 s Lund hanging run under the suite's open-loop multisine (the nominal rig in Drake)."""
    rig = RIGS["lund"]()
    result = simulate(run_configs(rig, 7, 3.0)["hanging"])
    log = RunLog(
        "hanging.csv", "", result.time, result.measured[:, 0], result.measured[:, 1], "torque", result.torque, 1e-3
    )
    return rig, log, make_windows([log], rig)


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


@pytest.mark.parametrize(
    "effect, form, size",
    [
        ("actuator_deadzone", "subtract", 0.03),
        ("actuator_deadzone", "subtract", 0.06),
        ("actuator_deadzone", "threshold", 0.03),
        ("actuator_deadzone", "threshold", 0.06),
        ("actuator_saturation", "hard", 0.35),
        ("actuator_saturation", "hard", 0.6),
        ("actuator_saturation", "smooth", 0.35),
        ("actuator_saturation", "smooth", 0.6),
    ],
)
def test_a_command_map_form_finds_its_true_parameter_from_the_default_starts(nominal_windows, effect, form, size):
    """``size``: a dead zone's true width as a fraction of m g l (the suite's sizes), a saturation's limit as one
    of the largest logged command."""
    rig, log, windows = nominal_windows
    nominal = Model.from_rig(rig)
    true_value = size * (nominal.gravity_torque if effect == "actuator_deadzone" else scales_of([log], nominal).command)
    truth = apply_effects(nominal, {effect: Effect(form, (true_value,))})
    synthetic = _surrogate_measured(truth, windows, rig.counts_per_rev)
    fit = fit_task(FitTask(effect, {}, nominal, synthetic, None, (log,), rig.counts_per_rev, FAST))
    fitted = fit.effects[effect]
    assert fitted.form == form
    assert fitted.values[0] == pytest.approx(true_value, rel=0.03)
    assert fit.train_gap < 0.05  # counts: the true model reproduces these windows to the encoder's rounding
    if form == "threshold":  # its interval is the block bootstrap of the line search
        low, high = np.percentile(fit.samples[effect][:, 0], [2.5, 97.5])
        assert low <= true_value <= high
