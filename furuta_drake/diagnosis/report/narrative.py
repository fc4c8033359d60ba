"""The report in words: the verdict sentence, each accepted effect as a physical statement, the confusable pairs,
the detection limits and what to do next, all read from a ``report.json`` object (nothing is computed here that
the diagnosis did not decide; :mod:`~furuta_drake.diagnosis.formatting` writes the figures).

``report.md`` and ``report.html`` both open on :func:`verdict_sentence`, so a reader of either gets the same
answer first.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from furuta_drake.diagnosis.formatting import ends, number, percent, quantity
from furuta_drake.diagnosis.gap.localize import dominant
from furuta_drake.diagnosis.report.torque import torque_words
from furuta_drake.effects.corrected import rig_entry
from furuta_drake.effects.vocabulary import CANDIDATES, DRIVE_KEYS, UNITS

NOUNS = {
    "arm_coulomb_friction": "Coulomb friction on the arm",
    "arm_viscous_friction": "viscous friction on the arm",
    "arm_stribeck": "breakaway (Stribeck) friction on the arm",
    "friction_asymmetry": "arm friction that differs with the direction",
    "pendulum_friction": "friction on the pendulum joint",
    "encoder_quantization": "a coarser encoder",
    "measurement_noise": "noise on the angles",
    "input_delay": "a delay of the command",
    "torque_gain_error": "a torque gain error",
    "actuator_deadzone": "a dead zone of the drive",
    "actuator_lag": "a lag of the drive",
    "actuator_saturation": "a saturation of the drive",
    "arm_spring": "a spring on the arm",
    "inertia_mismatch": "wrong inertias in the rig file",
    "drive_backlash": "backlash in the drive",
    "drive_compliance": "an elastic drive",
}
SCALES = {  # inertia_mismatch's scales: what each one scales in the rig file
    "arm_inertia_scale": "the arm's inertia",
    "pendulum_inertia_scale": "the pendulum's inertia",
    "coupling_scale": "the arm-pendulum coupling m l r",
    "gravity_scale": "the pendulum's gravity torque m g l",
}
SENSOR_EFFECTS = frozenset(name for name, candidate in CANDIDATES.items() if not candidate.fit)
NOTABLE_SCALE = 0.05  # an inertia scale further than this from 1 is stated beside the main one
NEVER_SEEN = "the fit never saw"
DESIGN_COMMAND = "furuta-drake design --diagnosis . --out design"


@dataclass
class Accepted:
    """An accepted effect: its fitted parameters and 95 % intervals in SI units, and its step of the selection."""

    name: str
    params: dict
    intervals: dict = field(default_factory=dict)
    step: dict | None = None


def final_entry(report: dict) -> dict | None:
    """The ranking entry of the model holding exactly the accepted effects that change the predictions (None when
    there is none)."""
    return _entry_of(report, dynamic_effects(report))


def dynamic_effects(report: dict) -> list[str]:
    """The accepted effects that change the predictions (the sensor effects left out)."""
    return [name for name in report.get("effects", []) if name not in SENSOR_EFFECTS]


def _entry_of(report: dict, names: list[str]) -> dict | None:
    """The ranking entry of the model holding exactly ``names`` (None when there is none)."""
    wanted = set(names)
    return next(
        (e for e in report.get("ranking", []) if wanted and set(e["effect"].split("+")) == wanted),
        None,
    )


def accepted_effects(report: dict) -> list[Accepted]:
    """The accepted effects in the report's order, their parameters from the final model's fit (a sensor effect's
    from its own ranking entry)."""
    dynamic = dynamic_effects(report)
    entry = final_entry(report) or {}
    steps = {step["effect"]: step for step in report.get("steps", [])}
    out = []
    for effect in _per_effect(dynamic, entry):
        if not effect.params and effect.name in steps:  # a report without the final entry: the step's own fit
            prefix = f"{effect.name}." if len(dynamic) > 1 else ""
            effect.params = {
                k.split(".")[-1]: v for k, v in steps[effect.name]["params"].items() if k.startswith(prefix)
            }
        effect.step = steps.get(effect.name)
        out.append(effect)
    for name in report.get("effects", []):
        if name in SENSOR_EFFECTS:
            (effect,) = _per_effect([name], _entry_of(report, [name]) or steps.get(name, {}))
            effect.step = steps.get(name)
            out.append(effect)
    return out


def beside_effects(report: dict) -> list[Accepted]:
    """The listed effects kept beside the torque beyond the vocabulary (``beside_torque``), with their parameters
    fitted beside it; none for a report without that key."""
    beside = report.get("beside_torque") or {}
    return _per_effect(beside.get("effects", []), beside)


def _per_effect(names: list[str], fit: dict) -> list[Accepted]:
    """Each of ``names`` with its parameters and intervals from ``fit`` (``params``, ``params_ci``; keys prefixed
    'effect.' when it holds several)."""
    out = []
    for name in names:
        prefix = f"{name}." if len(names) > 1 else ""
        params = {k[len(prefix) :]: v for k, v in fit.get("params", {}).items() if k.startswith(prefix)}
        intervals = {k[len(prefix) :]: v for k, v in fit.get("params_ci", {}).items() if k.startswith(prefix)}
        out.append(Accepted(name, params, intervals))
    return out


def _q(params: dict, key: str, intervals: dict | None) -> str:
    return quantity(params.get(key), UNITS.get(key, ""), interval=(intervals or {}).get(key))


def _interval(intervals: dict | None, key: str, prefix: str = "95 % interval ") -> str:
    interval = (intervals or {}).get(key)
    return f" ({prefix}{' to '.join(ends(*interval, 3))})" if interval else ""


def _ratio(share: float, intervals: dict | None = None, key: str = "", of: str = "") -> str:
    """A scale as words: "about 1.3 times <of>" above 1, "about 12 % less than <of>" below, then its interval."""
    text = f"about {number(share, 2)} times {of}" if share >= 1 else f"about {percent(1 - share)} less than {of}"
    return text + _interval(intervals, key)


def _inertia(p: dict, ci: dict | None, main_only: bool) -> str:
    """The arm's inertia scale as weight ("the arm is about 1.3 times heavier than the rig file says"), then the
    other scales further than ``NOTABLE_SCALE`` from 1 (in short when ``main_only``)."""
    arm = p["arm_inertia_scale"]
    size = f"about {number(arm, 2)} times heavier" if arm >= 1 else f"about {percent(1 - arm)} lighter"
    text = f"the arm is {size} than the rig file says" + _interval(
        ci, "arm_inertia_scale", "inertia scale, 95 % interval "
    )
    notable = [key for key in SCALES if key != "arm_inertia_scale" and key in p and abs(p[key] - 1) > NOTABLE_SCALE]
    if not notable:
        return text
    if main_only:
        sizes = sorted({number(p[key], 2) for key in notable}, key=float)
        span = sizes[0] if len(sizes) == 1 else f"{sizes[0]} to {sizes[-1]}"
        return f"{text} ({_joined([SCALES[key] for key in notable])} about {span} times)"
    return ", ".join(
        [text, *(f"{SCALES[key]} is {_ratio(p[key], ci, key, 'what the rig file says')}" for key in notable)]
    )


STATEMENTS = {
    "inertia_mismatch": _inertia,
    "input_delay": lambda p, ci, _: (
        f"commands reach the arm about {_q(p, 'delay', ci)} late"
        + (f", give or take {_q(p, 'delay_spread', ci)} from sample to sample" if "delay_spread" in p else "")
    ),
    "actuator_lag": lambda p, ci, _: f"the drive follows the command with a lag of about {_q(p, 'time_constant', ci)}",
    "arm_coulomb_friction": lambda p, ci, _: f"the arm's sliding (Coulomb) friction is about {_q(p, 'coulomb', ci)}",
    "arm_viscous_friction": lambda p, ci, _: f"the arm's viscous friction is about {_q(p, 'viscous', ci)}",
    "arm_stribeck": lambda p, ci, _: (
        f"the arm's friction breaks away at about {_q(p, 'static', ci)} and slides at about {_q(p, 'coulomb', ci)}"
    ),
    "friction_asymmetry": lambda p, ci, _: (
        f"the arm's Coulomb friction is about {_q(p, 'coulomb_pos', ci)} moving towards +phi and "
        f"{_q(p, 'coulomb_neg', ci)} towards -phi"
    ),
    "pendulum_friction": lambda p, ci, _: (
        f"the pendulum joint has about {_q(p, 'coulomb', ci)} of Coulomb and {_q(p, 'viscous', ci)} of viscous friction"
    ),
    "encoder_quantization": lambda p, ci, _: f"the encoders resolve only {number(p['counts_per_rev'], 6)} counts/rev",
    "measurement_noise": lambda p, ci, _: (
        f"the angles carry noise of about {_q(p, 'noise_std', ci)}, "
        + (f"low-passed over about {_q(p, 'correlation_time', ci)}" if "correlation_time" in p else "white")
    ),
    "torque_gain_error": lambda p, ci, _: f"the arm gets {_ratio(p['gain'], ci, 'gain', 'the commanded torque')}",
    "actuator_deadzone": lambda p, ci, _: f"commands under about {_q(p, 'deadzone', ci)} do not reach the arm",
    "actuator_saturation": lambda p, ci, _: f"the drive saturates at about {_q(p, 'limit', ci)}",
    "drive_backlash": lambda p, ci, _: (
        f"the drive has a play of about {_q(p, 'backlash', ci)} either way (half its width, arm side): the motor "
        "turns twice that before the arm follows a reversal"
    ),
    "drive_compliance": lambda p, ci, _: (
        f"the drive twists like a spring of about {_q(p, 'stiffness', ci)} damped by {_q(p, 'damping', ci)} "
        "between the motor and the arm"
    ),
    "arm_spring": lambda p, ci, _: (
        f"a spring of about {_q(p, 'stiffness', ci)} pulls the arm towards phi = "
        f"{number(math.degrees(p.get('equilibrium', 0.0)), 2)} deg"
    ),
}


def effect_statement(effect: Accepted, with_intervals: bool = False) -> str:
    """The effect as a physical statement ("commands reach the arm about 8.1 ms late"), the main parameters'
    95 % intervals when asked; the effect's name when its parameters are missing (an old report)."""
    statement = STATEMENTS.get(effect.name)
    try:
        return statement(effect.params, effect.intervals if with_intervals else None, not with_intervals)
    except (KeyError, TypeError):
        return NOUNS.get(effect.name, effect.name)


