"""The selection run again beside a kept torque: on surrogate logs of Coulomb friction beside cogging, the listed
friction is fitted beside the cogging alone and the torque found again claims no friction."""

from functools import partial

import numpy as np
import pytest
from test_unmodelled_torque_diagnosis import NOMINAL, QUBE, SETTINGS, surrogate_log

from furuta_drake.diagnosis.gap.metric import evaluate_gap, make_windows
from furuta_drake.diagnosis.selection.missing_torque import find_missing_torque
from furuta_drake.diagnosis.selection.reselection import reselect_beside_torque
from furuta_drake.diagnosis.selection.rule import Bootstrap
from furuta_drake.diagnosis.selection.stepwise import select_effects
from furuta_drake.effects.surrogate import REGULARIZATION_VELOCITY
from furuta_drake.effects.torque_library import LISTED_SHAPES, TERMS
from furuta_drake.effects.vocabulary import apply_effects
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.parallel import run_tasks

LEVEL = 0.05 * NOMINAL.gravity_torque  # the arm's Coulomb friction [N m]
COGGING = (0, TERMS.index("sin(7*phi)"), 0.1 * NOMINAL.gravity_torque)


@pytest.mark.slow
def test_beside_cogging_the_friction_is_fitted_again_and_the_torque_claims_none_of_it():
    friction = JointFrictionParameters(
        model="static", coulomb_pos=LEVEL, coulomb_neg=LEVEL, regularization_velocity=REGULARIZATION_VELOCITY
    )
    truth = NOMINAL.replace(arm_friction=friction, unmodelled_terms=(COGGING,))
    logs = [surrogate_log(truth, 4.0, 1), surrogate_log(truth, 4.0, 2)]
    train, heldout = make_windows(logs, QUBE), make_windows([surrogate_log(truth, 3.0, 3)], QUBE)
    counts = QUBE.counts_per_rev
    bootstrap = Bootstrap(heldout.count, SETTINGS.bootstrap, SETTINGS.seed)
    bases = []

    def select(base):
        bases.append(base.unmodelled_terms)
        names = ["arm_coulomb_friction", "arm_viscous_friction"]
        return select_effects(base, logs, train, heldout, counts, names, SETTINGS, partial(run_tasks, workers=1))

    selection = select(NOMINAL)
    final = apply_effects(NOMINAL, selection.final.effects) if selection.final else NOMINAL
    first = find_missing_torque(
        final, selection.nominal.per_window, evaluate_gap(final, heldout, counts).per_window, train, heldout,
        counts, bootstrap, SETTINGS,
    )  # fmt: skip
    assert first is not None and first.kept
    selection, missing, notes = reselect_beside_torque(
        selection, first, NOMINAL, select, train, heldout, counts, bootstrap, SETTINGS
    )
    # the selections again held only the cogging-like terms, never a friction-shaped one
    assert len(bases) >= 2 and all((j, TERMS[t]) not in LISTED_SHAPES for terms in bases[1:] for j, t, _ in terms)
    assert notes and selection.accepted == ["arm_coulomb_friction"]
    coulomb = selection.final.effects["arm_coulomb_friction"].values[0]
    assert coulomb == pytest.approx(LEVEL, rel=0.1)
    cogging = [c for j, t, c in missing.terms if (j, t) == COGGING[:2]]
    assert cogging and cogging[0] == pytest.approx(COGGING[2], rel=0.1)
    claimed = [abs(c) for j, t, c in missing.terms if (j, TERMS[t]) in LISTED_SHAPES]
    assert sum(claimed) <= 0.1 * LEVEL
    assert np.isfinite(selection.over_nominal[selection.final.name].reduction)
