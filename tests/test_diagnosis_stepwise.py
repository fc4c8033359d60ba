"""The selection's pair entry: when no single effect enters first because each masks the other, the candidates
with the lowest train gaps (one per law) are fitted together in pairs, and the pair enters on the same held-out
rule a single effect does."""

from __future__ import annotations

import numpy as np

from furuta_drake.diagnosis.candidates import Effect
from furuta_drake.diagnosis.fit import FitResult
from furuta_drake.diagnosis.gap import GapResult
from furuta_drake.diagnosis.select import ENTRY, Bootstrap
from furuta_drake.diagnosis.stepwise import Selection, _enter_pair

WINDOWS = 200
NOMINAL = np.full(WINDOWS, 1.0)  # excess squared residual per held-out window [counts^2]


def _gap(per_window: np.ndarray) -> GapResult:
    return GapResult(float(np.sqrt(per_window.mean())), {}, per_window, 0.0, [], [])


def _single(name: str, train_gap: float) -> FitResult:
    return FitResult(name, {name: Effect("", (1.0,))}, train_gap, _gap(NOMINAL.copy()))


def _run(pair_excess: dict[frozenset, float], singles: dict[str, FitResult]):
    """The selection, a fake of the fits (pairs with the given held-out excess), and the tasks asked for."""
    rng = np.random.default_rng(0)
    bootstrap = Bootstrap(WINDOWS, 500, 0)
    selection = Selection(_gap(NOMINAL), [(1, result) for result in singles.values()])
    asked = []

    def task(new, held):
        asked.append(frozenset([*held.effects, new]))
        return (new, held)

    def fit(tasks):
        results = []
        for new, held in tasks:
            effects = {**held.effects, new: Effect("", (1.0,))}
            level = pair_excess.get(frozenset(effects), 1.0)
            result = FitResult("+".join(effects), effects, 0.5, _gap(level * (1 + 0.05 * rng.standard_normal(WINDOWS))))
            selection.tried.append((2, result))
            selection.over_previous[result.name] = bootstrap.evidence(NOMINAL, result.heldout.per_window)
            results.append(result)
        return results

    return selection, task, fit, asked


def test_a_pair_that_neither_member_explains_alone_enters_better_single_first():
    singles = {
        "inertia_mismatch": _single("inertia_mismatch", 1.1),
        "arm_spring": _single("arm_spring", 1.2),
        "arm_coulomb_friction": _single("arm_coulomb_friction", 1.25),
        "arm_stribeck": _single("arm_stribeck", 1.22),  # the same law as Coulomb friction: one of them only
        "input_delay": _single("input_delay", 1.7),
    }
    # the pair halves the gap's square: a reduction of 1 - sqrt(0.25) = 50 %, far above the entry bound
    selection, task, fit, asked = _run({frozenset(["inertia_mismatch", "arm_spring"]): 0.25}, singles)
    assert _enter_pair(singles, task, fit, selection) == ["inertia_mismatch", "arm_spring"]
    assert set(asked) == {
        frozenset(["inertia_mismatch", "arm_spring"]),
        frozenset(["inertia_mismatch", "arm_stribeck"]),
        frozenset(["arm_spring", "arm_stribeck"]),
    }


def test_no_pair_enters_when_none_reduces_the_gap_beyond_the_entry_bound():
    singles = {name: _single(name, gap) for name, gap in (("inertia_mismatch", 1.1), ("arm_spring", 1.2))}
    # a 2 % reduction of the gap (excess x 0.96) is below the entry bound's 5 %
    assert 1 - np.sqrt(0.96) < ENTRY
    selection, task, fit, _ = _run({frozenset(["inertia_mismatch", "arm_spring"]): 0.96}, singles)
    assert _enter_pair(singles, task, fit, selection) is None