def _joined(parts: list[str]) -> str:
    return parts[0] if len(parts) == 1 else ", ".join(parts[:-1]) + " and " + parts[-1]


def _capital(text: str) -> str:
    return text[:1].upper() + text[1:]


def verdict_sentence(report: dict) -> str:
    """The answer in one plain sentence with its strength: what the logs show and how much of the held-out gap
    the accepted effects remove; for an unexplained gap with a kept torque, that torque and the listed effects
    fitted beside it."""
    gap = report["gap"]
    nominal = number(gap["nominal"]["heldout"], 2)
    effects = accepted_effects(report)
    if report["verdict"] == "none":
        return (
            f"The rig file's model already predicts the logs {NEVER_SEEN} to within their noise (held-out gap "
            f"{nominal} counts above the encoder noise): no unmodelled effect is needed."
        )
    if report["verdict"] == "unexplained" and report.get("unmodelled_torque"):
        return (
            f"The rig file's model misses these logs (held-out gap {nominal} counts) by a torque no effect of the "
            f"vocabulary holds: {_beside_torque(report)}."
        )
    if report["verdict"] == "unexplained":
        return (
            f"The rig file's model misses these logs (held-out gap {nominal} counts) in a way no effect of the "
            f"vocabulary explains: {_best_attempt(report, effects)} of the gap on logs {NEVER_SEEN}."
        )
    dynamic = [e for e in effects if e.name not in SENSOR_EFFECTS]
    sensors = [e for e in effects if e.name in SENSOR_EFFECTS]
    statements = _capital(_joined([effect_statement(e) for e in dynamic + sensors]))
    return f"{statements}; {_explained(report, dynamic, sensors)}."


