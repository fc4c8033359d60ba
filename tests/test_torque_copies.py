"""A torque beyond the vocabulary never takes a listed effect's place: terms that take a listed effect's shape
along the data are recognised as that effect's (and so never held fixed when the selection runs again beside the
torque), and a torque that copies a listed effect is said to."""

from __future__ import annotations

import numpy as np
import pytest

from furuta_drake.diagnosis.selection.missing_torque import MissingTorque, copies
from furuta_drake.effects.torque_library import TERMS, copied_effect, term_values


def _balancing_states(seed: int = 0, samples: int = 2000) -> np.ndarray:
    """States of a balancing run: the pendulum near the upright, the arm within 0.3 rad, both rates reversing."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 20.0, samples)
    phi = 0.3 * np.sin(1.3 * t) + 0.02 * rng.normal(size=samples)
    theta = 0.05 * np.sin(4.1 * t + 1.0)
    return np.vstack([theta, phi, 0.2 * np.cos(4.1 * t + 1.0), 0.39 * np.cos(1.3 * t) + 0.3 * rng.normal(size=samples)])


@pytest.mark.parametrize(
    "joint, term, effect",
    [
        (0, "tanh(phi_dot/0.02)", "arm_coulomb_friction"),
        (0, "tanh(phi_dot/0.02)*cos(phi)", "arm_coulomb_friction"),  # cos(phi) > 0.95 over the arm's range
        (0, "phi_dot", "arm_viscous_friction"),
        (1, "tanh(theta_dot/0.02)", "pendulum_friction"),
        (0, "sin(18*phi)", None),  # cogging of 18 periods a turn: no listed effect's shape
        (1, "cos(theta)", None),
    ],
)
def test_a_term_is_a_listed_effects_when_it_takes_that_shape_along_the_data(joint, term, effect):
    values = term_values(*_balancing_states())
    assert copied_effect(joint, TERMS.index(term), values) == effect


def test_a_torque_that_takes_coulomb_frictions_shape_copies_it_and_cogging_does_not():
    states = _balancing_states(1)
    values = term_values(*states)
    coulomb = -0.00176 * values[TERMS.index("tanh(phi_dot/0.02)*cos(phi)")]
    cogging = 0.002 * values[TERMS.index("sin(18*phi)")]

    def torque(fitted):
        return MissingTorque([], [], None, None, None, scatter={"arm": {"state": states, "fitted": fitted}})

    assert copies(torque(coulomb), "arm_coulomb_friction")
    assert not copies(torque(cogging), "arm_coulomb_friction")
    assert not copies(torque(coulomb), "arm_spring")


def test_a_selection_run_again_beside_a_torque_gives_every_model_its_evidence(monkeypatch):
    """The selection over the torque's base, made one over the rig file's model (:func:`rebased`): every model it
    holds, the models without one kept effect included, has its evidence over the model it was built on, so the
    ranking lists them (real logs with a position-periodic torque written in once ended in a KeyError there)."""
    from furuta_drake.diagnosis.gap.metric import GapResult
    from furuta_drake.diagnosis.pipeline import ranking
    from furuta_drake.diagnosis.selection import reselection
    from furuta_drake.diagnosis.selection.fit import FitResult
    from furuta_drake.diagnosis.selection.rule import Bootstrap
    from furuta_drake.diagnosis.selection.stepwise import Selection
    from furuta_drake.effects.surrogate import Model
    from furuta_drake.effects.vocabulary import Effect
    from furuta_drake.rig import RIGS

    windows = 50
    levels = {"input_delay": 0.5, "arm_viscous_friction": 0.6, "input_delay+arm_viscous_friction": 0.1}

    def gap(level):
        per_window = np.full(windows, level) + 0.01 * np.random.default_rng(int(100 * level)).normal(size=windows)
        return GapResult(float(np.sqrt(per_window.mean())), {}, per_window, 1 / 12, [], [])

    effects = {"input_delay": Effect("fixed", (3e-3,)), "arm_viscous_friction": Effect("", (1e-3,))}

    def fit(names):
        return FitResult("+".join(names), {n: effects[n] for n in names}, 0.5, gap(levels["+".join(names)]))

    monkeypatch.setattr(reselection, "evaluate_gap", lambda model, heldout, counts: gap(levels[_name_of(model)]))
    kept = ["input_delay", "arm_viscous_friction"]
    again = Selection(gap(1.0), [(1, fit(kept[:1])), (2, fit(kept)), (1, fit(kept[1:]))], accepted=kept)
    first = Selection(gap(1.0), [(1, fit(kept[:1]))])
    bootstrap = Bootstrap(windows, 200, 0)
    first.over_nominal = {"input_delay": bootstrap.evidence(first.nominal.per_window, gap(0.5).per_window)}
    first.over_previous = dict(first.over_nominal)
    nominal = Model.from_rig(RIGS["lund"]())
    out = reselection.rebased(again, first, nominal, None, None, 4096, bootstrap)
    assert {r.name for _, r in out.tried} <= set(out.over_previous) and set(out.over_previous) <= set(out.over_nominal)
    assert {row.effect for row in ranking(out, nominal)} == {"input_delay", "arm_viscous_friction", "+".join(kept)}


def _name_of(model) -> str:
    """Which of the fake models ``model`` is: by its delay and its arm's viscous level."""
    names = [
        name
        for name, on in (("input_delay", model.delay > 0), ("arm_viscous_friction", model.arm_friction.viscous > 0))
        if on
    ]
    return "+".join(names)
