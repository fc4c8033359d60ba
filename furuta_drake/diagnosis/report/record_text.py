"""The text keys of ``report.json``, written from the diagnosis' data: the held-out rule (``rule``, from the rule's
own constants), why the verdict (``choice``), why two effects are confusable (``confusable[].why``), how consistent
the folds were (``consistency.judgement``). The computing stages return numbers; these functions put them into
words (the reports' own sentences are :mod:`~furuta_drake.diagnosis.report.narrative`'s)."""

from __future__ import annotations

import numpy as np

from furuta_drake.diagnosis.selection.rule import (
    CLOSES,
    CONFUSABLE_LEVEL,
    ENTRY,
    FLOOR_COUNTS,
    LOWER_BOUND_QUANTILE,
    MARGIN,
    NEGLIGIBLE_COUNTS,
    NOISE_STANDARD_ERRORS,
    PARSIMONY,
)
from furuta_drake.diagnosis.selection.stepwise import EXCHANGE_RUNNERS_UP, PAIR_ENTRY, Selection
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import CANDIDATES, UNITS

NUMBERS = {1: "one", 2: "two", 3: "three", 4: "four", 5: "five"}


def rule_text(bootstrap: int, seed: int, max_effects: int) -> str:
    """The acceptance rule in one paragraph, written into every report from the rule's constants."""
    bound = f"{100 * LOWER_BOUND_QUANTILE:g} %"
    noise = "twice" if NOISE_STANDARD_ERRORS == 2 else f"{NOISE_STANDARD_ERRORS:g} times"
    return (
        f"Held-out reductions are bootstrapped over held-out windows ({bootstrap} paired resamples, seed "
        f"{seed}). Effects enter one at a time, at most {NUMBERS.get(max_effects, max_effects)}: nothing more "
        f"enters once a model's held-out gap "
        f"is below {FLOOR_COUNTS} counts; the candidate with the largest reduction over the model holding the earlier "
        f"effects enters when the {bound} lower bound of that reduction exceeds {ENTRY:.0%} (a simpler one within "
        f"{PARSIMONY:.0%} of it is preferred, or at the floor one whose mean excess squared residual is not larger "
        f"by more than {FLOOR_COUNTS}^2 counts^2 beyond a {CONFUSABLE_LEVEL:.0%} bootstrap interval; when none "
        f"enters first, the best pair of the {NUMBERS[PAIR_ENTRY]} best train fits may enter together on the same "
        f"bound); an "
        f"effect is kept when the reduction it brings to the model "
        f"holding all the other kept effects is at least {MARGIN:.0%} with a {bound} lower bound above {ENTRY:.0%} "
        f"and removes more than {FLOOR_COUNTS}^2 counts^2 of excess squared residual at its {bound} lower bound, "
        f"else the weakest is dropped and the forward steps resume without it; a kept effect is exchanged for "
        f"one of the {NUMBERS[EXCHANGE_RUNNERS_UP]} "
        f"best other-law candidates of "
        f"the step it entered at when the model holding that one and the other kept effects reduces the final "
        f"model's held-out gap with a {bound} lower bound above {ENTRY:.0%}; the verdict is none when no effect is "
        f"kept and the nominal gap is below {FLOOR_COUNTS} counts or {noise} its bootstrap standard error; "
        f"two supported candidates of different laws whose "
        f"difference of reductions has a {CONFUSABLE_LEVEL:.0%} interval holding 0, or whose mean excess squared "
        f"residuals differ by no more than {FLOOR_COUNTS}^2 counts^2 at that interval's bound, are reported as "
        f"confusable; "
        f"accepted effects that together reduce the nominal gap by less than {CLOSES:.0%} leave it "
        f"unexplained, unless it is below {NEGLIGIBLE_COUNTS} counts: then the verdict is none and the nearest "
        f"candidate is named."
    )


