"""The report's tables as plain text cells, one definition for ``report.md`` and ``report.html``: the accepted
effects, one row per accepted step, the candidate ranking (the best of each step and the rest), the worst time
windows and the rule's constants. Each function returns ``(header, rows)``; the writers only lay them out."""

from __future__ import annotations

from furuta_drake.diagnosis.formatting import interval_text, number, percent, quantity, seconds_range
from furuta_drake.diagnosis.report import narrative
from furuta_drake.diagnosis.report.torque import torque_sentence
from furuta_drake.diagnosis.selection.rule import THRESHOLDS
from furuta_drake.effects.vocabulary import UNITS

TOP_PER_STEP = 3  # ranking entries shown per step; the rest are folded
Table = tuple[list[str], list[list[str]]]


def effects_table(report: dict) -> Table:
    """One row per accepted effect: its name, the physical statement with intervals, what it brings beside the
    others, its rig-file line."""
    rows = []
    for effect in narrative.accepted_effects(report):
        step = effect.step or {}
        brings = (
            f"{percent(step['reduction_over_others'])} (at least {percent(step.get('evidence_over_others'))})"
            if step.get("reduction_over_others") is not None
            else ""
        )
        rows.append(
            [effect.name, narrative.effect_statement(effect, with_intervals=True), brings, narrative.rig_line(effect)]
        )
    return ["effect", "what it is (95 % interval)", "gap it removes beside the others", "rig file line"], rows


def beside_table(report: dict) -> Table:
    """One row per listed effect kept beside the torque beyond the vocabulary: its name, the physical statement
    with intervals, its rig-file line; no rows when the report has none or accepts them (the accepted effects'
    table then shows them)."""
    effects = [] if report.get("effects") else narrative.beside_effects(report)
    rows = [[e.name, narrative.effect_statement(e, with_intervals=True), narrative.rig_line(e)] for e in effects]
    return ["effect", "what it is (95 % interval)", "rig file line"], rows


def beside_sentence(report: dict) -> str:
    """What the listed effects fitted beside the torque remove, with it and alone."""
    return (
        f"Fitted beside the torque beyond the vocabulary; with it they remove "
        f"{percent(report['beside_torque'].get('heldout_reduction'))} of the held-out gap, alone "
        f"{percent(narrative.beside_alone(report))}. fitted_rig.yaml holds these lines and the torque."
    )


def steps_table(report: dict) -> Table:
    """One row per accepted step: the held-out gap and the reductions over nominal, the step before, the others."""
    rows = [
        [
            str(i),
            step["effect"],
            number(step["heldout_gap"]),
            percent(step["heldout_reduction"], 1),
            percent(step.get("reduction_over_previous"), 1),
            f"{percent(step.get('reduction_over_others'), 1)} [{percent(step.get('evidence_over_others'), 1)}]",
        ]
        for i, step in enumerate(report.get("steps", []), 1)
    ]
    header = [
        "step",
        "effect",
        "held-out gap [counts]",
        "less than nominal",
        "less than the step before",
        "brings beside the others [5 % bound]",
    ]
    return header, rows


RANKING_HEADER = [
    "step",
    "effect added",
    "its parameters: value [95 % interval]",
    "held-out gap [counts]",
    "less than nominal",
    "less than the step before [5 % bound]",
]


def ranking_tables(report: dict) -> tuple[Table, Table, list[str], list[str]]:
    """(the best ``TOP_PER_STEP`` candidates of each step, the others, the failed ones and those a step's screen
    left behind, each as "effect: reason")."""
    shown, folded = [], []
    for entry in (e for e in report.get("ranking", []) if e.get("status", "ok") == "ok"):
        same_step = sum(e.get("step", 1) == entry.get("step", 1) for e in shown)
        (shown if same_step < TOP_PER_STEP else folded).append(entry)
    failed, screened = (
        [f"{e['effect']}: {e.get('reason', '')}" for e in report.get("ranking", []) if e.get("status") == status]
        for status in ("failed", "screened")
    )
    rows = [_ranking_row(e) for e in shown], [_ranking_row(e) for e in folded]
    return (RANKING_HEADER, rows[0]), (RANKING_HEADER, rows[1]), failed, screened


def _ranking_row(entry: dict) -> list[str]:
    """A candidate as the effect its step added, that effect's parameters with units, and its reductions."""
    added = entry["effect"].split("+")[-1]
    prefix = f"{added}." if "+" in entry["effect"] else ""
    intervals, bounds = entry.get("params_ci", {}), entry.get("at_bound", {})
    params = [
        f"{key[len(prefix) :]} = "
        + (value if isinstance(value, str) else _param(key, value, intervals.get(key), bounds.get(key)))
        for key, value in entry["params"].items()
        if key.startswith(prefix)
    ]
    over_previous = entry.get("reduction_over_previous", entry["heldout_reduction"])
    bound = entry.get("evidence_over_previous", entry.get("evidence"))
    last = f"{percent(over_previous, 1)} [{percent(bound, 1)}]"
    if entry.get("score_gain") is not None:  # a sensor effect: it changes no prediction, its score tells
        params.append(f"score {number(entry['score_gain'])} nats/window [5 % bound {number(entry['score_evidence'])}]")
        last = f"none: the sensor, {percent(entry.get('sensor_share'), 1)} of the gap's square"
    return [
        str(entry.get("step", 1)),
        added,
        "; ".join(params),
        number(entry["heldout_gap"]),
        percent(entry["heldout_reduction"], 1),
        last,
    ]


def _param(key: str, value, interval, at_bound: str | None = None) -> str:
    unit = UNITS.get(key.split(".")[-1], "")
    if at_bound:
        return quantity(value, unit, digits=3) + f" (at the {at_bound} end of its range)"
    return quantity(value, unit, digits=3) + (f" [{interval_text(interval, unit)}]" if interval else "")


def windows_table(localization: dict) -> Table:
    """The worst time windows of the rig file's model, worst first."""
    rows = [
        [w["log"], seconds_range(w["start"], w["end"]), percent(w.get("share_of_gap"), 1), w["why"]]
        for w in localization.get("windows", [])
    ]
    return ["log", "time", "share of the gap", "why"], rows


def rule_table() -> Table:
    """The acceptance rule's constants (imported from the selection's code) and what each decides."""
    shown = {"counts": lambda v: f"{v} counts", "factor": lambda v: f"{v:g}x", "": percent}
    rows = [[t.name, shown[t.unit](t.value), t.meaning] for t in THRESHOLDS]
    return ["constant", "value", "what it decides"], rows


def unmodelled_table(fit: dict) -> Table:
    """The terms of an unmodelled-torque fit with their 95 % intervals."""
    rows = [[t["term"], number(t["coefficient"]), interval_text(t.get("ci"))] for t in fit.get("terms", [])]
    return ["term", "coefficient", "95 % interval"], rows


def unmodelled_sentence(joint: str, fit: dict) -> str:
    """What an unmodelled-torque fit says: its size, leading term and kind (:func:`torque_sentence`), and how far
    the final model with it reduces the nominal held-out gap."""
    return (
        f"{torque_sentence(joint, fit)} With it the final model reduces the nominal held-out gap by "
        f"{percent(fit.get('heldout_reduction'))}."
    )