def _explained(report: dict, dynamic: list[Accepted], sensors: list[Accepted]) -> str:
    """How much of the held-out gap the accepted effects' predictions remove, and apart from it how much of what
    is left the accepted sensor effects account for."""
    gap = report["gap"]
    lower, reduction = (final_entry(report) or {}).get("evidence"), gap["heldout_reduction"]
    text = ""
    if dynamic:
        strength = ""
        if lower is not None:  # the bound is the selection's (surrogate) figure; the headline the Drake replay's
            strength = (
                f" (at least {percent(lower)} with 95 % confidence)"
                if reduction is not None and lower <= reduction
                else f" (bootstrap lower bound {percent(lower)})"
            )
        owner = "this removes" if len(dynamic) == 1 else "together they remove"
        if sensors:
            owner = "the predictions of " + ("it" if len(dynamic) == 1 else "them") + " remove"
        text = f"{owner} {percent(reduction)} of the gap on logs {NEVER_SEEN}{strength}"
    if not sensors:
        return text
    left = (1.0 - (reduction or 0.0)) ** 2
    share = (gap.get("sensor_share") or 0.0) / max(left, 1e-12)
    noun = "the sensor" if len(sensors) == 1 else "the sensor effects"
    if not dynamic:
        return (
            f"no effect changes the rig file's predictions (held-out gap {number(gap['nominal']['heldout'], 2)} "
            f"counts), and {noun} account{'s' if len(sensors) == 1 else ''} for {percent(share)} of it, read from "
            f"the residuals' fastest part on logs {NEVER_SEEN}"
        )
    return f"{text}, and {noun} account{'s' if len(sensors) == 1 else ''} for {percent(share)} of what is left"


