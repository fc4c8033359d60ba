"""The hypotheses an experiment should separate, read from a diagnosis' report.

Every hypothesis is a complete model of the rig: the rig file's nominal model with a set of effects at their
fitted parameters (``ranking[].params``). The accepted model holds the accepted steps. Its rivals:

- **confusable** pairs and the models **within** ``NEAR`` of the accepted one's held-out reduction at the same
  step, of the gap the earlier effects leave (variants of the accepted law too: the rule's parsimony chooses among
  them on a few points): the accepted model with that step's effect replaced by the rival's (its parameters from
  its fit at that step; the other effects keep the accepted values);
- **next-step** models: the candidates of the step after the last accepted one that reduce what is left by at
  least ``NEXT_STEP_REDUCTION`` on held-out data without being accepted (at most ``MAX_NEXT_STEP``), as the
  accepted model plus that effect: was a further effect missed?
- with ``--target effect=value`` instead: the accepted model plus that effect at that size (its main parameter,
  in the units of ``detection_limits``), for effects whose detection limit in these logs is above the size;
  ``--target unmodelled_torque=SIZE``: the accepted model plus the diagnosis' unmodelled torque scaled to an RMS
  of SIZE [N m] along its train logs (:mod:`~furuta_drake.design.torque_hypothesis`);
- with no rival and no target (the verdict limited by what the logs can see): the targets of
  :func:`~furuta_drake.design.closed_loop.limited_targets`, every actuator effect not accepted whose
  detection limit is above a size that changes the rig's LQR loop.

A torque the diagnosis kept beyond the vocabulary is in every hypothesis (its coefficients refit like an effect's
parameters), unless it is the target. Each rival forms a :class:`Pair` with the accepted model. A pair is
*nested* when the rival is the accepted model plus one effect: an experiment can only show that the effect is
there (if the accepted model were the truth, the rival's fit would set the effect to nothing), so only the rival
as the truth is informative.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from furuta_drake.design.closed_loop import CLOSED_LOOP_SHARE, closed_loop_sizes, limited_targets
from furuta_drake.design.rollout import nominal_lqr_gain
from furuta_drake.design.torque_hypothesis import TORQUE, apply_hypothesis, report_torque, scaled_torque
from furuta_drake.diagnosis.selection.detection import INJECTIONS
from furuta_drake.diagnosis.selection.fit import scales_of
from furuta_drake.diagnosis.selection.rule import NEAR
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import CANDIDATES, Effect, law_of, rig_model
from furuta_drake.errors import ConfigError

NEXT_STEP_REDUCTION = 0.1  # a next-step candidate that reduces what is left by this much is a rival
MAX_NEXT_STEP = 3


@dataclass(frozen=True)
class Hypothesis:
    """A complete model: the nominal model with ``effects`` (applied in order)."""

    name: str  # the effects joined by "+" ("nominal" without any)
    effects: dict[str, Effect]
    model: Model
    role: str  # "accepted", "rival" or "target"


@dataclass(frozen=True)
class Pair:
    """Two hypotheses (indices into the hypothesis list) the experiment should separate.

    ``step``: the diagnosis step at which they differ; ``previous``: the effects of the model they are both judged
    against there (the held-out rule's reference); ``new``: the effect each adds at that step ("" for none).
    """

    first: int
    second: int
    step: int
    previous: dict[str, Effect]
    new: tuple[str, str]
    why: str
    nested: bool


@dataclass(frozen=True)
class Hypotheses:
    """The hypotheses (the accepted one first), the pairs to separate and notes on targets left out."""

    nominal: Model  # the rig file's model every hypothesis is built on
    hypotheses: list[Hypothesis]
    pairs: list[Pair]
    notes: list[str]


def entry_effects(entry: dict) -> dict[str, Effect]:
    """The effects of a ranking entry from its ``effect`` ("a" or "a+b") and ``params`` (prefixed "a." when
    it holds several)."""
    from furuta_drake.effects.vocabulary import effect_from_params

    names = entry["effect"].split("+")
    out = {}
    for name in names:
        prefix = f"{name}." if len(names) > 1 else ""
        params = {key[len(prefix) :]: value for key, value in entry["params"].items() if key.startswith(prefix)}
        out[name] = effect_from_params(name, params)
    return out


def parse_target(text: str) -> tuple[str, float]:
    """``effect=value`` of ``--target``; ConfigError naming the flag."""
    name, sep, value = text.partition("=")
    if not sep:
        raise ConfigError(f"--target {text!r}: expected effect=value (e.g. actuator_lag=0.005)")
    name = name.strip()
    if name not in CANDIDATES and name != TORQUE:
        raise ConfigError(f"--target {text!r}: unknown effect {name!r} (the vocabulary: {', '.join(CANDIDATES)})")
    if name not in INJECTIONS and name != TORQUE:
        raise ConfigError(f"--target {text!r}: {name} is a sensor effect; no command changes how well a log shows it")
    try:
        size = float(value)
    except ValueError:
        raise ConfigError(f"--target {text!r}: {value!r} is not a number") from None
    if not size > 0 or size != size or size == float("inf"):
        raise ConfigError(f"--target {text!r}: the size must be a positive number")
    return name, size


def read_hypotheses(report: dict, rig, train_logs, targets: list[tuple[str, float]] = ()) -> Hypotheses:
    """The hypotheses and pairs of ``report`` (module docstring); ``train_logs`` set the scales of a target's
    size. ConfigError when a target is already accepted or when nothing is left to separate."""
    nominal = rig_model(rig)
    ranked = [entry for entry in report["ranking"] if entry.get("status", "ok") == "ok"]
    steps = [step["effect"] for step in report["steps"]]
    final = _entry(ranked, steps, len(steps)) if steps else None
    torque = report_torque(report)
    carried = {TORQUE: torque} if torque is not None and TORQUE not in dict(targets) else {}
    accepted = {**(entry_effects(final) if final else {}), **carried}
    hypothesis = Hypothesis(_name(accepted), accepted, apply_hypothesis(nominal, accepted), "accepted")
    rivals = _Rivals(nominal, accepted, steps, [hypothesis], carried, torque)
    notes = []
    if targets:
        notes = _add_targets(rivals, report, train_logs, targets)
    else:
        _add_confusable(rivals, report, ranked)
        _add_within_near(rivals, ranked)
        _add_next_step(rivals, ranked)
    pairs = rivals.pairs
    limited = _limits_that_matter(report, rig, train_logs) if not pairs and not targets else None
    if limited is not None:  # the verdict is limited by what the logs can see, not by a rival
        return limited
    if not pairs:
        raise ConfigError(
            "nothing to separate: the diagnosis has no confusable pair, no rival within "
            f"{NEAR:.0%} of the accepted model and no next-step candidate; name an effect and a size "
            "with --target effect=value"
            if not targets
            else "nothing to separate: every --target is already detected by the diagnosis' logs"
        )
    return Hypotheses(nominal, rivals.hypotheses, pairs, notes)


@dataclass
class _Rivals:
    """The hypotheses read so far (the accepted one first) and each one's pair with the accepted model."""

    nominal: Model
    accepted: dict[str, Effect]
    steps: list[str]  # the accepted effects in the order of their steps
    hypotheses: list[Hypothesis]
    carried: dict[str, Effect]  # the diagnosis' torque, in every hypothesis when it is not the target
    torque: Effect | None  # the diagnosis' torque
    pairs: list[Pair] = field(default_factory=list)

    def add(self, effects: dict[str, Effect], role: str, step: int, new: tuple[str, str], why: str, nested: bool):
        """Add the model of ``effects`` (and the carried torque) paired with the accepted one at ``step``, unless
        it is already held."""
        effects = {**effects, **self.carried}
        name = _name(effects)
        if any(h.name == name for h in self.hypotheses):
            return
        self.hypotheses.append(Hypothesis(name, effects, apply_hypothesis(self.nominal, effects), role))
        previous = {**{k: self.accepted[k] for k in self.steps[: step - 1]}, **self.carried}
        self.pairs.append(Pair(0, len(self.hypotheses) - 1, step, previous, new, why, nested))


def _add_targets(rivals: _Rivals, report: dict, train_logs, targets: list[tuple[str, float]]) -> list[str]:
    """Add the accepted model plus each ``--target`` effect at its size below the detection limit; returns notes
    on the targets the logs already detect. ConfigError when a target is already accepted."""
    accepted, steps, notes = rivals.accepted, rivals.steps, []
    limits = {limit["effect"]: limit for limit in report["detection_limits"]}
    scales = scales_of(train_logs, rivals.nominal)
    for name, size in targets:
        if name == TORQUE:
            _add_torque_target(rivals, size, train_logs)
            continue
        if name in accepted or law_of(name) & set(accepted):
            raise ConfigError(
                f"--target {name}={size:g}: the diagnosis already accepted {name} (or a variant of its law)"
            )
        effect, increment = _target_effect(name, size, scales, rivals.hypotheses[0].model)
        limit = limits.get(name, {}).get("value")
        if limit is not None and _target_effect(name, limit, scales, rivals.hypotheses[0].model)[1] <= increment:
            notes.append(
                f"--target {name}={size:g}: these logs already detect it (detection limit {limit:.4g} "
                f"{INJECTIONS[name].param}); no experiment is needed for it"
            )
            continue
        rivals.add(
            {**accepted, name: effect},
            "target",
            len(steps) + 1,
            ("", name),
            f"{name} at {INJECTIONS[name].param} = {size:g}, below what these logs detect "
            f"({'not detected at any size' if limit is None else f'limit {limit:.4g}'})",
            nested=True,
        )
    return notes


def _add_torque_target(rivals: _Rivals, size: float, train_logs) -> None:
    """Add the accepted model plus the diagnosis' torque scaled to an RMS of ``size`` [N m] along ``train_logs``.
    ConfigError when the diagnosis kept no torque."""
    if rivals.torque is None:
        raise ConfigError(f"--target {TORQUE}={size:g}: the diagnosis kept no unmodelled torque to target")
    rivals.add(
        {**rivals.accepted, TORQUE: scaled_torque(rivals.torque, size, train_logs)},
        "target",
        len(rivals.steps) + 1,
        ("", TORQUE),
        f"the unmodelled torque at an RMS of {size:g} N m along the diagnosis' train logs",
        nested=True,
    )


def _add_confusable(rivals: _Rivals, report: dict, ranked: list[dict]) -> None:
    """Add the rival of each confusable pair of ``report``: the accepted model with the chosen effect's step
    replaced by the other effect's fit at that step."""
    steps = rivals.steps
    chosen_at = {k + 1: name for k, name in enumerate(steps)}
    for pair in report.get("confusable", []):
        chosen, other = pair["effects"]
        step = next((k for k, name in chosen_at.items() if name == chosen), None)
        entry = _entry(ranked, steps[: step - 1] + [other], step) if step else None
        if entry is not None:
            rivals.add(
                _rival(rivals.accepted, steps, step, entry),
                "rival",
                step,
                (chosen, other),
                f"confusable at step {step}: {pair['why']}",
                nested=False,
            )


def _add_within_near(rivals: _Rivals, ranked: list[dict]) -> None:
    """Add, at every accepted step, the rivals whose held-out reduction of the gap the earlier effects leave is
    within ``NEAR`` of the chosen effect's (over the nominal model, every candidate of a late step is within it of
    the chosen one, the earlier effects having closed most of the gap: one that adds nothing would be a rival no
    experiment can show)."""
    steps = rivals.steps
    for step, chosen in {k + 1: name for k, name in enumerate(steps)}.items():
        reference = _entry(ranked, steps[:step], step)
        for entry in ranked if reference else []:
            other = entry["effect"].split("+")[-1]
            if (
                entry["step"] == step
                and other != chosen
                and entry["effect"].split("+")[:-1] == steps[: step - 1]
                and entry["reduction_over_previous"] >= reference["reduction_over_previous"] - NEAR
            ):
                rivals.add(
                    _rival(rivals.accepted, steps, step, entry),
                    "rival",
                    step,
                    (chosen, other),
                    f"at step {step}, {other} reduces the held-out gap the earlier effects leave by "
                    f"{entry['reduction_over_previous']:.1%}, within {NEAR:.0%} of {chosen}'s "
                    f"{reference['reduction_over_previous']:.1%}",
                    nested=False,
                )


def _add_next_step(rivals: _Rivals, ranked: list[dict]) -> None:
    """Add the accepted model plus each of the (at most ``MAX_NEXT_STEP``) next-step candidates that reduce what
    it leaves by at least ``NEXT_STEP_REDUCTION``, largest reduction first."""
    steps = rivals.steps
    following = sorted(
        (
            entry
            for entry in ranked
            if entry["step"] == len(steps) + 1
            and entry["effect"].split("+")[:-1] == steps
            and (entry["reduction_over_previous"] or 0.0) >= NEXT_STEP_REDUCTION
        ),
        key=lambda entry: -entry["reduction_over_previous"],
    )
    for entry in following[:MAX_NEXT_STEP]:
        other = entry["effect"].split("+")[-1]
        rivals.add(
            {**rivals.accepted, other: entry_effects(entry)[other]},
            "rival",
            len(steps) + 1,
            ("", other),
            f"{other} reduces the held-out gap the accepted model leaves by {entry['reduction_over_previous']:.1%}"
            f" without being accepted",
            nested=True,
        )


def _limits_that_matter(report: dict, rig, train_logs) -> Hypotheses | None:
    """The hypotheses of the targets :func:`~furuta_drake.design.closed_loop.limited_targets` finds on
    the rig's LQR, with a note naming them; None when there is none."""
    targets = limited_targets(report, closed_loop_sizes(rig, nominal_lqr_gain(rig)))
    if not targets:
        return None
    found = read_hypotheses(report, rig, train_logs, targets)
    note = (
        "no rival: the design targets the detection limits above a size that changes the closed loop ("
        + ", ".join(f"{name}={size:.4g}" for name, size in targets)
        + f", {CLOSED_LOOP_SHARE:.0%} of the way to the rig's LQR margins)"
    )
    return Hypotheses(found.nominal, found.hypotheses, found.pairs, [note, *found.notes])


def _name(effects: dict[str, Effect]) -> str:
    return "+".join(effects) or "nominal"


def _entry(ranked: list[dict], names: list[str], step: int) -> dict | None:
    """The ranking entry of the model holding ``names`` (in any order; the diagnosis may fit a model again once an
    effect is dropped), preferably the one fitted at ``step``."""
    matches = [entry for entry in ranked if set(entry["effect"].split("+")) == set(names)]
    return next((entry for entry in matches if entry["step"] == step), matches[0] if matches else None)


def _rival(accepted: dict[str, Effect], steps: list[str], step: int, entry: dict) -> dict[str, Effect]:
    """The rival of ``entry`` (a model fitted at ``step``: the earlier accepted effects and another one) as a
    complete model: its own fit, then the effects accepted after ``step`` at their accepted values."""
    return {**entry_effects(entry), **{name: accepted[name] for name in steps[step:]}}


def _target_effect(name: str, size: float, scales, model: Model) -> tuple[Effect, float]:
    """The effect whose main parameter is ``size`` (the value a detection limit states: an increment over the
    model, a gain or inertia scale, or a saturation limit [N m]) and the size of its departure from ``model``
    that the detection limits bisect on."""
    if name in ("torque_gain_error", "inertia_mismatch"):
        increment = size - 1.0
    elif name == "actuator_saturation":
        increment = 1.0 - size / scales.command
    else:
        increment = size
    return INJECTIONS[name].effect(increment, scales, model), abs(increment)
