"""The forward steps' screen: every candidate is fitted briefly first, and only those whose screen comes within
reach of the best are fitted fully. A full fit goes on from the starts its screen ranked, so it is the fit the
selection made without a screen; a candidate left behind cannot come near the one that enters once both are
fitted; when no single candidate enters, every one is fitted before the pairs are formed from their fits."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from furuta_drake.diagnosis.gap.metric import make_windows
from furuta_drake.diagnosis.selection import stepwise
from furuta_drake.diagnosis.selection.fit import FitTask, fit_task, screen_task
from furuta_drake.diagnosis.selection.rule import PARSIMONY
from furuta_drake.diagnosis.selection.stepwise import select_effects
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import CANDIDATES
from furuta_drake.rig import RIGS
from tests.conftest import suite_log

SETTINGS = DiagnosisSettings(
    fit_windows=20, start_windows=8, bootstrap=200, interval_resamples=50, max_effects=2, detection_limits=False
)


def _serial(function, tasks):
    return [function(task) for task in tasks]


@pytest.fixture(scope="module")
def viscous_qube():
    """A QUBE-Servo 2 under an open-loop multisine with the suite's strong arm viscous friction: a train and a
    held-out log."""
    rig = RIGS["qube_servo2"]()
    logs = [suite_log("hanging", seed, "arm_viscous_friction", 2, 3.0, rig="qube_servo2") for seed in (1, 2)]
    return rig, logs


def _select(rig, logs, settings):
    train, heldout = make_windows(logs[:1], rig), make_windows(logs[1:], rig)
    nominal = Model.from_rig(rig)
    names = [name for name, candidate in CANDIDATES.items() if candidate.offered(nominal)]
    return select_effects(nominal, logs[:1], train, heldout, rig.counts_per_rev, names, settings, _serial)


def test_a_fit_from_its_screens_starts_is_the_fit_without_a_screen():
    """Both forms of a delay (fixed and jittering, the latter judged by the variance it adds) fitted from the
    screen's ranked starts give the fit ranked from every start, to the last bit."""
    rig = RIGS["lund"]()
    train = [suite_log("hanging", 3, "input_delay", 2, 3.0)]
    windows = make_windows(train, rig)
    task = FitTask("input_delay", {}, Model.from_rig(rig), windows, None, tuple(train), rig.counts_per_rev, SETTINGS)
    screen = screen_task(task)
    assert set(screen.starts) == {form.name for form in CANDIDATES["input_delay"].forms}
    plain, screened = fit_task(task), fit_task(dataclasses.replace(task, starts=screen.starts))
    assert screened.effects == plain.effects and screened.train_gap == plain.train_gap
    assert all(np.array_equal(screened.samples[name], plain.samples[name]) for name in plain.samples)
    # the screen itself already points at the 4.5-period delay the world holds
    assert screen.effects["input_delay"].values[0] == pytest.approx(4.5e-3, abs=1e-3)


def test_the_screen_keeps_the_decision_and_leaves_behind_only_what_cannot_come_near(viscous_qube):
    rig, logs = viscous_qube
    screened = _select(rig, logs, SETTINGS)
    full = _select(rig, logs, dataclasses.replace(SETTINGS, screen=False))
    assert screened.accepted == full.accepted and screened.accepted[0] == "arm_viscous_friction"
    assert screened.final.effects == full.final.effects  # the model that entered was fitted as without a screen
    models = [frozenset(result.effects) for _, result in screened.tried if not result.failure]
    assert len(models) == len(set(models))  # one row per model: a later fit takes the place of its screen
    left = {result.name: result for step, result in screened.tried if step == 1 and result.screened}
    assert left, "a strong viscous friction leaves some candidate far behind on the screen"
    assert "arm_viscous_friction" not in left
    for name, result in left.items():
        assert not result.samples and "not fitted further" in result.screened  # a screen's values, no interval
        # fitted fully, the candidate removes clearly less of the held-out gap than the one that entered
        fitted = full.over_nominal[name].reduction
        assert fitted < full.over_nominal["arm_viscous_friction"].reduction - PARSIMONY


def test_when_no_candidate_enters_alone_every_screened_one_is_fitted_before_the_pairs(viscous_qube, monkeypatch):
    rig, logs = viscous_qube
    pairs_from = []

    def no_single_enters(*args, **kwargs):
        return None

    def enter_pair(fitted, *args):
        pairs_from.append(dict(fitted))
        return None

    monkeypatch.setattr(stepwise, "choose", no_single_enters)
    monkeypatch.setattr(stepwise, "_enter_pair", enter_pair)
    selection = _select(rig, logs, dataclasses.replace(SETTINGS, max_effects=2))
    assert selection.accepted == [] and len(pairs_from) == 1
    assert pairs_from[0] and not any(result.screened for result in pairs_from[0].values())
    assert not any(result.screened for step, result in selection.tried if step == 1)