def _beside_torque(report: dict) -> str:
    """The kept torque in words (:func:`~.torque_report.torque_words`), the listed effects fitted beside it with
    their values, and how much of the gap they remove together; without effects beside it, the best candidate."""
    torques = []
    for joint, entry in report["unmodelled_torque"].items():
        words, kind = torque_words(joint, entry)
        torques.append(f"{words} ({kind})" if kind else words)
    text = _joined(torques)
    beside, effects = report.get("beside_torque") or {}, beside_effects(report)
    if not effects:
        reduction = next(iter(report["unmodelled_torque"].values())).get("heldout_reduction")
        best = _best_attempt(report, [])
        return f"{text}; it removes {percent(reduction)} of the gap on logs {NEVER_SEEN}, where {best}"
    return (
        f"{text}, and beside it {_joined([effect_statement(e) for e in effects])}; together they remove "
        f"{percent(beside.get('heldout_reduction'))} of the gap on logs {NEVER_SEEN}, the listed "
        f"{'effects' if len(effects) > 1 else 'effect'} alone {percent(beside_alone(report))}"
    )


def beside_alone(report: dict) -> float | None:
    """The held-out reduction of the listed effects kept beside the torque, without it (their ranking entry's)."""
    entry = _entry_of(report, (report.get("beside_torque") or {}).get("effects", []))
    return (entry or {}).get("heldout_reduction")


def _best_attempt(report: dict, effects: list[Accepted]) -> str:
    """What came closest for an unexplained gap: the accepted effects, else the best candidate tried."""
    if effects:
        found = _joined([effect_statement(e) for e in effects])
        return f"the accepted effects ({found}) remove only {percent(report['gap']['heldout_reduction'])}"
    best = next((e for e in report.get("ranking", []) if e.get("status", "ok") == "ok"), None)
    if best is None:
        return "no candidate could be fitted to remove any"
    names = [NOUNS.get(name, name) for name in best["effect"].split("+")]
    return f"the best candidate tried ({_joined(names)}) removes only {percent(best['heldout_reduction'])}"