def confusable_why(pair: dict) -> str:
    """Why two effects are confusable (:func:`furuta_drake.diagnosis.selection.rule.confusable`'s ``pair``), in one
    clause."""
    (first, second), (r_first, r_second) = pair["effects"], pair["reductions"]
    low, high = pair["difference"]
    if pair["by_excess"]:
        difference = (
            f"mean excess squared residuals, [{low:+.3g}, {high:+.3g}] counts^2, stays below the floor's "
            f"resolution ({FLOOR_COUNTS}^2 counts^2)"
        )
    else:
        difference = f"reductions, [{100 * low:+.1f}, {100 * high:+.1f}] points, holds 0"
    return (
        f"held-out reductions {r_first:.1%} ({first}) and {r_second:.1%} ({second}): the {CONFUSABLE_LEVEL:.0%} "
        f"bootstrap interval of the difference of their {difference}"
    )


def choice_text(selection: Selection) -> str:
    """Why the verdict, in one paragraph: the effects that change the predictions, then the sensor's."""
    parts = (_gain_only_text(selection), _prediction_text(selection), sensor_text(selection))
    return " ".join(part for part in parts if part)


def _gain_only_text(selection: Selection) -> str:
    """Why the command maps were not tried, when they were not."""
    if not selection.gain_only:
        return ""
    return (
        f"The logged commands take one magnitude (a bang-bang): on them {' and '.join(selection.gain_only)} act as a "
        f"gain of the drive, so torque_gain_error was tried in their place."
    )


def sensor_text(selection: Selection) -> str:
    """What the sensor effects' signature showed on the held-out windows, one sentence each: a sensor effect that
    passes its test is accepted only when the selection closes the gap (else it is not among the effects)."""
    parts = []
    for finding in selection.sensors:
        if finding.accepted:
            verb = "is accepted on its signature" if selection.closes else "passes its signature test"
            parts.append(
                f"{finding.name} {verb}: its held-out log score beats the rig file's sensor by "
                f"{finding.score_gain:.3g} nats per window (5 % lower bound {finding.lower_bound:.3g})."
                + ("" if selection.closes else " It is not among the effects: with them the gap is not closed.")
            )
        elif finding.note:
            parts.append(f"{finding.name} is not accepted: {finding.note}.")
    jitter = selection.jitter
    if jitter is not None:
        verb = "are" if jitter.credited else "are not"
        parts.append(
            f"The jittering delay's draws {verb} credited with the variance they add: on the held-out windows they "
            f"score {float(np.mean(jitter.gain)):.3g} nats per window above a constant variance (5 % lower bound "
            f"{jitter.lower_bound:.3g})."
        )
    return " ".join(parts)


