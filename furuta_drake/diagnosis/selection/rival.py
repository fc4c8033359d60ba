"""Intervals that hold when the model is not complete: the accepted model's parameter intervals inflated about
the fitted value by ``rule.INTERVAL_INFLATION``, then widened by how far its parameters move when the strongest
candidate not accepted is fitted beside it.

The block bootstrap of :mod:`~furuta_drake.diagnosis.selection.fit` states the spread of a fit *given* its model. An
effect below the detection limits may still act on the logs, and the accepted effects then absorb part of it: their
values are biased by an amount the bootstrap cannot see. Each interval [lo, hi] of a fitted value x first becomes
[x - k (x - lo), x + k (hi - x)] with k = ``INTERVAL_INFLATION`` (never below 0 for a parameter that cannot be
negative), the factor calibrated on the suites with and without a small hidden second effect
(benchmarks/diagnosis/interval_coverage_fits.py). The forward pass has also fitted the model holding the accepted
effects and each further candidate *together* (the joint refits of the step after the last one kept, or the model before
the backward pass dropped an effect); the one that reduces the final model's held-out gap the most is the
*rival*. A parameter whose value moves by d in the rival then spans [min(lo, lo + d), max(hi, hi + d)] of the
inflated interval: it holds whether or not the rival is present. The move is measured from the final model as the
selection fitted it (the rival's fit windows), also when the report's final model is its refit on every train
window (:mod:`~furuta_drake.diagnosis.selection.final_fit`).
"""

from __future__ import annotations

import dataclasses

from furuta_drake.diagnosis.result import RankedCandidate
from furuta_drake.diagnosis.selection.fit import FitResult
from furuta_drake.diagnosis.selection.rule import INTERVAL_INFLATION, Bootstrap
from furuta_drake.diagnosis.selection.stepwise import Selection
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import SIGNED, describe


def rival(selection: Selection, bootstrap: Bootstrap) -> FitResult | None:
    """The model holding every kept effect and one more, refitted together (a kept effect's values moved), that
    reduces the final model's held-out gap the most; None when none was fitted."""
    final = _selected(selection)
    if final is None:
        return None
    kept = set(selection.accepted)
    joint = [
        result
        for _, result in selection.tried
        if not result.failure
        and set(result.effects) > kept
        and len(result.effects) == len(kept) + 1
        and any(result.effects[name] != final.effects[name] for name in kept)
    ]
    reduction = {
        result.name: bootstrap.evidence(final.heldout.per_window, result.heldout.per_window).reduction
        for result in joint
    }
    return max(joint, key=lambda result: reduction[result.name], default=None)


def shifts(selection: Selection, bootstrap: Bootstrap, nominal: Model) -> dict[str, float]:
    """Per reported parameter of the final model (its ranking keys), the move of its value in the rival model from
    the final model as the selection fitted it."""
    found = rival(selection, bootstrap)
    if found is None:
        return {}
    final, several = _selected(selection), len(selection.accepted) > 1
    out = {}
    for name in selection.accepted:
        before = describe(name, final.effects[name], nominal)
        after = describe(name, found.effects[name], nominal)
        if before.get("form") != after.get("form"):
            continue  # a move across forms is no shift of one parameter
        prefix = f"{name}." if several else ""
        out.update({prefix + key: after[key] - value for key, value in before.items() if key != "form"})
    return out


def _selected(selection: Selection) -> FitResult | None:
    """The final model as the selection fitted it (on the fit windows the rivals were fitted on)."""
    return selection.subset_fit or selection.final


def inflated(value: float, low: float, high: float, name: str, factor: float = INTERVAL_INFLATION) -> list[float]:
    """The interval [``low``, ``high``] of the fitted ``value`` of parameter ``name`` (its last dotted part a
    vocabulary name) inflated about it by ``factor``; not below 0 unless the parameter is signed."""
    inflated_low = min(low, value - factor * (value - low))  # never narrower than the bootstrap's
    high = max(high, value + factor * (high - value))
    return [inflated_low if name.rsplit(".", 1)[-1] in SIGNED else max(inflated_low, min(low, 0.0)), high]


def widen(ranking: list[RankedCandidate], selection: Selection, bootstrap: Bootstrap, nominal: Model):
    """``ranking`` with the final model's ``params_ci`` inflated and widened by the rival's shifts (module
    docstring); the bootstrap's own intervals kept as ``params_ci_if_complete``."""
    if selection.final is None:
        return ranking
    moves = shifts(selection, bootstrap, nominal)
    out = []
    for row in ranking:
        if row.effect == selection.final.name and row.params_ci:
            widened = {}
            for key, (low, high) in row.params_ci.items():
                low, high = inflated(row.params[key], low, high, key)
                move = moves.get(key, 0.0)
                widened[key] = [min(low, low + move), max(high, high + move)]
            row = dataclasses.replace(row, params_ci=widened, params_ci_if_complete=row.params_ci)
        out.append(row)
    return out
