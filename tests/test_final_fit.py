"""The accepted model is fitted once more on every train window (furuta_drake/diagnosis/selection/final_fit.py): a hard
actuator saturation acts only in the windows whose command exceeds its limit. When the seeded draw of fit windows
holds none of them, the selection's fit cannot see the limit; the refit on every window finds it, and the report's
final model, its interval and its held-out evidence are the refit's. With no more train windows than the draw
takes, nothing changes."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from test_form_starts import _surrogate_measured

from benchmarks.diagnosis.suite import run_configs
from furuta_drake.diagnosis.gap.metric import evaluate_gap, make_windows
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.diagnosis.selection.final_fit import refit_final
from furuta_drake.diagnosis.selection.fit import FitTask, fit_task, interval
from furuta_drake.diagnosis.selection.rule import Bootstrap
from furuta_drake.diagnosis.selection.stepwise import Selection
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import Effect, apply_effects
from furuta_drake.rig import RIGS
from furuta_drake.simulate import simulate

SETTINGS = DiagnosisSettings(fit_windows=6, interval_resamples=100, bootstrap=200, detection_limits=False)
BURST_FROM = 2.21  # [s]: from here on the hanging run's command is amplified ...
BURST_GAIN = 4.0  # ... by this factor
LIMIT = 2.0  # the true saturation limit, in units of the largest command before the burst


def _log(seed: int, burst: bool) -> RunLog:
    """The suite's 3 s Lund hanging run (open-loop multisine, nominal rig in Drake), its command amplified by
    ``BURST_GAIN`` from ``BURST_FROM`` on when ``burst`` (the angles only set the windows' initial states: the
    measured angles are the true model's prediction)."""
    result = simulate(run_configs(RIGS["lund"](), seed, 3.0)["hanging"])
    command = result.torque.copy()
    if burst:
        command[result.time >= BURST_FROM] *= BURST_GAIN
    return RunLog(f"hanging_{seed}.csv", "", result.time, *result.measured[:, :2].T, "torque", command, 1e-3)


def _selection(fitted, nominal: Model, heldout, counts: int) -> tuple[Selection, Bootstrap]:
    """The selection that accepted ``fitted`` (its model judged on ``heldout``) and its held-out bootstrap."""
    fitted = dataclasses.replace(fitted, heldout=evaluate_gap(apply_effects(nominal, fitted.effects), heldout, counts))
    bootstrap = Bootstrap(heldout.count, SETTINGS.bootstrap, SETTINGS.seed)
    nominal_gap = evaluate_gap(nominal, heldout, counts)
    evidence = bootstrap.evidence(nominal_gap.per_window, fitted.heldout.per_window)
    selection = Selection(
        nominal_gap,
        [(1, fitted)],
        accepted=["actuator_saturation"],
        over_nominal={fitted.name: evidence},
        over_previous={fitted.name: evidence},
        over_others={"actuator_saturation": evidence},
        over_step=[evidence],
    )
    return selection, bootstrap


@pytest.fixture(scope="module")
def problem():
    """The nominal model, the true limit [N m], train windows whose fit-window draw misses the burst, the train
    log, and the saturation fitted on the drawn windows."""
    rig = RIGS["lund"]()
    counts = rig.counts_per_rev
    nominal = Model.from_rig(rig)
    train_log = _log(7, burst=True)
    limit = LIMIT * float(np.max(np.abs(train_log.input[train_log.time < BURST_FROM])))
    truth = apply_effects(nominal, {"actuator_saturation": Effect("hard", (limit,))})
    train = _surrogate_measured(truth, make_windows([train_log], rig), counts)
    fitted = fit_task(FitTask("actuator_saturation", {}, nominal, train, None, (train_log,), counts, SETTINGS))
    heldout = {
        burst: _surrogate_measured(truth, make_windows([_log(8, burst=burst)], rig), counts) for burst in (False, True)
    }
    return nominal, limit, train, heldout, (train_log,), fitted


def _serial(function, tasks):
    return [function(task) for task in tasks]


def test_the_draw_misses_the_burst_and_its_fit_misses_the_limit(problem):
    _, limit, train, _, _, fitted = problem
    drawn = train.subset(SETTINGS.fit_windows, SETTINGS.seed).starts[0]
    assert np.all(drawn + train.horizons[0] <= BURST_FROM / 1e-3)  # no drawn window reaches the burst
    assert train.count > SETTINGS.fit_windows
    assert fitted.effects["actuator_saturation"].values[0] > 1.25 * limit  # clips nothing it saw


def test_the_refit_on_every_train_window_finds_the_limit_and_is_reported(problem):
    """Held-out logs without a burst: no limit acts there, so every model's verdict is the same."""
    nominal, limit, train, heldout, logs, fitted = problem
    counts = RIGS["lund"]().counts_per_rev
    selection, bootstrap = _selection(fitted, nominal, heldout[False], counts)
    refitted, notes = refit_final(selection, nominal, train, heldout[False], logs, counts, SETTINGS, bootstrap, _serial)
    assert notes == []
    final = refitted.final
    assert refitted.subset_fit is selection.final and final is not selection.final
    assert final.effects["actuator_saturation"].values[0] == pytest.approx(limit, rel=0.02)
    low, high = interval(final.samples["actuator_saturation"][:, 0])
    assert low <= limit <= high
    assert refitted.over_nominal[final.name].heldout_gap == pytest.approx(final.heldout.gap)
    assert refitted.verdict == selection.verdict and refitted.accepted == selection.accepted


def test_a_refit_that_would_change_the_verdict_is_not_reported(problem):
    """Held-out logs with a burst: the drawn windows' fit leaves their gap open (verdict unexplained), the
    refit would close it; the selection's verdict and its fit stay."""
    nominal, _, train, heldout, logs, fitted = problem
    counts = RIGS["lund"]().counts_per_rev
    selection, bootstrap = _selection(fitted, nominal, heldout[True], counts)
    assert selection.verdict == "unexplained"
    refitted, notes = refit_final(selection, nominal, train, heldout[True], logs, counts, SETTINGS, bootstrap, _serial)
    assert refitted is selection and "would change the verdict" in notes[0]


def test_with_no_more_train_windows_than_the_draw_nothing_changes(problem):
    nominal, _, train, heldout, logs, fitted = problem
    counts = RIGS["lund"]().counts_per_rev
    selection, bootstrap = _selection(fitted, nominal, heldout[True], counts)
    every = dataclasses.replace(SETTINGS, fit_windows=train.count)
    assert refit_final(selection, nominal, train, heldout[True], logs, counts, every, bootstrap, _serial) == (
        selection,
        [],
    )