def where_sentence(localization: dict) -> str:
    """Where the gap is: the signal holding most of it, the most over-represented regime and the largest band
    (:func:`~furuta_drake.diagnosis.gap.localize.dominant`)."""
    where = dominant(localization)
    if where["signal"] is None:
        return ""
    return f"Most of the gap is in {where['signal']} ({percent(where['signal_share'])})" + _where_details(where) + "."


WHY_NOT = {
    "evidence": "its evidence was too weak",
    "at_bound": "its fit ran to the end of its range",
    "below_detection_limit": "its fitted size is below what these logs detect",
}


def remaining_sentences(report: dict) -> list[str]:
    """What the accepted effects leave (``report["remaining"]``), in words: its share and size, where it sits and
    the effects that could still take part of it with why each was not accepted; [] when nothing is left."""
    left = report.get("remaining")
    if not left:
        return []
    sizes = ", ".join(f"{name} {number(value, 2)}" for name, value in left["rms_counts"].items() if value is not None)
    where = left["where"]
    text = f"What remains: {percent(left['share'])} of the nominal held-out gap ({sizes} counts)"
    if where["signal"] is not None:
        text += f", mostly in {where['signal']} ({percent(where['signal_share'])})" + _where_details(where)
    sentences = [text + "."]
    named = []
    for candidate in left["candidates"]:
        why = candidate["why_not"]
        reason = (
            f"confusable with {why.split(':', 1)[1]}" if why.startswith("confused_with:") else WHY_NOT.get(why, why)
        )
        named.append(f"{candidate['effect']} ({percent(candidate['of_remaining'])} of it; {reason})")
    if named:
        sentences.append("Effects that could still take part of it: " + "; ".join(named) + ".")
    return sentences


def disturbance_sentence(report: dict) -> str:
    """The rig's disturbance (``report["disturbance"]``) in words: what the corrected model still misses on the
    held-out logs as an arm torque ('' without one)."""
    disturbance = report.get("disturbance")
    if not disturbance:
        return ""
    low, high = disturbance["ci"] or (None, None)
    interval = f" (95 % interval {number(1e3 * low, 2)} to {number(1e3 * high, 2)})" if low is not None else ""
    return (
        f"Read as a torque on the arm, what the corrected model still misses on the held-out logs is "
        f"{number(1e3 * disturbance['arm_torque_rms'], 2)} mN m RMS{interval}, 90 % of its power below "
        f"{number(disturbance['bandwidth_hz'], 2)} Hz: the rig's disturbance, which fitted_rig.yaml carries and tune "
        "designs against."
    )


def _where_details(where: dict) -> str:
    """The regime and band clauses of a :func:`~furuta_drake.diagnosis.gap.localize.dominant` record."""
    text = ""
    if where["regime"] is not None:
        text += (
            f"; {percent(where['regime_share'])} of it comes {_regime_phrase(where['regime'])}, which is "
            f"{percent(where['regime_samples'])} of the samples"
        )
    if where["band_hz"] is not None:
        low, high = where["band_hz"]
        text += f"; the {number(low)}-{number(high)} Hz band holds {percent(where['band_share'])}"
    return text


def _regime_phrase(regime: str) -> str:
    return {"upright": "with the pendulum upright", "hanging": "with the pendulum hanging"}.get(
        regime, f"in the {regime} regime" if regime != "swinging" else "while the pendulum swings"
    )


def confusable_sentences(report: dict) -> list[str]:
    """Each confusable pair in words."""
    return [
        f"These logs cannot tell {NOUNS.get(a, a)} from {NOUNS.get(b, b)}: {pair['why']}."
        for pair in report.get("confusable", [])
        for a, b in [pair["effects"]]
    ]


