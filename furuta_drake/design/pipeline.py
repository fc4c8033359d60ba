"""``furuta-drake design`` as one function, :func:`design_experiment`: read a diagnosis -> the hypotheses to
separate -> search the excitation family on the surrogate -> check the best design in Drake under every
hypothesis -> predict what the diagnosis would decide with its log added. ``docs/design.md`` explains every
output.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from furuta_drake.design.choice import MODES, choice_record, chosen
from furuta_drake.design.criterion import Parametrised, experiment_windows, refit_residuals
from furuta_drake.design.family import Family
from furuta_drake.design.hypotheses import Hypotheses, parse_target, read_hypotheses
from furuta_drake.design.inputs import DiagnosisRecord, read_diagnosis
from furuta_drake.design.limits import diagnosis_heldout_windows, predicted_limits, target_sizes
from furuta_drake.design.optimise import (
    SAFETY,
    Bounds,
    EvaluatedDesign,
    Evaluator,
    Search,
    optimise,
)
from furuta_drake.design.predict import RIVAL, TRUTH, predict_direction
from furuta_drake.design.rollout import (
    drake_config,
    nominal_lqr_gain,
    surrogate_closed_loop,
    surrogate_runs,
)
from furuta_drake.design.torque_hypothesis import apply_hypothesis
from furuta_drake.diagnosis.gap.metric import evaluate_gap, window_samples
from furuta_drake.diagnosis.selection.fit import scales_of
from furuta_drake.effects.vocabulary import Scales
from furuta_drake.errors import ConfigError, SimulationDiverged
from furuta_drake.parallel import one_blas_thread
from furuta_drake.simulate import simulate

PENDULUM_BOUND = {"hanging": 0.5, "balancing": 0.2}  # [rad] from hanging or from the upright
DRAKE_RESCALES = 2
SETTLES = 0.8  # a design settles a pair when the rule tells its hypotheses apart in this share of noise draws
REPEATS = (2, 3, 4, 6, 8)  # longer experiments tried for the suggested duration (multiples of it)
AUTO_DURATION = 8.0  # [s] the experiment searched when no duration is given
LIMIT_REPEATS = (1, 2, 4)  # multiples of AUTO_DURATION compared when the design targets detection limits


@dataclass(frozen=True)
class DesignSettings:
    """Sizes and seeds of a design; the defaults are the command's, smaller values trade precision for speed.

    Attributes
    ----------
    generations, population : the cross-entropy search's generations and designs per generation.
    draws : Monte Carlo noise draws of the predicted outcome.
    bootstrap : paired resamples of the held-out windows in each draw (the diagnosis' rule).
    refit_iterations : Gauss-Newton steps of the refits that score the search's best designs and the final one.
    seed : seed of the search's draws and of the noise draws.
    """

    generations: int = 3
    population: int = 16
    draws: int = 40
    bootstrap: int = 1000
    refit_iterations: int = 3
    seed: int = 0

    def validate(self) -> None:
        for name in ("generations", "population", "draws", "bootstrap", "refit_iterations"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ConfigError(f"design setting {name} must be a positive integer, got {value!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ConfigError(f"design setting seed must be a non-negative integer, got {self.seed!r}")


FAST = DesignSettings(generations=1, population=8, draws=8, bootstrap=200, refit_iterations=1)
"""Settings for quick checks: every stage runs, briefly."""


@dataclass
class Run:
    """One hypothesis under the final design in Drake."""

    time: np.ndarray  # [s]
    angles: np.ndarray  # (N, 2) true [theta, phi] [rad]
    command: np.ndarray  # (N,) logged command [N m] (with --balancing: the LQR's plus the dither)
    peaks: dict[str, float]


@dataclass
class Design:
    """A finished design (``docs/design.md``): ``status`` is ``design``, ``no_separation`` or ``refused``."""

    status: str
    reason: str
    mode: str  # "hanging" | "balancing"
    duration: float  # [s]
    period: float  # [s]
    input_kind: str  # "torque" | "voltage"
    torque_per_volt: float  # [N m / V] (1 for torque)
    bounds: Bounds
    hypotheses: Hypotheses
    command: np.ndarray | None  # (N,) the played command [N m] (the dither with --balancing)
    excitation: dict
    pairs: list[dict]
    runs: dict[str, Run]
    search: dict
    notes: list[str]
    record: DiagnosisRecord
    settings: DesignSettings
    options: dict = field(default_factory=dict)
    limits: list[dict] = field(default_factory=list)  # per target: today's and the predicted detection limit
    choice: dict = field(default_factory=dict)  # the candidate experiments compared by their predicted limits


def design_experiment(
    diagnosis: str | Path,
    *,
    duration: float | None = None,
    balancing: bool | None = None,
    targets: list[str] = (),
    arm_bound: float = 1.0,
    settings: DesignSettings = DesignSettings(),
    progress: Callable[[str], None] | None = None,
) -> Design:
    """Design the experiment that separates a diagnosis' competing hypotheses.

    Parameters
    ----------
    diagnosis : the output directory of ``furuta-drake diagnose``.
    duration : length of the experiment [s]; its first half trains, its second half is held out. None: the
        shortest repeat of an ``AUTO_DURATION`` experiment predicted to settle every pair, up to ``REPEATS[-1]``
        times as long; when the design targets detection limits, the one of ``AUTO_DURATION`` times
        ``LIMIT_REPEATS`` whose predicted limits are lowest (:mod:`furuta_drake.design.choice`).
    balancing : True: a dither added to the project's LQR balancing the upright; False: an open-loop command
        played from rest with the pendulum hanging; None: the open loop, or, when the design targets detection
        limits, the mode whose predicted limits are lowest.
    targets : ``effect=value`` texts: separate the accepted model from it plus that effect at that size (the main
        parameter's value, as ``detection_limits`` states it) instead of from its rivals.
    arm_bound : the largest arm angle |phi| allowed under any hypothesis [rad].
    settings : sizes and seeds (:class:`DesignSettings`); progress : called with a line per stage.
    """
    settings.validate()
    _check_options(duration, arm_bound)
    with one_blas_thread():  # its linear algebra is small: a second BLAS thread would only spin
        parsed = [parse_target(text) for text in targets]
        record = read_diagnosis(diagnosis)
        _check_duration(duration, record.rig)
        hypotheses = read_hypotheses(record.report, record.rig, record.train, parsed)
        say = progress or (lambda line: None)
        say(f"{len(hypotheses.hypotheses)} hypotheses, {len(hypotheses.pairs)} pairs to separate")
        sizes = target_sizes(hypotheses, parsed, record.report, record.rig)
        choosing = bool(sizes) and (balancing is None or duration is None)
        mode = None if choosing and balancing is None else "balancing" if balancing else "hanging"
        options = {
            "duration": duration,
            "mode": mode,
            "targets": list(targets),
            "arm_bound": arm_bound,
            "settings": dataclasses.asdict(settings),
        }
        context = _Context(
            record, hypotheses, scales_of(record.train, hypotheses.nominal), sizes, settings, options, say
        )
        if choosing:
            modes = MODES if mode is None else (mode,)
            durations = [duration] if duration is not None else [AUTO_DURATION * r for r in LIMIT_REPEATS]
            return _chosen_design(context, modes, durations)
        return _design_in_mode(context, mode, duration)


@dataclass(frozen=True)
class _Context:
    """What every stage of one design reads: the diagnosis, its hypotheses, scales and targets' sizes, the
    settings, the options as given and the progress callback."""

    record: DiagnosisRecord
    hypotheses: Hypotheses
    scales: Scales
    sizes: list[tuple[str, float]]
    settings: DesignSettings
    options: dict
    say: Callable[[str], None]


@dataclass
class _Searched:
    """The search of one mode: its family (at the duration searched), LQR gain (balancing) and common record."""

    mode: str
    family: Family
    gain: np.ndarray | None
    search: Search
    common: dict


def _searched(context: _Context, mode: str, duration: float | None) -> _Searched:
    """The cross-entropy search of the family's shapes in ``mode`` (section 3 of docs/design.md)."""
    record, hypotheses, rig = context.record, context.hypotheses, context.record.rig
    accepted = hypotheses.hypotheses[0].model
    family = Family(
        float(duration or AUTO_DURATION),
        rig.sample_period,
        accepted.arm_inertia_total,
        accepted.back_emf_damping + accepted.arm_friction.viscous,
    )
    bounds = Bounds(float(context.options["arm_bound"]), PENDULUM_BOUND[mode], rig.torque_limit)
    gain = nominal_lqr_gain(rig) if mode == "balancing" else None
    evaluator = _evaluator(family.base(), hypotheses, rig, context.scales, bounds, gain)
    settings = context.settings
    search = optimise(
        evaluator,
        hypotheses,
        settings.generations,
        settings.population,
        settings.refit_iterations,
        settings.seed,
        context.say,
    )
    common = _common(record, hypotheses, bounds, settings, search, context.options, mode)
    if search.inseparable and search.directions and search.best is not None:
        common["notes"].append(
            "left out, no experiment of the family separates them: " + _inseparable_text(search, hypotheses)
        )
    return _Searched(mode, family, gain, search, common)


def _design_in_mode(context: _Context, mode: str, duration: float | None) -> Design:
    """The design in ``mode``: at ``duration``, or (None) the shortest repeat predicted to settle every pair."""
    searched = _searched(context, mode, duration)
    family = searched.family
    refusal = _refusal(searched, context.hypotheses)
    if refusal is not None:
        return refusal
    design = _final(searched, family, context)
    if duration is None and design.status == "design":
        needed = [pair["suggested_duration_s"] for pair in design.pairs]
        longer = max((d for d in needed if d is not None), default=family.duration)
        if longer > family.duration:
            context.say(f"repeating the experiment to {longer:g} s")
            design = _final(searched, dataclasses.replace(family, duration=longer), context)
    design.notes += _unsettled_notes(design)
    design.limits = _predicted_limits(design, context)
    return design


def _chosen_design(context: _Context, modes: tuple[str, ...], durations: list[float]) -> Design:
    """Every mode of ``modes`` at every duration of ``durations`` played in Drake and its detection limits
    predicted; the candidate :func:`~furuta_drake.design.choice.chosen` picks, its pairs predicted, with the
    comparison in ``choice``."""
    candidates, played = [], []
    for mode in modes:
        searched = _searched(context, mode, durations[0])
        refusal = _refusal(searched, context.hypotheses)
        for duration in durations if refusal is None else [searched.family.duration]:
            design, runs = refusal, {}
            if refusal is None:
                context.say(f"{mode} for {duration:g} s: playing it in Drake and predicting its detection limits")
                design, runs = _played(searched, dataclasses.replace(searched.family, duration=duration), context)
                design.limits = _predicted_limits(design, context) if design.status == "design" else []
            candidates.append({"mode": mode, "duration_s": duration, "status": design.status, "reason": design.reason})
            candidates[-1]["limits"] = design.limits
            played.append((design, runs, searched))
    index = chosen(candidates)
    design, runs, searched = played[0 if index is None else index]
    if index is not None:
        design.pairs = _predicted_pairs(
            searched.search,
            runs,
            context.hypotheses,
            context.record,
            context.scales,
            context.settings,
            design.duration,
        )
        design.notes += _unsettled_notes(design)
    design.choice = choice_record(candidates, index)
    return design


def _predicted_limits(design: Design, context: _Context) -> list[dict]:
    """Per target of the context (``--target`` ones, else the limits that matter), today's and the predicted
    detection limit of ``design`` (:mod:`furuta_drake.design.limits`)."""
    hypotheses, record = design.hypotheses, design.record
    run = design.runs.get(hypotheses.hypotheses[0].name)
    return predicted_limits(
        record,
        hypotheses,
        context.sizes,
        None if run is None else (run.angles, run.command),
        context.scales,
        design.settings.bootstrap,
        design.settings.seed,
    )


def _common(record, hypotheses, bounds, settings, search, options: dict, mode: str) -> dict:
    """What every outcome of the design records: the mode, the rig's period and input, the bounds, hypotheses,
    diagnosis, settings, notes, the search's summary and the options."""
    return dict(
        mode=mode,
        period=record.rig.sample_period,
        input_kind=record.input_kind,
        torque_per_volt=record.train[0].torque_per_volt if record.input_kind == "voltage" else 1.0,
        bounds=bounds,
        hypotheses=hypotheses,
        record=record,
        settings=settings,
        notes=list(hypotheses.notes),
        search=_search_summary(search),
        options=options,
    )


def _check_options(duration: float | None, arm_bound: float) -> None:
    if duration is not None and not (isinstance(duration, (int, float)) and math.isfinite(duration) and duration > 0):
        raise ConfigError(f"--duration must be a positive number of seconds, got {duration!r}")
    if not (isinstance(arm_bound, (int, float)) and math.isfinite(arm_bound) and arm_bound > 0):
        raise ConfigError(f"--arm-bound must be a positive angle [rad], got {arm_bound!r}")


def _check_duration(duration: float | None, rig) -> None:
    """Each half of the experiment must hold one gap window of the rig."""
    period = rig.sample_period
    horizon, smooth = window_samples(period, rig)
    shortest = 2 * (horizon + 2 * smooth + 1) * period
    if duration is not None and duration < shortest:
        raise ConfigError(
            f"--duration {duration:g} s is too short: each half of the experiment must hold a gap "
            f"window of this rig ({shortest:.3g} s in all)"
        )


def _evaluator(base, hypotheses, rig, scales, bounds, gain) -> Evaluator:
    """The evaluator of the family's designs: a dither added to the LQR balancing (``gain`` given), or an
    open-loop command played from rest with the pendulum hanging."""
    period = rig.sample_period
    if gain is not None:

        def runs(model, dithers):
            return surrogate_closed_loop(model, gain, dithers, period, rig.torque_limit, rig.counts_per_rev)

        signal, motion = base.torque_dither, None
    else:

        def runs(model, commands):
            return surrogate_runs(model, commands, period), commands

        signal, motion = base.feedforward, base.arm_motion
    return Evaluator(base, hypotheses, rig, scales, bounds, runs, signal, motion, hanging=gain is None)


def _refusal(searched: _Searched, hypotheses: Hypotheses) -> Design | None:
    """The Design that says why there is none: no direction separates the pairs, or no design keeps within the
    bounds under every hypothesis; None when the search found one."""
    search, family, common = searched.search, searched.family, searched.common
    bounds, balancing = common["bounds"], searched.mode == "balancing"
    if search.directions and search.best is not None:
        return None
    if not search.directions:
        status, why = "no_separation", "no experiment separates them: " + _inseparable_text(search, hypotheses)
    else:
        status, why = (
            "refused",
            f"no design of the family keeps the arm within {bounds.arm:g} rad, the pendulum "
            f"within {bounds.pendulum:g} rad of {'the upright' if balancing else 'hanging'} and the "
            f"command within {bounds.command:.4g} N m under every hypothesis",
        )
    return Design(status, why, duration=family.duration, command=None, excitation={}, pairs=[], runs={}, **common)


def _unsettled_notes(design: Design) -> list[str]:
    """A note for each pair predicted to be settled with less than ``SETTLES`` probability."""
    notes = []
    for pair in design.pairs:
        if pair["detection_probability"] < SETTLES:
            longer = pair["suggested_duration_s"]
            notes.append(
                f"{' vs '.join(pair['hypotheses'])}: predicted detection probability "
                f"{pair['detection_probability']:.0%}, below {SETTLES:.0%}; "
                + (
                    f"the same experiment repeated to {longer:g} s would reach it (--duration {longer:g})"
                    if longer
                    else f"not reached by repeating it up to {REPEATS[-1]} times"
                )
            )
    return notes


def _final(searched: _Searched, family: Family, context: _Context) -> Design:
    """:func:`_played`, with its outcome predicted per pair."""
    design, runs = _played(searched, family, context)
    if design.status == "design":
        context.say("predicting the diagnosis' outcome")
        design.pairs = _predicted_pairs(
            searched.search, runs, context.hypotheses, context.record, context.scales, context.settings, family.duration
        )
    return design


def _played(searched: _Searched, family: Family, context: _Context) -> tuple[Design, dict[int, Run]]:
    """The search's best design played for ``family.duration`` and checked in Drake under every hypothesis
    (scaled down if a bound is left), with the Drake runs per hypothesis index; ``refused`` when it still leaves
    a bound. Its pairs are left for :func:`_predicted_pairs`."""
    search, gain, common = searched.search, searched.gain, searched.common
    balancing = searched.mode == "balancing"
    hypotheses, bounds = common["hypotheses"], common["bounds"]
    played = (family.torque_dither if balancing else family.feedforward)(search.best.amplitudes)[0]
    best, runs = _checked_in_drake(
        dataclasses.replace(search.best, command=played),
        family,
        hypotheses,
        common["record"].rig,
        bounds,
        balancing,
        gain,
        common["settings"],
        context.say,
    )
    excitation = {
        "family": "band-limited multisine "
        + ("torque dither added to the LQR" if balancing else "arm motion played as feedforward torque"),
        **family.describe(best.amplitudes, "N_m" if balancing else "rad"),
    }
    if balancing:
        excitation["lqr_gain"] = [float(v) for v in np.ravel(gain)]
    common = {**common, "notes": list(common["notes"])}
    if runs is None:
        why = "the best design leaves a bound under some hypothesis in Drake even scaled down: "
        refused = Design(
            "refused",
            why + _violations(best.peaks, bounds, hypotheses),
            duration=family.duration,
            command=None,
            excitation=excitation,
            pairs=[],
            runs={},
            **common,
        )
        return refused, {}
    design = Design(
        "design",
        "",
        duration=family.duration,
        command=best.command,
        excitation=excitation,
        pairs=[],
        runs={hypotheses.hypotheses[h].name: run for h, run in runs.items()},
        **common,
    )
    return design, runs


def _checked_in_drake(
    best: EvaluatedDesign,
    family: Family,
    hypotheses: Hypotheses,
    rig,
    bounds: Bounds,
    balancing: bool,
    gain,
    settings: DesignSettings,
    say,
) -> tuple[EvaluatedDesign, dict[int, Run] | None]:
    """The best design played in Drake on every hypothesis it was checked on; scaled down (by the worst ratio,
    with the search's safety margin) while a bound is left, at most ``DRAKE_RESCALES`` times. None for the
    runs when it still leaves one."""
    for _ in range(DRAKE_RESCALES + 1):
        runs = {}
        for h in best.runs:
            say(f"checking the design in Drake on {hypotheses.hypotheses[h].name}")
            try:
                result = simulate(
                    drake_config(
                        rig,
                        hypotheses.hypotheses[h].model,
                        best.command,
                        family.duration,
                        balancing,
                        settings.seed,
                        gain,
                    )
                )
            except SimulationDiverged:
                runs[h] = Run(
                    np.zeros(0), np.zeros((0, 2)), np.zeros(0), {"arm": np.inf, "pendulum": np.inf, "command": np.inf}
                )
                continue
            angles = result.state[:, :2]
            rest = 0.0 if balancing else np.pi
            runs[h] = Run(
                result.time,
                angles,
                result.torque,
                {
                    "arm": float(np.max(np.abs(angles[:, 1]))),
                    "pendulum": float(np.max(np.abs(angles[:, 0] - rest))),
                    "command": float(np.max(np.abs(result.torque))),
                },
            )
        ratio = min(
            min(
                bounds.arm / max(run.peaks["arm"], 1e-300),
                bounds.pendulum / max(run.peaks["pendulum"], 1e-300),
                bounds.command * (1 + 1e-9) / max(run.peaks["command"], 1e-300),
            )
            for run in runs.values()
        )
        best = dataclasses.replace(best, peaks={h: run.peaks for h, run in runs.items()})
        if ratio >= 1.0:
            return best, runs
        scale = SAFETY * ratio if ratio > 0 else 0.5  # 0: a run diverged
        best = dataclasses.replace(best, level=best.level * scale, command=best.command * scale)
    return best, None


def _predicted_pairs(
    search: Search,
    runs: dict[int, Run],
    hypotheses: Hypotheses,
    record: DiagnosisRecord,
    scales,
    settings: DesignSettings,
    duration: float,
) -> list[dict]:
    """Per pair: its hypotheses, why, and per informative direction the exact noncentrality and the predicted
    outcome of the rule (:mod:`furuta_drake.design.predict`) on the Drake runs, with the duration
    (a multiple of ``duration`` in ``REPEATS``) at which the outcome would be detected in ``SETTLES`` of the draws
    (None when none is)."""
    counts = record.rig.counts_per_rev
    old_windows = diagnosis_heldout_windows(record)
    old_cache: dict[str, np.ndarray] = {}

    def old_excess(effects) -> np.ndarray:
        key = repr(effects)
        if key not in old_cache:
            old_cache[key] = evaluate_gap(apply_hypothesis(hypotheses.nominal, effects), old_windows, counts).per_window
        return old_cache[key]

    out = []
    for index, pair in enumerate(hypotheses.pairs):
        names = [hypotheses.hypotheses[pair.first].name, hypotheses.hypotheses[pair.second].name]
        entry = {"hypotheses": names, "step": pair.step, "why": pair.why, "nested": pair.nested, "directions": []}
        for direction in [d for d in search.directions + search.inseparable if d.pair == index]:
            head, outcome, predict = _predicted_direction(
                direction, pair, runs, hypotheses, record, scales, settings, old_excess
            )
            outcome["suggested_duration_s"] = _suggested_duration(outcome, predict, duration)
            entry["directions"].append({**head, "separable": direction in search.directions, **outcome})
        entry["detection_probability"] = min(d["detection_probability"] for d in entry["directions"])
        needed = [d["suggested_duration_s"] for d in entry["directions"]]
        entry["suggested_duration_s"] = None if None in needed else max(needed)
        out.append(entry)
    return out


def _predicted_direction(direction, pair, runs, hypotheses, record, scales, settings, old_excess):
    """One direction of a pair (its truth against its rival) on the truth's Drake run: (its names, exact
    noncentrality and RMS difference; the rule's predicted outcome; ``replicas`` -> the outcome of the experiment
    repeated that many times)."""
    rig, counts = record.rig, record.rig.counts_per_rev
    truth, rival = hypotheses.hypotheses[direction.truth], hypotheses.hypotheses[direction.rival]
    run = runs[direction.truth]
    train, heldout = experiment_windows(run.angles[:, :, None], run.command[None], rig.sample_period, rig)
    fits = {
        key: refit_residuals(
            Parametrised(hypotheses.nominal, effects, scales), train, heldout, counts, settings.refit_iterations
        )
        for key, effects in ((TRUTH, truth.effects), (RIVAL, rival.effects), ("previous", pair.previous))
    }
    new = dict(zip((TRUTH, RIVAL), pair.new if direction.truth == pair.first else pair.new[::-1]))
    old = {TRUTH: old_excess(truth.effects), RIVAL: old_excess(rival.effects), "previous": old_excess(pair.previous)}
    arguments = (fits[TRUTH], fits[RIVAL], fits["previous"], old, new, pair.nested, pair.step == 1, truth.model)
    arguments += (counts, settings.draws, settings.bootstrap, settings.seed)
    squared = fits[RIVAL].residuals[1:] ** 2
    head = {
        "truth": truth.name,
        "rival": rival.name,
        "noncentrality": float(np.sum(squared) / fits[TRUTH].variance),
        "rms_difference_counts": float(np.sqrt(np.mean(squared))),
    }
    return head, predict_direction(*arguments), lambda replicas: predict_direction(*arguments, replicas=replicas)


def _suggested_duration(outcome: dict, predict, duration: float) -> float | None:
    """The duration (a multiple of ``duration`` in ``REPEATS``) at which the outcome would be detected in
    ``SETTLES`` of the draws (None when none is)."""
    repeats = 1
    if outcome["detection_probability"] < SETTLES:
        repeats = next((r for r in REPEATS if predict(r)["detection_probability"] >= SETTLES), None)
    return None if repeats is None else duration * repeats


def _search_summary(search: Search) -> dict:
    feasible = [c for c in search.candidates if c.feasible]
    return {
        "designs_evaluated": len(search.candidates),
        "within_bounds": len(feasible),
        "criterion": "the smallest noncentrality over every pair's informative directions (surrogate: one "
        "linearised refit of the rival on the train half ranks a generation, iterated refits score "
        "its best designs)",
        "best_weakest_noncentrality": None
        if search.best is None
        else search.best.score(search.directions, refined=True),
    }


def _inseparable_text(search: Search, hypotheses: Hypotheses) -> str:
    names = {(d.truth, d.rival) for d in search.inseparable}
    return "; ".join(
        f"{hypotheses.hypotheses[t].name} (as the truth) and {hypotheses.hypotheses[r].name}: their "
        f"held-out windows differ by less than the noise of one sample over the whole experiment, once "
        f"the rival's parameters and initial states are refit"
        for t, r in sorted(names)
    )


def _violations(peaks: dict[int, dict[str, float]], bounds: Bounds, hypotheses: Hypotheses) -> str:
    parts = []
    for h, peak in peaks.items():
        for key, limit in (("arm", bounds.arm), ("pendulum", bounds.pendulum), ("command", bounds.command)):
            if not peak[key] <= limit * (1 + 1e-9):
                parts.append(f"{hypotheses.hypotheses[h].name}: {key} {peak[key]:.3g} > {limit:.3g}")
    return "; ".join(parts)