def _prediction_text(selection: Selection) -> str:
    """Why the effects that change the predictions were kept (or none was)."""
    if not selection.accepted:
        if selection.closes:
            return "No effect that changes the predictions is needed."
        if selection.quiet:
            return "The nominal model explains the held-out data to within their noise: no effect is needed."
        if selection.negligible:
            return _negligible_text(selection)
        return "No candidate, nor set of candidates, reduces the nominal model's held-out gap by the rule's margin."
    total = selection.over_nominal[selection.final.name]
    text = (
        f"The model holding {', '.join(selection.accepted)} reduces the nominal held-out gap by {total.reduction:.1%} "
        f"(5 % lower bound {total.lower_bound:.1%}). "
    )
    if selection.beneath:
        text += (
            f"Each was judged on the held-out gap beyond the variance {' and '.join(selection.beneath)} adds (it "
            f"passes its signature test beside the nominal model), which would otherwise hide it; the reductions over "
            f"nominal keep the rig file's sensor alone taken off. "
        )
    if len(selection.accepted) > 1:
        text += (
            "Without each of them the held-out gap of the others' model grows: "
            + "; ".join(
                f"{name} brings {selection.over_others[name].reduction:.1%} (lower bound "
                f"{selection.over_others[name].lower_bound:.1%})"
                for name in selection.accepted
            )
            + "."
        )
    for exchange in selection.exchanges:
        evidence = exchange["evidence"]
        if exchange.get("simpler"):
            text += (
                f" {exchange['in']} replaced {exchange['out']}: beside the other kept effects it explains the held-out "
                f"data as well with one parameter (a drive gain g acts as a uniform scaling of the inertias and "
                f"gravity by 1/g; the held-out gap changes by {-evidence.reduction:+.1%}, within the bootstrap's "
                f"spread)."
            )
            continue
        text += (
            f" {exchange['in']} replaced {exchange['out']}, which had entered before it: beside the other kept "
            f"effects it explains the held-out data better, reducing the gap of the model holding "
            f"{exchange['out']} by {evidence.reduction:.1%} (lower bound {evidence.lower_bound:.1%})."
        )
    if selection.negligible:
        text += " " + _negligible_text(selection)
    elif not selection.closes:
        text += f" With the sensor's share that is less than the {CLOSES:.0%} that explains it: the gap is unexplained."
    for pair in selection.confusable:
        text += (
            f" {pair['effects'][1]} explains the held-out data as well as {pair['effects'][0]} "
            f"({confusable_why(pair)}); {pair['effects'][0]} was accepted for its larger point reduction or fewer "
            f"parameters."
        )
    return text


def consistency_judgement(consistency_result, nominal: Model) -> str:
    """One line: how often the verdict and each effect came back, the spread of the main parameters, and the
    effects these logs cannot pin down (:class:`~furuta_drake.diagnosis.result.Consistency`)."""
    verdicts, effects = consistency_result.verdicts, consistency_result.effects
    ranges, folds = consistency_result.params_range, len(verdicts)
    counts = {verdict: verdicts.count(verdict) for verdict in dict.fromkeys(verdicts)}
    if len(counts) == 1:
        text = f"same verdict ({verdicts[0]}) on {folds}/{folds} folds"
    else:
        text = "verdict " + ", ".join(f"{verdict} on {n}/{folds}" for verdict, n in counts.items()) + " folds"
    named = {name: sum(name in found for found in effects) for found in effects for name in found}
    if named and any(n < folds for n in named.values()):
        text += "; effects " + ", ".join(f"{name} {n}/{folds}" for name, n in named.items())
    mains = [
        f"{name} {CANDIDATES[name].main} {low:.4g}-{high:.4g}"
        for key, (low, high) in ranges.items()
        for name in [key.split(".")[0]]
        if key.split(".")[1] == CANDIDATES[name].main
    ]
    if mains:
        text += "; " + ", ".join(mains)
    if consistency_result.unsettled:
        text += "; these logs cannot pin down " + ", ".join(
            f"{name} (named on {n}/{folds})" for name, n in consistency_result.unsettled.items()
        )
    return text


def _negligible_text(selection: Selection) -> str:
    """Why a gap that nothing closes reads ``none``, with the nearest candidate and its fit."""
    text = (
        f"The nominal held-out gap, {selection.nominal.gap:.3f} counts after the sensor's own variance, is below "
        f"{NEGLIGIBLE_COUNTS} counts: too small to matter, so the verdict is none."
    )
    nearest = selection.nearest()
    if nearest is None:
        return text
    ((name, effect),) = nearest.effects.items()
    form = CANDIDATES[name].form(effect.form)
    values = ", ".join(
        f"{param} {value:.3g} {UNITS.get(param, '')}".rstrip() for param, value in zip(form.params, effect.values)
    )
    evidence = selection.over_nominal[nearest.name]
    return text + (
        f" The nearest candidate is {name}{f' ({effect.form})' if effect.form else ''} at {values}: it reduces the "
        f"gap by {evidence.reduction:.1%} (5 % lower bound {evidence.lower_bound:.1%})."
    )
