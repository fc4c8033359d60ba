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

A friction law's form is a rival of its own: a presliding spring and a smooth sign fit stick-slip about equally
well when the true friction is neither (a bristle model, a Karnopp law), and the levels each reads differ by more
than either's bootstrap spread. So each kept friction law is also fitted in its other form beside the other kept
effects (every effect refitted, on the same fit windows); where the data cannot rule that form out (the 90 %
interval of the difference of the two models' held-out excess squared residuals stays within the floor's
resolution), the intervals also span the moves of the parameters both forms share and of the other effects'.
"""

from __future__ import annotations

import dataclasses

from furuta_drake.diagnosis.result import RankedCandidate
from furuta_drake.diagnosis.selection.fit import FitResult, FitTask, scales_of
from furuta_drake.diagnosis.selection.rule import INTERVAL_INFLATION, Bootstrap, beyond_resolution
from furuta_drake.diagnosis.selection.stepwise import Selection, in_form
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import CANDIDATES, SIGNED, describe, law_of

FRICTION_LAWS = law_of("arm_coulomb_friction")  # the kept laws whose forms are fitted as rivals


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


def form_rival_tasks(selection: Selection, template: FitTask) -> list[FitTask]:
    """The fits of the final model (as the selection fitted it) with one kept friction law in another of its forms,
    started from its values there (the parameters both forms have kept), every effect refitted; ``template``: a
    task on the selection's train and held-out windows whose ``new`` and ``fixed`` are replaced."""
    final = _selected(selection)
    if final is None:
        return []
    scales, tasks = scales_of(template.logs, template.model), []
    for name in (name for name in selection.accepted if name in FRICTION_LAWS):
        effect = final.effects[name]
        others = {other: value for other, value in final.effects.items() if other != name}
        for form in CANDIDATES[name].forms:
            if form.name != effect.form:
                start = in_form(name, effect, form, scales)
                tasks.append(dataclasses.replace(template, new=name, fixed=others, start=start))
    return tasks


def shifts(selection: Selection, bootstrap: Bootstrap, nominal: Model) -> dict[str, list[float]]:
    """Per reported parameter of the final model (its ranking keys), the moves of its value from the final model as
    the selection fitted it: in the rival model, and in each form rival the data cannot rule out (module
    docstring)."""
    final = _selected(selection)
    found = rival(selection, bootstrap)
    models = [found] if found is not None else []
    models += [
        result
        for result in selection.form_rivals
        if not result.failure
        and not beyond_resolution(
            bootstrap.excess_difference_interval(result.heldout.per_window, final.heldout.per_window)[0]
        )
    ]
    several, out = len(selection.accepted) > 1, {}
    for model in models:
        for name in selection.accepted:
            before = describe(name, final.effects[name], nominal)
            after = describe(name, model.effects[name], nominal)
            prefix = f"{name}." if several else ""
            for key, value in before.items():
                if key != "form" and key in after:  # a parameter only one form has moves nowhere
                    out.setdefault(prefix + key, []).append(after[key] - value)
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
                move = moves.get(key, [0.0])
                widened[key] = [min(low, low + min(move)), max(high, high + max(move))]
            row = dataclasses.replace(row, params_ci=widened, params_ci_if_complete=row.params_ci)
        out.append(row)
    return out
