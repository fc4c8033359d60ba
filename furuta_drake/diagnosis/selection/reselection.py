"""The selection run again beside the kept torque (stage 4c of the diagnosis).

An effect outside the vocabulary can distort a listed one in the selection: beside cogging, Coulomb friction
never enters, or enters at a wrong size, and the torque found afterwards takes a friction-like share of it. Once a
torque is kept, the selection (:class:`~furuta_drake.diagnosis.selection.stepwise.Stepwise`) runs again with the
torque's terms outside the listed effects' shapes in the model as fixed terms, so that listed effects are fitted beside
the outside effect; the torque is then found again beside the effects kept there
(:func:`~furuta_drake.diagnosis.selection.missing_torque.find_missing_torque`, judged by the same rule). This repeats
while the kept effects or the torque's terms change, at most ``RESELECTIONS`` times.

The report's selection stays one over the rig file's model: the effects kept beside the torque, at the values
fitted there, are judged without it against the nominal model (their held-out gaps evaluated again), so the verdict
still says what the listed effects explain.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from furuta_drake.diagnosis.gap.metric import Windows, evaluate_gap
from furuta_drake.diagnosis.selection.missing_torque import MissingTorque, find_missing_torque, with_terms
from furuta_drake.diagnosis.selection.rule import Bootstrap, is_kept
from furuta_drake.diagnosis.selection.stepwise import Selection
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.torque_library import JOINTS, LISTED_SHAPES, TERMS, copied_effect, term_values
from furuta_drake.effects.vocabulary import apply_effects

RESELECTIONS = 2  # selections run again beside a kept torque at the most


def reselect_beside_torque(
    selection: Selection,
    missing: MissingTorque | None,
    nominal: Model,
    select: Callable[[Model], Selection],
    train: Windows,
    heldout: Windows,
    counts: int,
    bootstrap: Bootstrap,
    settings,
) -> tuple[Selection, MissingTorque | None, list[str]]:
    """The selection and the torque after running ``select`` (the stepwise selection on a given base model) again
    beside the kept torque (module docstring), and the report's notes. The base holds the torque's terms that no
    listed effect's torque has the shape of (:func:`_base_keys`): a friction-shaped term corrects the listed
    friction fitted beside the outside effect, and held fixed it would keep that fit. The passes stop when the kept
    effects and the torque's terms outside those shapes no longer change, when the torque found again is not kept,
    or when the torque kept before explains the held-out data better by the rule's margin."""
    notes = []
    for _ in range(RESELECTIONS):
        base = [(j, t, c) for j, t, c in missing.terms if (j, t) in _base_keys(missing)] if missing else []
        if not base:
            break
        again = select(with_terms(nominal, base))
        if any(again.model(again.accepted[:k]) is None for k in range(1, len(again.accepted) + 1)):
            break  # a step's model failed to fit: the report could not show the steps
        model = apply_effects(nominal, again.final.effects if again.final else {})
        reference = evaluate_gap(model, heldout, counts).per_window
        judge = again.rule_bootstrap(bootstrap)
        found = find_missing_torque(
            model, selection.nominal.per_window, reference, train, heldout, counts, judge, settings
        )
        worse = found is not None and is_kept(judge.evidence(found.heldout.per_window, missing.heldout.per_window))
        if found is None or not found.kept or worse:
            break
        before, after = (", ".join(s.accepted) or "no effect" for s in (selection, again))
        notes.append(
            f"selected again with the unmodelled torque's {', '.join(TERMS[t] for _, t, _ in base)} in the model: "
            + (
                f"{before} became {after}"
                if before != after
                else (f"{after} fitted again beside it" if again.accepted else "no effect entered beside it")
            )
            + "; the torque then found again beside them"
        )
        unchanged = set(again.accepted) == set(selection.accepted) and _base_keys(found) == _base_keys(missing)
        selection, missing = rebased(again, selection, nominal, train, heldout, counts, bootstrap), found
        if unchanged:  # the next pass would select on the same terms
            break
    return selection, missing, notes


def _base_keys(missing: MissingTorque) -> set[tuple[int, int]]:
    """The (joint, term) of the torque's terms that no listed effect's torque has the shape of: neither one of the
    listed shapes (``LISTED_SHAPES``) nor a term that takes a listed effect's shape along the train windows
    (:func:`~furuta_drake.effects.torque_library.copied_effect`: ``tanh(phi_dot/0.02)*cos(phi)`` is Coulomb friction
    on a balancing arm). Held fixed, such a term would keep the listed effect it copies out of the selection."""
    keys = set()
    for j, t, _ in missing.terms:
        values = term_values(*missing.scatter[JOINTS[j]]["state"])
        if (j, TERMS[t]) not in LISTED_SHAPES and copied_effect(j, t, values) is None:
            keys.add((j, t))
    return keys


def rebased(
    again: Selection,
    first: Selection,
    nominal: Model,
    train: Windows,
    heldout: Windows,
    counts: int,
    bootstrap: Bootstrap,
) -> Selection:
    """``again`` (a selection over the nominal model with a torque) as a selection over ``nominal`` itself: the
    models of its kept effects (each step's, and each without one of them) at their fitted values, their gaps
    evaluated without the torque, and their evidence over the nominal model, over the step before and over the
    others; ``first`` (the selection over ``nominal``) gives the other models tried (those of the same names
    left out)."""
    kept = again.accepted
    sets = [kept[:k] for k in range(1, len(kept) + 1)] + [[o for o in kept if o != name] for name in kept]
    models = {}
    for effects in sets:
        fitted = again.model(effects) if effects else None
        if fitted is not None and frozenset(effects) not in models:
            model = apply_effects(nominal, fitted.effects)
            models[frozenset(effects)] = dataclasses.replace(
                fitted, heldout=evaluate_gap(model, heldout, counts), train_gap=evaluate_gap(model, train, counts).gap
            )
    out = Selection(
        first.nominal,
        [(len(key), result) for key, result in models.items()]
        + [(step, r) for step, r in first.tried if r.name not in {m.name for m in models.values()}],
        accepted=list(kept),
        over_nominal=dict(first.over_nominal),
        over_previous=dict(first.over_previous),
        quiet=first.quiet,
        runners_up=again.runners_up,
        exchanges=again.exchanges,
        sensors=again.sensors,
        jitter=again.jitter,
        beneath=again.beneath,
        beneath_variance=again.beneath_variance,
    )
    judge = out.rule_bootstrap(bootstrap)
    nominal_gap = first.nominal.per_window
    for key, result in models.items():
        out.over_nominal[result.name] = bootstrap.evidence(nominal_gap, result.heldout.per_window)
        built_on = models.get(frozenset(key - {result.name.split("+")[-1]}))
        out.over_previous[result.name] = judge.evidence(
            built_on.heldout.per_window if built_on else nominal_gap, result.heldout.per_window
        )
    chain = [nominal_gap] + [model.heldout.per_window for model in out.step_models]
    for result, before, after in zip(out.step_models, chain[:-1], chain[1:]):
        out.over_previous[result.name] = judge.evidence(before, after)
    out.over_step = [judge.evidence(before, after) for before, after in zip(chain[:-1], chain[1:])]
    for name in kept:
        without = models.get(frozenset(o for o in kept if o != name))
        out.over_others[name] = judge.evidence(without.heldout.per_window if without else nominal_gap, chain[-1])
    return out