def look_alike_sentences(report: dict) -> list[str]:
    """Each accepted effect's look-alikes (the vocabulary's ``look_alike``) in words, with what the other removes of
    the gap on its own when the ranking has it; a pair the report already names confusable is left to that."""
    named = {frozenset(pair["effects"]) for pair in report.get("confusable", [])}
    ranking = {entry["effect"]: entry for entry in report.get("ranking", [])}
    out = []
    for name in report.get("effects", []):
        for other, why in CANDIDATES[name].look_alike if name in CANDIDATES else ():
            if frozenset((name, other)) in named:
                continue
            entry = ranking.get(other)
            alone = (
                f"; on its own {NOUNS.get(other, other)} removes {percent(entry['heldout_reduction'])} of the gap on "
                f"logs {NEVER_SEEN}, against {percent(ranking[name]['heldout_reduction'])}"
                if entry and entry.get("heldout_reduction") is not None and name in ranking
                else ""
            )
            out.append(f"{_capital(NOUNS.get(name, name))} can look like {NOUNS.get(other, other)}: {why}{alone}.")
    return out


REVERSAL_SHARE = 2.0  # the gap is "at velocity reversals" when their share of it is this many times their samples'


def reversal_sentence(report: dict) -> str:
    """For a gap that no effect nor a torque of the state explains and that concentrates at the arm's velocity
    reversals (their share of it at least ``REVERSAL_SHARE`` times their share of the samples), that in words: what
    acts there only ('' otherwise)."""
    if report["verdict"] != "unexplained" or report.get("unmodelled_torque"):
        return ""
    regimes = (report.get("localization") or {}).get("regimes", [])
    reversal = next((r for r in regimes if r.get("regime") == "arm velocity reversal"), None)
    if not reversal or not reversal.get("share_of_samples") or reversal.get("share_of_gap") is None:
        return ""
    if reversal["share_of_gap"] < REVERSAL_SHARE * reversal["share_of_samples"]:
        return ""
    tried = {name for entry in report.get("ranking", []) for name in entry["effect"].split("+")}
    drive = (
        "backlash in the drive or friction of another law than the vocabulary's"
        if "drive_backlash" in tried
        else "backlash in the drive (state the drive's gear_ratio and rotor_inertia in the rig file's drive: section, "
        "and the diagnosis fits its play) or friction of another law than the vocabulary's"
    )
    return (
        f"The gap concentrates at the arm's velocity reversals ({percent(reversal['share_of_gap'])} of it in "
        f"{percent(reversal['share_of_samples'])} of the samples) and no torque of the state explains it: something "
        f"acts as the arm turns back, such as {drive}"
    )


def consistency_sentence(report: dict) -> str:
    """The decision repeated on splits of the logs, in words ('' when ``--folds`` did not run)."""
    consistency = report.get("consistency")
    if not consistency:
        return ""
    same = consistency["verdicts"].count(report["verdict"])
    return (
        f"Repeated on {consistency['folds']} splits of the logs, the same verdict came back {same} times "
        f"({consistency['judgement']})."
    )


def trust_sentences(report: dict) -> list[str]:
    """How far to trust the verdict: the folds' consistency and the confusable pairs, or what would tell."""
    sentences = [
        s for s in [consistency_sentence(report), *confusable_sentences(report), *look_alike_sentences(report)] if s
    ]
    if sentences:
        return sentences
    folds = "run with --folds K to repeat the decision on K splits of the logs."
    return [
        f"No other effect explains the held-out data as well; {folds}" if report.get("effects") else _capital(folds)
    ]


def limit_sentence(limit: dict) -> str:
    """What a detection limit means: the largest size of the effect that could hide in these logs."""
    name, value, param = limit["effect"], limit["value"], limit["param"]
    noun = NOUNS.get(name, name)
    if value is None:
        return f"{_capital(noun)} of any size tried could hide here (not detected at any size)"
    if param == "gain" or param.endswith("_scale"):
        return f"{_capital(noun)} within {percent(abs(value - 1), 1)} of 1 could hide here"
    if param == "limit":
        return f"A saturation of the drive above {quantity(value, limit['unit'])} could hide here"
    if name == "drive_compliance":  # the softer the drive, the larger its effect
        return f"An elastic drive stiffer than {quantity(value, limit['unit'])} could hide here"
    if param == "counts_per_rev":
        return f"An encoder finer than {number(value, 6)} counts/rev could hide here"
    return f"{_capital(noun)} under {quantity(value, limit['unit'])} could hide here"


