"""What the accepted effects leave (``report.json``'s ``remaining``).

When the final model's held-out gap, less what the accepted sensor effects account for, is above the rule's
negligible size (:func:`~furuta_drake.diagnosis.selection.rule.negligible`), the diagnosis says what is left: its
share of the nominal held-out gap, its size per signal, where it sits (the dominant signal, regime and band of the
localisation after the accepted effects, :func:`~furuta_drake.diagnosis.gap.localize.dominant`) and the effects
fitted beside the accepted ones that could still take part of it, each with why it was not accepted:

- ``confused_with:NAME``: the rule could not tell it from the accepted effect NAME (a confusable pair);
- ``at_bound``: its main parameter's fit ran to the end of its search range;
- ``below_detection_limit``: its fitted size is below what these logs detect for it;
- ``evidence``: otherwise, its reduction of the gap the accepted effects leave did not pass the rule.
"""

from __future__ import annotations

import math

from furuta_drake.diagnosis.gap.localize import dominant
from furuta_drake.diagnosis.result import DetectionLimit, GapFigures, RankedCandidate
from furuta_drake.diagnosis.selection.rule import negligible
from furuta_drake.effects.vocabulary import CANDIDATES

MAX_CANDIDATES = 5  # the candidates listed, largest share of what remains first
MIN_SHARE = 0.01  # a candidate is listed when it removes at least this share of what remains (the report's resolution)


def remaining_record(
    gap: GapFigures,
    per_signal: dict[str, float],
    localization: dict,
    ranking: list[RankedCandidate],
    accepted: list[str],
    confusable: list[dict],
    limits: list[DetectionLimit],
) -> dict:
    """The ``remaining`` entry ({} when what is left is negligible): ``gap`` the report's figures,
    ``per_signal`` the final model's held-out gap of theta and phi [counts], ``localization`` the report's (its
    ``after`` part read when there is one), ``accepted`` the effects of the final model."""
    nominal = gap.nominal["heldout"] or 0.0
    left_squared = (gap.with_effects["heldout"] or 0.0) ** 2 - (gap.sensor_share or 0.0) * nominal**2
    left = math.sqrt(max(left_squared, 0.0))
    if nominal <= 0.0 or negligible(left):
        return {}
    return {
        "share": left / nominal,
        "rms_counts": {name: per_signal.get(name) for name in ("theta", "phi")},
        "where": dominant(localization.get("after") or localization),
        "candidates": candidates(ranking, accepted, confusable, limits),
    }


def candidates(
    ranking: list[RankedCandidate], accepted: list[str], confusable: list[dict], limits: list[DetectionLimit]
) -> list[dict]:
    """Each effect fitted beside exactly the ``accepted`` ones (its latest step), not accepted, that removes at least
    ``MIN_SHARE`` of what they leave, with its held-out reduction over the nominal model (``heldout_reduction``), the
    share of the gap the accepted effects leave that it removes (``of_remaining``) and why it was not accepted (module
    docstring); largest ``of_remaining`` first."""
    latest: dict[str, RankedCandidate] = {}
    for row in ranking:
        names = row.effect.split("+")
        new = names[-1]
        if row.status == "failed" or new in accepted or sorted(names[:-1]) != sorted(accepted):
            continue
        if (row.reduction_over_previous or 0.0) < MIN_SHARE:
            continue
        if new not in latest or row.step > latest[new].step:
            latest[new] = row
    rows = sorted(latest.values(), key=lambda row: -(row.reduction_over_previous or 0.0))[:MAX_CANDIDATES]
    return [
        {
            "effect": row.effect.split("+")[-1],
            "heldout_reduction": row.heldout_reduction,
            "of_remaining": row.reduction_over_previous,
            "why_not": why_not(row, accepted, confusable, limits),
        }
        for row in rows
    ]


def why_not(row: RankedCandidate, accepted: list[str], confusable: list[dict], limits: list[DetectionLimit]) -> str:
    """Why the last effect of ``row`` was not accepted beside ``accepted`` (module docstring)."""
    name = row.effect.split("+")[-1]
    for pair in confusable:
        if name in pair["effects"]:
            other = next((e for e in pair["effects"] if e != name and e in accepted), None)
            if other is not None:
                return f"confused_with:{other}"
    main = CANDIDATES[name].main
    key = f"{name}.{main}" if "+" in row.effect else main
    if key in row.at_bound:
        return "at_bound"
    limit = next((entry for entry in limits if entry.effect == name and entry.param == main), None)
    value = row.params.get(key)
    if limit is not None and isinstance(value, (int, float)) and isinstance(limit.value, (int, float)):
        neutral = CANDIDATES[name].neutral
        if abs(value - neutral) < abs(limit.value - neutral):
            return "below_detection_limit"
    return "evidence"
