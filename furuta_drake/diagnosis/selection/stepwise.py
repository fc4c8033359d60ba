"""The selection of effects (stage 4 of the diagnosis): forward, one effect at a time, each fitted together with the
earlier ones (every candidate screened first, those the screen leaves far behind not fitted further) and entering on
the held-out rule's lenient bound; then backward, each kept only while the model without it is worse by the rule's
margin; then exchanges, each kept effect replaced by a runner-up of the step it entered at, or by a richer variant of
its law, when that explains the held-out data significantly better, the forward and backward passes resumed after
each; last, a kept inertia error replaced by a drive gain that explains the data as well
(:mod:`furuta_drake.diagnosis.selection.rule` holds the rule). These are the
effects that change the predictions; a sensor effect that passes its signature test beside the nominal model has
them judged on the gap beyond the variance it adds. The sensor effects are then read beside the final model and
judged on their own signature (:mod:`furuta_drake.diagnosis.selection.sensor`), and a named jittering delay's draws
are credited with the variance they add (:mod:`furuta_drake.diagnosis.selection.jitter_fit`)."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from furuta_drake.diagnosis.formatting import percent
from furuta_drake.diagnosis.gap.metric import GapResult, evaluate_gap
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.diagnosis.selection.equation_error import equation_error_starts
from furuta_drake.diagnosis.selection.fit import (
    FitResult,
    FitTask,
    after_screen,
    fit_task,
    fit_windows,
    scales_of,
    screen_task,
)
from furuta_drake.diagnosis.selection.jitter_fit import HeldoutJitter, heldout_jitter
from furuta_drake.diagnosis.selection.rule import (
    CLOSES,
    ENTRY,
    LEVEL_EXCESS,
    PARSIMONY,
    Bootstrap,
    Comparison,
    choose,
    combined_reduction,
    confusable,
    confusable_pair,
    decide,
    n_params,
    negligible,
    order,
    verdict,
)
from furuta_drake.diagnosis.selection.sensor import SensorFinding, read_sensors
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import CANDIDATES, Effect, apply_effects, law_of
from furuta_drake.parallel import Failure

COMMAND_MAPS = ("actuator_deadzone", "actuator_saturation")  # static maps of the command beside the gain
ONE_MAGNITUDE = 0.99  # logged |commands| whose 10 % quantile is within this of their 97 % take one magnitude
JOINT_REFITS = 3  # at a later step, the candidates fitted again together with the earlier effects
FRESH_STARTS_FROM = 3  # from this step, those refits also start from the new effect's own starts
PAIR_ENTRY = 3  # when no single effect enters first, pairs of this many best train fits are fitted together
EXCHANGE_RUNNERS_UP = 2  # per kept effect, the runners-up of its entry step tried in its place
MAX_EXCHANGES = 2  # exchanges made at the most (each followed by the backward pass)
GAIN, INERTIA = "torque_gain_error", "inertia_mismatch"  # one explanation when the inertia scales are uniform
SCREEN_REACH = 0.3  # a step's candidate whose screen reduces the gap the earlier effects leave by this much less
# than the best screen (as shares of that gap on the start windows) is not fitted further


@dataclass
class Selection:
    """The outcome of the selection on one split of the logs: the effects kept, in the order they entered, and
    every model fitted on the way."""

    nominal: GapResult  # the nominal model on the held-out windows
    tried: list[tuple[int, FitResult]]  # every model fitted, with its step (its number of effects)
    accepted: list[str] = field(default_factory=list)  # the accepted effects, in the order they entered
    over_nominal: dict[str, Comparison] = field(default_factory=dict)  # model name -> evidence over nominal
    over_previous: dict[str, Comparison] = field(default_factory=dict)  # ... over the model it was built on
    over_others: dict[str, Comparison] = field(default_factory=dict)  # kept effect -> final over final without it
    over_step: list[Comparison] = field(default_factory=list)  # each accepted step over the step before
    confusable: list[dict] = field(default_factory=list)
    quiet: bool = False  # the nominal model explains the held-out data to within their noise
    runners_up: dict[str, list[tuple[str, Effect]]] = field(default_factory=dict)  # kept effect -> the other
    # laws' candidates at its entry step, best first, with their fits there
    variants: dict[str, list[tuple[str, Effect]]] = field(default_factory=dict)  # kept effect -> the other
    # variants of its law at its entry step, best first, with their fits there
    exchanges: list[dict] = field(default_factory=list)  # {"out", "in", "evidence"}: the exchanges made
    subset_fit: FitResult | None = None  # the final model as the selection fitted it, on its fit windows, when
    # ``final`` is its refit on every train window (:mod:`~furuta_drake.diagnosis.selection.final_fit`)
    regressed: dict = field(default_factory=dict)  # the train logs' equation-error starts (every fit's)
    gain_only: list[str] = field(default_factory=list)  # command maps not tried: on commands of one magnitude
    # (bang-bang) a dead zone or a saturation of the drive acts as a gain
    sensors: list[SensorFinding] = field(default_factory=list)  # the sensor effects read beside the final model
    jitter: HeldoutJitter | None = None  # the final model's jittering delay judged on the held-out windows
    beneath: list[str] = field(default_factory=list)  # the sensor effects the rule judged the others beyond
    beneath_variance: np.ndarray | None = None  # per held-out window, the variance they add [counts^2]
    form_rivals: list[FitResult] = field(default_factory=list)  # the final model with a kept friction law in its
    # other form (:mod:`~furuta_drake.diagnosis.selection.rival`)

    def rule_bootstrap(self, bootstrap: Bootstrap) -> Bootstrap:
        """``bootstrap`` as the rule reads this selection's models: beyond the variance of the sensor effects it
        judged them beyond (``bootstrap`` itself when none)."""
        return bootstrap if self.beneath_variance is None else bootstrap.beyond(self.beneath_variance)

    def model(self, effects) -> FitResult | None:
        """The fitted model holding exactly ``effects`` (in any order), or None (a screen is no fit: a model the
        backward pass or an exchange compares with must be one)."""
        return next(
            (r for _, r in self.tried if not (r.failure or r.screened) and set(r.effects) == set(effects)), None
        )

    @property
    def step_models(self) -> list[FitResult]:
        """The model after each accepted step: holding the first 1, 2, ... kept effects (where such a set's fit
        failed, the step before's, or the final model for the first)."""
        out = []
        for k in range(1, len(self.accepted) + 1):
            model = self.model(self.accepted[:k])
            out.append(model if model is not None else (out[-1] if out else self.final))
        return out

    @property
    def final(self) -> FitResult | None:
        return self.model(self.accepted) if self.accepted else None

    @property
    def sensor_effects(self) -> list[SensorFinding]:
        """The accepted sensor effects."""
        return [finding for finding in self.sensors if finding.accepted]

    def claimed(self) -> np.ndarray:
        """Per held-out window, the variance [counts^2] the accepted sensor effects and a credited jittering delay
        add to the residuals beyond the rig file's own sensor."""
        total = np.zeros(self.nominal.per_window.size)
        for finding in self.sensor_effects:
            total = total + finding.claimed
        if self.jitter is not None and self.jitter.credited:
            total = total + self.jitter.claimed
        return total

    @property
    def shares(self) -> tuple[float, float]:
        """(the share of the nominal held-out mean squared excess the final model's predictions remove, the share
        of it the accepted sensor effects and a credited jitter account for, at most what the predictions leave)."""
        reduction = self.over_nominal[self.final.name].reduction if self.accepted else 0.0
        predicted = 1.0 - (1.0 - reduction) ** 2
        if not self.sensor_effects and (self.jitter is None or not self.jitter.credited):
            return predicted, 0.0
        before = max(float(self.nominal.per_window.mean()), 1e-12)
        return predicted, min(float(self.claimed().mean()) / before, 1.0 - predicted)

    @property
    def closes(self) -> bool:
        return bool(self.accepted or self.sensor_effects) and combined_reduction(*self.shares) >= CLOSES

    @property
    def negligible(self) -> bool:
        """No effect closes the nominal held-out gap, and that gap is too small to matter
        (:func:`~furuta_drake.diagnosis.selection.rule.negligible`)."""
        return not self.closes and negligible(self.nominal.gap)

    @property
    def verdict(self) -> str:
        names = self.effects
        sensors = sorted(self.sensor_effects, key=lambda finding: -float(np.mean(finding.claimed)))
        dynamic = names[: len(names) - len(sensors)]
        return verdict(dynamic, [finding.name for finding in sensors], self.shares, self.quiet or self.negligible)

    def nearest(self) -> FitResult | None:
        """The single candidate fitted that reduces the nominal held-out gap the most (None when none was)."""
        singles = [r for step, r in self.tried if step == 1 and not (r.failure or r.screened) and "+" not in r.name]
        return max(singles, key=lambda r: self.over_nominal[r.name].reduction, default=None)

    @property
    def effects(self) -> list[str]:
        """The accepted effects (those changing the predictions in the order accepted, then the sensor effects;
        empty for none and unexplained); a Stribeck fit without static excess, or an asymmetry fit with equal
        levels, is named Coulomb friction (the vocabulary's Stribeck is static friction *above* it, its asymmetry
        levels that differ)."""
        if not self.closes:
            return []
        dynamic = [_vocabulary_name(name, self.final.effects[name]) for name in self.accepted]
        return dynamic + [finding.name for finding in self.sensor_effects]


def _vocabulary_name(name: str, effect: Effect) -> str:
    """A Stribeck fit whose static level is within ``LEVEL_EXCESS`` of its Coulomb level has no Stribeck part, and
    an asymmetry fit whose two levels are that close no asymmetry: both are Coulomb friction."""
    if name == "arm_stribeck" and effect.values[1] <= (1.0 + LEVEL_EXCESS) * effect.values[0]:
        return "arm_coulomb_friction"
    if name == "friction_asymmetry" and abs(effect.values[0] - effect.values[1]) <= LEVEL_EXCESS * max(
        effect.values[:2]
    ):
        return "arm_coulomb_friction"
    return name


def select_effects(
    nominal: Model,
    logs: list[RunLog],
    train,
    heldout,
    counts: int,
    names: list[str],
    settings: DiagnosisSettings,
    run: Callable,
) -> Selection:
    """Select up to ``settings.max_effects`` effects under the held-out rule
    (:mod:`furuta_drake.diagnosis.selection.rule`): forward, one at a time, each fitted together with the earlier ones
    and entering when it reduces the gap of the model holding them; then backward, each kept only while the model
    without it is worse by the rule, the forward steps resumed without an effect dropped; then the exchanges
    (:class:`Stepwise`)."""
    return Stepwise(nominal, logs, train, heldout, counts, settings, run).select(names)


class Stepwise:
    """The selection on one split of the logs: its :class:`Selection` and the steps that fill it, each fit run by
    ``run`` (the contained worker pool) and recorded with its held-out evidence over the nominal model and over
    the model it was built on."""

    def __init__(self, nominal: Model, logs, train, heldout, counts: int, settings: DiagnosisSettings, run):
        self.nominal, self.logs, self.train, self.heldout = nominal, tuple(logs), train, heldout
        self.counts, self.settings, self.run = counts, settings, run
        self.bootstrap = Bootstrap(heldout.count, settings.bootstrap, settings.seed)
        self.judge = self.bootstrap  # the rule's bootstrap: beyond a sensor effect's variance once one is read
        self.scales = scales_of(self.logs, nominal)
        self.nominal_gap = evaluate_gap(nominal, heldout, counts)
        self.regressed = equation_error_starts(self.logs, nominal)
        self.selection = self.fresh_selection()
        self.screens: dict[str, tuple] = {}  # model name -> (its task, its screen): a candidate the screen left behind
        self.nominal_sensors: list[SensorFinding] | None = None  # the sensor effects read beside the nominal model

    def fresh_selection(self) -> Selection:
        """A selection holding no effect yet."""
        quiet = self.bootstrap.within_noise(self.nominal_gap.per_window)
        return Selection(self.nominal_gap, [], quiet=quiet, regressed=self.regressed)

    def select(self, names: list[str]) -> Selection:
        """The effects among ``names`` that change the predictions (:meth:`select_dynamic`), judged beyond the
        sensor effects among them that pass their signature test beside the nominal model
        (:meth:`sensor_beneath`); then the sensor effects read beside the final model (:meth:`read_sensors`). A
        sensor effect the dynamic effects were judged beyond that is not confirmed there has the selection made
        again on the whole gap."""
        dynamic = [name for name in names if CANDIDATES[name].fit]
        sensors = [name for name in names if not CANDIDATES[name].fit]
        beneath = self.sensor_beneath(sensors)
        self.select_dynamic(dynamic, beneath)
        self.read_sensors(sensors)
        if beneath and not {finding.name for finding in beneath} <= {f.name for f in self.selection.sensor_effects}:
            self.selection, self.screens = self.fresh_selection(), {}
            self.select_dynamic(dynamic, [])
            self.read_sensors(sensors)
        return self.selection

    def sensor_beneath(self, names: list[str]) -> list[SensorFinding]:
        """The sensor effects among ``names`` that pass their signature test beside the nominal model: the dynamic
        effects are judged on the gap beyond the variance they add (a few counts of noise or a coarse encoder
        would otherwise hide every dynamic effect under them), while every reduction reported keeps the rig file's
        own sensor alone taken off."""
        if not names:
            return []
        self.nominal_sensors = read_sensors(
            self.nominal, self.train, self.heldout, self.counts, self.settings, self.bootstrap
        )
        return [finding for finding in self.nominal_sensors if finding.accepted and finding.name in names]

    def select_dynamic(self, dynamic: list[str], beneath: list[SensorFinding]) -> None:
        """The effects that change the predictions among ``dynamic``, judged on the held-out gap beyond the variance
        the sensor effects ``beneath`` add (none: on the whole gap): forward (:meth:`step` until none enters) and
        backward (:meth:`forward_backward`); then at most ``MAX_EXCHANGES`` exchanges, after each of which the
        backward pass and the forward steps run again beside the model it made: the later steps' candidates were
        judged beside the effect exchanged out, which had stood in for part of them (on logged commands of one
        magnitude, a bang-bang, the gain in place of a dead zone or a saturation of the drive, which act on them as
        a gain)."""
        self.selection.beneath = [finding.name for finding in beneath]
        self.selection.beneath_variance = sum(finding.claimed for finding in beneath) if beneath else None
        self.judge = self.selection.rule_bootstrap(self.bootstrap)
        levels = self.scales.command_levels
        if levels and levels[0] >= ONE_MAGNITUDE * levels[-1] and "torque_gain_error" in dynamic:
            self.selection.gain_only = [name for name in dynamic if name in COMMAND_MAPS]
            dynamic = [name for name in dynamic if name not in COMMAND_MAPS]
        dropped: set[str] = set()
        self.forward_backward(dynamic, dropped)
        for _ in range(MAX_EXCHANGES):
            if not _exchange(
                self.selection, self.judge, self.nominal_gap, self.task, self.fit, self.best_form, self.scales
            ):
                break
            _backward(self.selection, self.judge, self.nominal_gap, self.task, self.fit, self.scales)
            self.resume(dropped)
            self.forward_backward(dynamic, dropped)
        if GAIN in dynamic and _prefer_gain(self.selection, self.judge, self.nominal_gap, self.task, self.fit):
            _backward(self.selection, self.judge, self.nominal_gap, self.task, self.fit, self.scales)

    def forward_backward(self, dynamic: list[str], dropped: set[str]) -> None:
        """Forward steps over ``dynamic`` less ``dropped`` until none enters, then the backward pass; the forward
        steps resumed without the effects the backward pass dropped (added to ``dropped``) until it drops none."""
        while True:
            pool = [name for name in dynamic if name not in dropped]
            while len(self.selection.accepted) < self.settings.max_effects and self.step(pool):
                pass
            entered = set(self.selection.accepted)
            _backward(self.selection, self.judge, self.nominal_gap, self.task, self.fit, self.scales)
            if entered <= set(self.selection.accepted):
                return
            dropped |= entered - set(self.selection.accepted)
            self.resume(dropped)

    def resume(self, dropped: set[str]) -> None:
        """Forget the fits of the forward steps after the effects kept, save those holding an effect in
        ``dropped``: the steps resume from the kept effects without those (an effect that stood in for a later
        one can win its step by a hair and be dropped beside it; the candidate it beat there, the right one,
        enters then), their candidates screened and fitted again without the dropped ones."""
        resumed = len(self.selection.accepted) + 1
        self.selection.tried = [(s, r) for s, r in self.selection.tried if s < resumed or set(r.effects) & dropped]

    def read_sensors(self, names: list[str]) -> None:
        """The sensor effects among ``names`` read beside the final model and judged on the held-out windows, and
        the final model's jittering delay (when it has one) judged there too."""
        selection = self.selection
        model = apply_effects(self.nominal, selection.final.effects) if selection.final else self.nominal
        findings = (
            self.nominal_sensors  # beside the nominal model: read already (:meth:`sensor_beneath`)
            if selection.final is None and self.nominal_sensors is not None
            else read_sensors(model, self.train, self.heldout, self.counts, self.settings, self.bootstrap)
        )
        selection.sensors = [finding for finding in findings if finding.name in names]
        if model.delay_spread > 0:
            selection.jitter = heldout_jitter(
                model, self.train, self.heldout, self.counts, self.bootstrap, self.settings.seed
            )

    def record(self, result: FitResult, previous) -> None:
        """``result``'s held-out evidence over the nominal model and over the model it was built on (``previous``,
        its per-window excess)."""
        self.selection.over_nominal[result.name] = self.bootstrap.evidence(
            self.nominal_gap.per_window, result.heldout.per_window
        )
        self.selection.over_previous[result.name] = self.judge.evidence(previous, result.heldout.per_window)

    def fit(self, tasks: list[FitTask], step: int, previous) -> list[FitResult]:
        """The ``tasks`` fitted (a failed one as a FitResult with its reason), tried at ``step`` and recorded."""
        return self.tried(tasks, self.run(fit_task, tasks), step, previous)

    def tried(self, tasks: list[FitTask], results: list, step: int, previous) -> list[FitResult]:
        """The ``results`` of ``tasks`` (a failed one as a FitResult with its reason), tried at ``step`` and
        recorded; a fit takes the place of a screen of the same model among the models tried."""
        results = [_as_fit(task, result) for task, result in zip(tasks, results)]
        tried = self.selection.tried
        for result in results:
            screen = next(
                (i for i, (_, r) in enumerate(tried) if r.screened and set(r.effects) == set(result.effects)), None
            )
            if screen is None or result.failure:
                tried.append((step, result))
            else:
                tried[screen] = (step, result)
            if not result.failure:
                self.record(result, previous)
        return results

    def screened_fits(self, tasks: list[FitTask], step: int, previous) -> list[FitResult]:
        """A step's candidates (``tasks``, beside the same earlier effects): each screened
        (:func:`~furuta_drake.diagnosis.selection.fit.screen_task`); fitted fully from the screen's starts when its
        screen's reduction of the gap the earlier effects leave on the start windows comes within ``SCREEN_REACH`` of
        the best screen's, or the screen failed (the fit says why); else kept as its screen, ``screened`` and why. Every
        candidate is fitted when the earlier effects leave no excess over the floor on the start windows. Recorded
        at ``step``. A candidate the screen leaves that far behind does not come near the best one once
        both are fitted: it can neither enter nor be confused with the one that does."""
        before = self.start_excess(tasks[0].fixed) if tasks else 0.0
        if before <= 0.0:  # the start windows sit at the floor already: no screen tells the candidates apart
            return self.fit(tasks, step, previous)
        screens = [None if isinstance(s, Failure) else s for s in self.run(screen_task, tasks)]
        reduction = [None if s is None else 1.0 - np.sqrt(max(s.excess, 0.0) / before) for s in screens]
        best = max((r for r in reduction if r is not None), default=None)
        behind = [best is not None and r is not None and r < best - SCREEN_REACH for r in reduction]
        results = self.run(after_screen, [(t, s, not left) for t, s, left in zip(tasks, screens, behind)])
        gap = "the nominal gap" if step == 1 else "the gap the earlier effects leave"
        for i, task in enumerate(tasks):
            if behind[i] and not isinstance(results[i], Failure):
                share = percent(round(reduction[i], 2) + 0.0)  # (no "-0 %")
                reason = f"its screen reduced {gap} on the start windows by {share}, the best screen by {percent(best)}"
                results[i] = dataclasses.replace(results[i], screened=reason + ": not fitted further")
                self.screens[task.name] = (task, screens[i])
        return self.tried(tasks, results, step, previous)

    def start_excess(self, effects: dict) -> float:
        """The mean excess squared residual [counts^2] on the start windows of the nominal model with ``effects``."""
        windows = fit_windows(self.train, self.settings)[1]
        return float(evaluate_gap(apply_effects(self.nominal, effects), windows, self.counts).per_window.mean())

    def fit_screened_out(self, fitted: dict[str, FitResult], step: int, previous) -> dict[str, FitResult]:
        """``fitted`` with every candidate the screen left behind fitted fully from its screen's starts, each in its
        screen's place among the models tried."""
        out = [name for name, result in fitted.items() if result.screened]
        jobs = [(*self.screens[name], True) for name in out]
        results = self.tried([job[0] for job in jobs], self.run(after_screen, jobs), step, previous)
        kept = {name: result for name, result in fitted.items() if name not in out}
        return kept | {name: result for name, result in zip(out, results) if not result.failure}

    def best_form(self, result: FitResult, result_task: FitTask, previous) -> FitResult:
        """``result``, or its refit with another form of its earlier effects when that fits the train windows
        better (:func:`_refit_forms`), recorded in its place."""
        refitted = _refit_forms(result, result_task, self.run)
        if refitted is not result:
            self.selection.tried = [(s, refitted if r is result else r) for s, r in self.selection.tried]
            self.record(refitted, previous)
        return refitted

    def task(self, new: str, held: FitResult | None, **options) -> FitTask:
        """The fit of ``new`` beside the effects of ``held`` (none: beside the nominal model alone)."""
        return FitTask(
            new=new,
            fixed=held.effects if held else {},
            model=self.nominal,
            train=self.train,
            heldout=self.heldout,
            logs=self.logs,
            nominal_counts=self.counts,
            settings=self.settings,
            fixed_samples=held.samples if held else {},
            regressed=self.selection.regressed,
            **options,
        )

    def step(self, names: list[str]) -> bool:
        """One forward step: every candidate not yet held fitted beside the kept effects, the best refitted jointly,
        and the rule's choice (or, at the first step, a pair) entered. Returns whether one entered."""
        selection = self.selection
        step, held = len(selection.accepted) + 1, selection.final
        previous = held.heldout.per_window if held else self.nominal_gap.per_window
        if step > 1 and self.judge.at_floor(previous):
            return False
        pool = [name for name in names if not law_of(name) & set(selection.accepted)]
        tasks = [self.task(name, held, frozen=step > 1) for name in pool]
        screened = self.settings.screen
        results = self.screened_fits(tasks, step, previous) if screened else self.fit(tasks, step, previous)
        fitted = {r.name: r for r in results if not r.failure}
        if self.judge.at_floor(self.nominal_gap.per_window):
            return False
        if step > 1:
            self.joint_refits(fitted, held, step, previous)
        pairs = step == 1 and not selection.quiet and self.settings.max_effects > 1
        kept, chosen = self.choice(fitted, previous)
        if any(result.screened for result in fitted.values()) and (
            kept[chosen].screened if chosen is not None else pairs
        ):  # the rule chose a screen, or none enters alone and the pairs start from every candidate's fit
            kept, chosen = self.choice(self.fit_screened_out(fitted, step, previous), previous)
        fitted = kept
        evidence, added, per_window = self.rule_inputs(fitted)
        if chosen is None and pairs:
            pair = _enter_pair(
                fitted, self.task, lambda tasks, before=previous: self.fit(tasks, 2, before), selection, self.scales
            )
            if pair is not None:
                for name in pair:
                    selection.runners_up[name] = _runners_up(name, evidence, added, fitted)
                selection.accepted += pair
                return True
        if chosen is None:
            return False
        fitted[chosen] = self.best_form(fitted[chosen], self.task(added[chosen], held), previous)
        evidence[chosen] = selection.over_previous[chosen]
        per_window[chosen] = fitted[chosen].heldout.per_window
        selection.confusable += confusable(chosen, evidence, added, previous, per_window, self.judge)
        selection.runners_up[added[chosen]] = _runners_up(added[chosen], evidence, added, fitted)
        selection.variants[added[chosen]] = _variants(added[chosen], evidence, added, fitted)
        selection.accepted.append(added[chosen])
        return True

    def choice(self, fitted: dict[str, FitResult], previous) -> tuple[dict[str, FitResult], str | None]:
        """(``fitted`` less the candidates at zero size, the rule's choice among them over ``previous`` or None)."""
        fitted = {name: result for name, result in fitted.items() if not _null(result, self.scales)}
        evidence, added, per_window = self.rule_inputs(fitted)
        return fitted, choose(evidence, added, ENTRY, previous, per_window, self.judge)

    def rule_inputs(self, fitted: dict[str, FitResult]) -> tuple[dict, dict, dict]:
        """Per model in ``fitted``: its evidence over the model it was built on, the effect it adds, and its
        held-out excess per window: what the rule reads."""
        evidence = {name: self.selection.over_previous[name] for name in fitted}
        added = {name: name.split("+")[-1] for name in fitted}
        return evidence, added, {name: result.heldout.per_window for name, result in fitted.items()}

    def joint_refits(self, fitted: dict[str, FitResult], held: FitResult, step: int, previous) -> None:
        """The ``JOINT_REFITS`` most promising candidates fitted again together with the earlier effects, from their
        fits beside the earlier effects held; beside two or more earlier effects also from the new effect's own
        starts in each of its forms (fitted beside earlier effects that stood in for it, its value there can sit in
        another basin of the joint cost: a delay beside friction and an inertia error). The best fit on the train
        windows (its excess before the gap's clip at the floor; any refit over a screen) replaces the held fit in
        ``fitted``."""
        selection = self.selection
        best = sorted(fitted, key=lambda name: -selection.over_previous[name].reduction)[:JOINT_REFITS]
        tasks = [self.task(name.split("+")[-1], held, start=fitted[name].effects[name.split("+")[-1]]) for name in best]
        if step >= FRESH_STARTS_FROM:
            tasks += [self.task(name.split("+")[-1], held) for name in best]
        results = self.fit(tasks, step, previous)
        for i, name in enumerate(best):
            refits = [r for r in results[i :: len(best)] if not r.failure]
            options = refits if refits and fitted[name].screened else [fitted[name], *refits]  # a screen is no fit
            kept = min(options, key=lambda r: r.train_excess)
            dropped = [r for r in [fitted[name], *results[i :: len(best)]] if r is not kept]
            selection.tried = [(s, r) for s, r in selection.tried if not any(r is d for d in dropped)]
            fitted[name] = kept
            self.record(kept, previous)


def _null(result: FitResult, scales) -> bool:
    """Whether the effect ``result`` adds (the last of its effects) is at zero size: a step that adds nothing is no
    step (:meth:`~furuta_drake.effects.vocabulary.Candidate.is_null`)."""
    name, effect = list(result.effects.items())[-1]
    return CANDIDATES[name].is_null(effect, scales)


def _runners_up(effect: str, evidence: dict, added: dict, fitted: dict) -> list[tuple[str, Effect]]:
    """The candidates of other laws than ``effect``'s at its entry step, best first, with their fits there."""
    return _entry_fits(evidence, added, fitted, lambda other: not law_of(other) & law_of(effect))


def _variants(effect: str, evidence: dict, added: dict, fitted: dict) -> list[tuple[str, Effect]]:
    """The other variants of ``effect``'s law at its entry step, best first, with their fits there."""
    return _entry_fits(evidence, added, fitted, lambda other: other != effect and other in law_of(effect))


def _entry_fits(evidence: dict, added: dict, fitted: dict, kept: Callable[[str], bool]) -> list[tuple[str, Effect]]:
    """Of a step's fitted models, best first, each added effect that ``kept`` holds (and is fitted, not read from the
    data) with its fit there."""
    return [
        (added[name], fitted[name].effects[added[name]])
        for name in order(evidence)
        if kept(added[name]) and CANDIDATES[added[name]].fit
    ]


def _exchange(
    selection: Selection,
    bootstrap: Bootstrap,
    nominal_gap: GapResult,
    task: Callable,
    fit: Callable,
    best_form: Callable,
    scales,
) -> bool:
    """Replace one kept effect by a runner-up of the step it entered at, or by another variant of its law, when
    the model holding the other kept effects and that one (fitted together) reduces the final model's held-out gap
    with a 5 % lower bound above ``ENTRY``. The forward pass chooses with the earlier effects held, so an effect
    that stood in for a later one can win its step by a hair (a transport delay standing in for a lag beside
    friction not yet fitted); judged again beside the effects finally kept, the right one explains the data
    clearly better. Likewise a Coulomb friction preferred to a Stribeck or an asymmetric law at its step (the
    simpler, where the gap the other effects still hid left them level) is replaced by that variant when, beside
    the effects finally kept, the variant also reduces the nominal gap by more than ``PARSIMONY`` beyond it (the
    rule's preference of the simpler law, kept). The ``EXCHANGE_RUNNERS_UP`` best runners-up and variants of each
    kept effect are tried, the other effects in each of their forms (a friction's form was chosen beside the effect
    now replaced); the best exchange is made. Returns whether one was."""
    final = selection.final
    if final is None or bootstrap.at_floor(final.heldout.per_window):  # nothing left to explain better
        return False
    best = None
    for name in selection.accepted:
        others = [other for other in selection.accepted if other != name]
        held = selection.model(others) if others else None
        if others and held is None:
            continue  # the model without it failed to fit (the backward pass fitted it otherwise)
        for result in _exchange_fits(selection, name, others, held, nominal_gap, task, fit, best_form, scales):
            evidence = bootstrap.evidence(final.heldout.per_window, result.heldout.per_window)
            new = result.name.split("+")[-1]
            if evidence.lower_bound > ENTRY and _beyond_parsimony(new, name, result, final, nominal_gap, bootstrap):
                if best is None or evidence.reduction > best[2].reduction:
                    best = (name, result, evidence)
    if best is None:
        return False
    name, result, evidence = best
    new = next(effect for effect in result.effects if effect not in selection.accepted)
    selection.accepted = [other for other in selection.accepted if other != name] + [new]
    selection.runners_up[new] = [(name, final.effects[name])] + [
        r for r in selection.runners_up.get(name, []) if r[0] != new
    ]
    selection.variants[new] = [(name, final.effects[name])] if new in law_of(name) else []
    selection.exchanges.append({"out": name, "in": new, "evidence": evidence})
    return True


def _exchange_fits(selection, name, others, held, nominal_gap, task, fit, best_form, scales) -> list[FitResult]:
    """The models holding ``others`` and, in place of ``name``, each of its ``EXCHANGE_RUNNERS_UP`` best runners-up
    of laws not held and variants of its law (those fitted on the way, the others fitted now from their fits at
    ``name``'s entry step), failed and zero-size ones left out."""
    taken = set().union(*(law_of(other) for other in others))
    runners_up = [(r, start) for r, start in selection.runners_up.get(name, []) if not law_of(r) & taken]
    tried = runners_up[:EXCHANGE_RUNNERS_UP] + selection.variants.get(name, [])[:EXCHANGE_RUNNERS_UP]
    known = [selection.model([*others, r]) for r, _ in tried]
    missing = [task(r, held, start=start) for (r, start), model in zip(tried, known) if model is None]
    before = held.heldout.per_window if held else nominal_gap.per_window
    fitted = fit(missing, len(selection.accepted), before) if missing else []
    fitted = [r if r.failure else best_form(r, t, before) for r, t in zip(fitted, missing)]
    results = [model for model in known if model is not None] + fitted
    return [r for r in results if not r.failure and not _null(r, scales)]


def _beyond_parsimony(new: str, out: str, result: FitResult, final: FitResult, nominal_gap, bootstrap) -> bool:
    """Whether ``new`` may replace ``out``: an effect of another law always may; a variant of ``out``'s law with
    more parameters only when the model holding it reduces the nominal held-out gap by more than ``PARSIMONY``
    beyond ``final`` (the rule prefers the simpler law within it, as at entry)."""
    if new not in law_of(out) or n_params(new) <= n_params(out):
        return True
    nominal = nominal_gap.per_window
    gain = bootstrap.evidence(nominal, result.heldout.per_window).reduction
    return gain - bootstrap.evidence(nominal, final.heldout.per_window).reduction > PARSIMONY


def _prefer_gain(selection: Selection, bootstrap: Bootstrap, nominal_gap: GapResult, task, fit) -> bool:
    """Replace a kept inertia error by a torque gain when the model holding the gain in its place (fitted beside the
    other kept effects, from the gain the inertia scales' mean stands for) explains the held-out data as well: the
    ``CONFUSABLE_LEVEL`` interval of the difference of the two models' reductions of the nominal gap reaches 0 (or
    the gain's is the larger), and the gain earns its place beside the other kept effects as the inertia error did
    (:func:`~furuta_drake.diagnosis.selection.rule.decide`). A gain g of the drive is exactly a uniform scaling of
    the inertias and gravity by 1 / g (friction then reads as its true size over g), so one parameter explains what
    four do; the two are stated as a confusable pair when that interval holds 0 (a lab acts on them differently:
    the amplifier or the rig file's masses). Returns whether the gain replaced the inertia error."""
    final = selection.final
    if final is None or INERTIA not in selection.accepted or GAIN in selection.accepted:
        return False
    others = [name for name in selection.accepted if name != INERTIA]
    held = selection.model(others) if others else None
    if others and held is None:
        return False
    gain = selection.model([*others, GAIN])
    if gain is None:
        start = Effect("", (1.0 / float(np.mean(final.effects[INERTIA].values)),))
        gain = next(iter(fit([task(GAIN, held, start=start)], len(selection.accepted), nominal_gap.per_window)))
    if gain.failure:
        return False
    nominal = nominal_gap.per_window
    reductions = [bootstrap.evidence(nominal, model.heldout.per_window).reduction for model in (gain, final)]
    low, high = bootstrap.difference_interval(nominal, gain.heldout.per_window, final.heldout.per_window)
    reference = held.heldout.per_window if held else nominal
    kept = decide(bootstrap.evidence(reference, gain.heldout.per_window), first=not others)
    simpler = high >= 0.0 and kept  # (a gain the backward pass would drop beside the others replaces nothing)
    if low <= 0.0 <= high:
        selection.confusable = [p for p in selection.confusable if set(p["effects"]) != {GAIN, INERTIA}]
        if simpler:
            pair = confusable_pair((GAIN, INERTIA), reductions, (low, high))
        else:
            pair = confusable_pair((INERTIA, GAIN), reductions[::-1], (-high, -low))
        selection.confusable.append(pair)
    if not simpler:
        return False
    selection.accepted = others + [GAIN]
    selection.runners_up[GAIN] = [(INERTIA, final.effects[INERTIA])]
    evidence = bootstrap.evidence(final.heldout.per_window, gain.heldout.per_window)
    selection.exchanges.append({"out": INERTIA, "in": GAIN, "evidence": evidence, "simpler": True})
    return True


def _enter_pair(
    fitted: dict[str, FitResult],
    task: Callable,
    fit: Callable,
    selection: Selection,
    scales,
) -> list[str] | None:
    """Two effects that enter together when neither enters alone: each masks the other, so that alone neither
    fit reduces the held-out gap (an inertia error beside a spring, say). The ``PAIR_ENTRY`` candidates with the
    lowest train gap (of different laws) are fitted together in pairs, each from its single fit; the pair with
    the largest reduction enters when the lower bound of that reduction exceeds ``ENTRY``, its better single fit
    first. The backward pass then judges each of the two against the model holding the other."""
    ranked = sorted(fitted, key=lambda name: fitted[name].train_gap)
    best = []
    for name in ranked:
        if not any(law_of(name) & law_of(other) for other in best):
            best.append(name)
        if len(best) == PAIR_ENTRY:
            break
    pairs = [(first, second) for i, first in enumerate(best) for second in best[i + 1 :]]
    joint = [
        r
        for r in fit([task(second, fitted[first]) for first, second in pairs])
        if not r.failure and not any(CANDIDATES[name].is_null(effect, scales) for name, effect in r.effects.items())
    ]
    if not joint:
        return None
    winner = max(joint, key=lambda r: selection.over_previous[r.name].reduction)
    if selection.over_previous[winner.name].lower_bound <= ENTRY:
        return None
    return sorted(winner.effects, key=lambda name: fitted[name].train_gap)


def _backward(
    selection: Selection,
    bootstrap: Bootstrap,
    nominal_gap: GapResult,
    task: Callable,
    fit: Callable,
    scales=None,
) -> None:
    """Drop, one at a time, the kept effect whose removal costs the least while that cost's lower bound is not
    enough (:func:`~furuta_drake.diagnosis.selection.rule.decide`): every effect finally kept reduces the held-out gap
    of the model holding all the others by the rule's margin (an effect that entered beside a stronger one it
    masked must earn its place). An effect that later refits shrank to zero size (a lag that stood in for effects
    entered after it) is dropped first: it removes nothing. The model without an effect is the others refitted
    together, from the final model's values, when the selection did not fit it on the way."""
    while selection.accepted:
        final = selection.final
        null = [name for name in selection.accepted if scales and CANDIDATES[name].is_null(final.effects[name], scales)]
        without = {}
        for name in selection.accepted:
            others = [other for other in selection.accepted if other != name]
            model = selection.model(others) if others else None
            if others and model is None:
                model = _refit_subset(final, others, task, fit, nominal_gap)
            # (a model without it that failed to fit leaves the effect judged against the nominal model)
            reference = model.heldout.per_window if model else nominal_gap.per_window
            without[name] = bootstrap.evidence(reference, final.heldout.per_window)
        failing = null or [name for name in selection.accepted if not decide(without[name])]
        if not failing:
            break
        dropped = min(failing, key=lambda name: without[name].lower_bound)
        selection.accepted.remove(dropped)
        if (
            selection.accepted
            and selection.final is None
            and not _refit_subset(final, selection.accepted, task, fit, nominal_gap)
        ):
            selection.accepted = [name for name in final.effects if name in selection.accepted or name == dropped]
            break  # (the model without it failed to fit: it stays)
    selection.over_others = {name: without[name] for name in selection.accepted}
    for k in range(1, len(selection.accepted)):  # the report's steps: every earlier set of the kept effects
        if selection.model(selection.accepted[:k]) is None:
            _refit_subset(selection.final, selection.accepted[:k], task, fit, nominal_gap)
    models = [nominal_gap] + [model.heldout for model in selection.step_models]
    selection.over_step = [
        bootstrap.evidence(before.per_window, after.per_window) for before, after in zip(models[:-1], models[1:])
    ]
    selection.confusable = [pair for pair in selection.confusable if pair["effects"][0] in selection.accepted]


def _refit_subset(final: FitResult, names: list[str], task: Callable, fit: Callable, nominal_gap) -> FitResult | None:
    """The model holding ``names`` (some of the final model's effects) fitted together, every one started from its
    value in ``final``, recorded in the selection by ``fit``; None when the fit failed."""
    earlier = names[:-1]
    held = FitResult(
        "+".join(earlier),
        {name: final.effects[name] for name in earlier},
        float("nan"),
        None,
        samples={name: final.samples[name] for name in earlier if name in final.samples},
    )
    tasks = [task(names[-1], held if earlier else None, start=final.effects[names[-1]])]
    return next((r for r in fit(tasks, len(names), nominal_gap.per_window) if not r.failure), None)


def _refit_forms(result: FitResult, task: FitTask, run: Callable) -> FitResult:
    """``result`` (an accepted model with earlier effects) fitted again with every other form of its earlier
    effects that have several (their form was chosen before the new effect was there to share the residual);
    the form with the lowest train excess (the gap before its clip at the floor) is kept."""
    tasks, scales = [], scales_of(task.logs, task.model)
    for name, effect in task.fixed.items():
        if not CANDIDATES[name].fit:  # a sensor effect's form is read from the data, not fitted
            continue
        for form in CANDIDATES[name].forms:
            if form.name != effect.form:
                tasks.append(dataclasses.replace(task, fixed={**task.fixed, name: in_form(name, effect, form, scales)}))
    if not tasks:
        return result
    fits = [fit for fit in (_as_fit(t, r) for t, r in zip(tasks, run(fit_task, tasks))) if not fit.failure]
    return min([result] + fits, key=lambda fit: fit.train_excess)


def in_form(name: str, effect: Effect, form, scales) -> Effect:
    """``effect`` in another ``form`` of its candidate: the parameters both forms have keep their values, the
    others take the form's first start."""
    old = dict(zip(CANDIDATES[name].form(effect.form).params, effect.values))
    return Effect(form.name, tuple(old.get(param, start) for param, start in zip(form.params, form.starts(scales)[0])))


def _as_fit(task: FitTask, result) -> FitResult:
    """A task's result, a failed one as a FitResult with its reason."""
    if isinstance(result, Failure):
        return FitResult(task.name, {}, float("nan"), None, failure=result.reason)
    return result