def rig_line(effect: Accepted) -> str:
    """The line the effect adds under ``effects:`` in the rig file (as ``fitted_rig.yaml`` holds it); a drive's
    effect, the keys it sets in the ``drive:`` section."""
    if effect.name in DRIVE_KEYS:
        keys = [key for key in DRIVE_KEYS[effect.name] if key in effect.params]
        return "drive: {" + ", ".join(f"{key}: {number(effect.params[key], 6)}" for key in keys) + "}"
    try:
        entry = rig_entry(effect.name, effect.params)
    except (KeyError, ValueError):
        return f"{effect.name}: (see fitted_rig.yaml)"
    values = ", ".join(f"{k}: {v if isinstance(v, str) else number(v, 6)}" for k, v in entry.items())
    return f"{effect.name}: {{{values}}}"


def undetectable(report: dict) -> list[str]:
    """The effects these logs could not detect at any size tried."""
    return [limit["effect"] for limit in report.get("detection_limits", []) if limit["value"] is None]


def next_steps(report: dict) -> list[tuple[str, str]]:
    """What to do next: (what and why, the command to run from the report's folder)."""
    steps = []
    if report.get("effects") or report.get("unmodelled_torque"):
        steps.append(
            (
                f"Continue from the fitted rig file ({_held_in_rig(report)}): diagnose "
                "new logs against it, so a further effect need not compete with these",
                "furuta-drake diagnose --rig fitted_rig.yaml --train NEW_TRAIN.csv --heldout NEW_HELDOUT.csv "
                "--out next-diagnosis",
            )
        )
        steps.append(("Simulate the corrected model", "furuta-drake simulate --config fitted_model.yaml"))
    hidden, pairs = undetectable(report), report.get("confusable", [])
    if pairs or hidden:
        why = [f"separate {NOUNS.get(a, a)} from {NOUNS.get(b, b)}" for a, b in (p["effects"] for p in pairs)]
        why += [f"make {NOUNS.get(name, name)} detectable" for name in hidden]
        steps.append((f"Design the experiment that would {_joined(why)}", DESIGN_COMMAND))
    if report["verdict"] == "unexplained":
        reversal = reversal_sentence(report)
        steps.append(
            (
                (reversal + ". " if reversal else "")
                + "The gap is not an effect of the vocabulary: check the rig file's constants on the bench (the "
                "hanging swing period), then look where the gap is left (below) for the missing physics",
                "furuta-drake rig --check RIG.yaml",
            )
        )
    if report["verdict"] == "none":
        steps.append(("Nothing to add to the rig file; the detection limits below say what could still hide", ""))
        steps += _smaller_target(report)
    return steps


def _held_in_rig(report: dict) -> str:
    """What ``fitted_rig.yaml`` holds beyond the rig file: the accepted effects (else those fitted beside the kept
    torque) and the torque beyond the vocabulary."""
    held = []
    if report.get("effects"):
        drive = any(name in DRIVE_KEYS for name in report["effects"])
        held.append("the accepted effects are in its effects: section" + (" (the drive's in drive:)" if drive else ""))
    elif beside_effects(report):
        held.append("the effects fitted beside the torque are in its effects: section")
    if report.get("unmodelled_torque"):
        held.append("the torque beyond the vocabulary is in its unmodelled_torque: section")
    return ", ".join(held)


def _smaller_target(report: dict) -> list[tuple[str, str]]:
    """A design that would detect the first additive effect at half its detection limit (none when there is none)."""
    sizes = [
        limit
        for limit in report.get("detection_limits", [])
        if limit["value"] is not None and limit["unit"] in ("N m", "s", "N m s/rad")
    ]
    if not sizes:
        return []
    limit = sizes[0]
    half = limit["value"] / 2
    return [
        (
            f"To look below the limits, design the experiment that would detect {NOUNS.get(limit['effect'])} of "
            f"{quantity(half, limit['unit'])}, half its limit here",
            f"{DESIGN_COMMAND} --target {limit['effect']}={number(half, 3)}",
        )
    ]
