"""``furuta-drake diagnose`` as one function, :func:`diagnose`: load -> split into train and held-out data ->
windows -> select effects one step at a time (fit on train, the held-out rule) -> detection limits -> replay in
Drake -> localise, returning a :class:`~furuta_drake.diagnosis.result.Diagnosis`
(:func:`~furuta_drake.diagnosis.report.write_report` writes it; ``docs/diagnose.md`` explains every figure).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Callable

import numpy as np

from furuta_drake.config import SimulationConfig
from furuta_drake.diagnosis.candidates import (
    CANDIDATES, Effect, apply_effects, describe, law_of, rig_model,
)
from furuta_drake.diagnosis.detection import detection_limits
from furuta_drake.diagnosis.fit import FitResult, FitTask, fit_task, interval, scales_of
from furuta_drake.diagnosis.gap import (
    GapResult, evaluate_gap, gap_metric_definition, horizon_seconds, make_windows, window_residuals, window_samples,
)
from furuta_drake.diagnosis.localize import localize
from furuta_drake.diagnosis.log_format import LogFormat
from furuta_drake.diagnosis.log_format import LogFormat
from furuta_drake.diagnosis.logs import RunLog, ignored_columns_note, load_logs, load_rig
from furuta_drake.diagnosis.parallel import Failure, run_tasks
from furuta_drake.diagnosis.replay import model_actuator, model_rig, replay_gaps
from furuta_drake.diagnosis.report import effect_curve, input_record
from furuta_drake.diagnosis.result import (
    Artifacts, Consistency, Diagnosis, GapFigures, RankedCandidate, Step,
)
from furuta_drake.diagnosis.select import (
    CLOSES, ENTRY, MARGIN, Bootstrap, Evidence, choose, confusable, threshold_note,
)
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.diagnosis.surrogate import Model
from furuta_drake.friction import FrictionParameters
from furuta_drake.rig import RigParameters

HOLDOUT_FRACTION = 0.3
HOLDOUT_BLOCKS = 10
MIN_BLOCK_S = 1.0  # [s]: three or more gap windows per block
MIN_BLOCKS = 3
STATIC_EXCESS = 0.1  # a Stribeck fit whose static level is within 10 % of its Coulomb level has no Stribeck part
UNCERTAINTY = ("95 % intervals from a block bootstrap over the fit's train windows (a window is a block), "
               "linearised at the fit: one Gauss-Newton step per resample; quantisation is read exactly, noise "
               "is bootstrapped over blocks of second differences")


def _cut(log: RunLog, edges: list[int], held: set[int]) -> tuple[list[RunLog], list[RunLog]]:
    """``log`` cut at sample ``edges`` into blocks: (train blocks, held-out blocks ``held``), each named with its
    times."""
    train, heldout = [], []
    for k, (first, last) in enumerate(zip(edges[:-1], edges[1:])):
        part = dataclasses.replace(
            log, name=f"{log.name} (t = {log.time[first]:.2f}-{log.time[last - 1]:.2f} s)",
            time=log.time[first:last], theta=log.theta[first:last], phi=log.phi[first:last],
            input=log.input[first:last])
        (heldout if k in held else train).append(part)
    return train, heldout


def _blocks(log: RunLog) -> int:
    return min(HOLDOUT_BLOCKS, int(log.time.size * log.sample_period / MIN_BLOCK_S))


def _held_out_blocks(blocks: int) -> set[int]:
    """Which of ``blocks`` equal blocks are held out: HOLDOUT_FRACTION of them, spread evenly (1, 4, 8 of 10)."""
    held = max(1, round(HOLDOUT_FRACTION * blocks))
    return {int(round((i + 0.5) * blocks / held - 0.5)) for i in range(held)}


def split_heldout(logs: list[RunLog]) -> tuple[list[RunLog], list[RunLog], str]:
    """Without --heldout: every log is cut into up to HOLDOUT_BLOCKS equal blocks of at least MIN_BLOCK_S and
    HOLDOUT_FRACTION of the blocks, spread over the run, are held out, so train and held-out data both see every
    phase of it (the tail of a swing-up log is only balancing). A log too short for MIN_BLOCKS blocks holds
    out its last HOLDOUT_FRACTION."""
    train, heldout = [], []
    for log in logs:
        blocks = _blocks(log)
        if blocks < MIN_BLOCKS:
            edges, held = [0, int(log.time.size * (1.0 - HOLDOUT_FRACTION)), log.time.size], {1}
        else:
            edges, held = np.linspace(0, log.time.size, blocks + 1).astype(int).tolist(), _held_out_blocks(blocks)
        parts = _cut(log, edges, held)
        train, heldout = train + parts[0], heldout + parts[1]
    return train, heldout, (
        f"no --heldout logs: each train log was cut into up to {HOLDOUT_BLOCKS} equal blocks of at least "
        f"{MIN_BLOCK_S:g} s and {HOLDOUT_FRACTION:.0%} of them, spread over the run, were held out and never used "
        f"for fitting (a log shorter than {MIN_BLOCKS} blocks held out its last {HOLDOUT_FRACTION:.0%}): "
        + ", ".join(log.name for log in heldout))


def fold_split(logs: list[RunLog], folds: int, fold: int, rig: RigParameters) -> tuple[list[RunLog], list[RunLog]]:
    """Split ``fold`` of ``folds``: every log cut into max(folds, up to HOLDOUT_BLOCKS) equal blocks, the blocks
    b with b mod folds == fold held out (each fold holds out other blocks, spread over every log); a log too
    short for ``folds`` blocks of one gap window each trains in every fold."""
    train, heldout = [], []
    for log in logs:
        blocks = max(folds, _blocks(log))
        if log.time.size // blocks <= sum(window_samples(log.sample_period, rig)) + window_samples(
                log.sample_period, rig)[1]:
            train.append(log)
            continue
        edges = np.linspace(0, log.time.size, blocks + 1).astype(int).tolist()
        parts = _cut(log, edges, {b for b in range(blocks) if b % folds == fold})
        train, heldout = train + parts[0], heldout + parts[1]
    return train, heldout


@dataclass
class Selection:
    """The outcome of the selection on one split of the logs: the effects kept, in the order they entered, and
    every model fitted on the way."""

    nominal: GapResult  # the nominal model on the held-out windows
    tried: list[tuple[int, FitResult]]  # every model fitted, with its step (its number of effects)
    kept: list[str] = field(default_factory=list)  # the accepted effects, in the order they entered
    over_nominal: dict[str, Evidence] = field(default_factory=dict)  # model name -> evidence over nominal
    over_previous: dict[str, Evidence] = field(default_factory=dict)  # ... over the model it was built on
    over_others: dict[str, Evidence] = field(default_factory=dict)  # kept effect -> final over final without it
    over_step: list[Evidence] = field(default_factory=list)  # each accepted step over the step before
    confusable: list[dict] = field(default_factory=list)
    at_floor: bool = False  # the nominal model explains the held-out data to within their noise

    def model(self, effects) -> FitResult | None:
        """The fitted model holding exactly ``effects`` (in any order), or None."""
        return next((r for _, r in self.tried if not r.failure and set(r.effects) == set(effects)), None)

    @property
    def accepted(self) -> list[FitResult]:
        """The model after each accepted step: holding the first 1, 2, ... kept effects."""
        return [self.model(self.kept[:k]) for k in range(1, len(self.kept) + 1)]

    @property
    def final(self) -> FitResult | None:
        return self.model(self.kept) if self.kept else None

    @property
    def closes(self) -> bool:
        return bool(self.kept) and self.over_nominal[self.final.name].reduction >= CLOSES

    @property
    def verdict(self) -> str:
        if not self.closes:
            return "none" if self.at_floor else "unexplained"
        return self.effects[0]

    @property
    def effects(self) -> list[str]:
        """The accepted effects in the order accepted (empty for none and unexplained); a Stribeck fit without
        static excess is named Coulomb friction (the vocabulary's Stribeck is static friction *above* it)."""
        if not self.closes:
            return []
        return [_vocabulary_name(name, self.final.effects[name]) for name in self.kept]


def _vocabulary_name(name: str, effect: Effect) -> str:
    if name == "arm_stribeck" and effect.values[1] <= (1.0 + STATIC_EXCESS) * effect.values[0]:
        return "arm_coulomb_friction"
    return name


def select_effects(nominal: Model, logs: list[RunLog], train, heldout, counts: int, names: list[str],
                   settings: DiagnosisSettings, run: Callable) -> Selection:
    """Select up to ``settings.max_effects`` effects under the held-out rule (:mod:`furuta_drake.diagnosis.select`):
    forward, one at a time, each fitted together with the earlier ones and entering when it reduces the gap of
    the model holding them; then backward, each kept only while the model without it is worse by the rule."""
    bootstrap = Bootstrap(heldout.count, settings.bootstrap, settings.seed)
    nominal_gap = evaluate_gap(nominal, heldout, counts)
    selection = Selection(nominal_gap, [], at_floor=bootstrap.at_floor(nominal_gap.per_window))

    def fit(tasks, step, previous):
        results = [_as_fit(task, result) for task, result in zip(tasks, run(fit_task, tasks))]
        for result in results:
            selection.tried.append((step, result))
            if not result.failure:
                selection.over_nominal[result.name] = bootstrap.evidence(nominal_gap.per_window,
                                                                         result.heldout.per_window)
                selection.over_previous[result.name] = bootstrap.evidence(previous, result.heldout.per_window)
        return results

    def task(new, held):
        return FitTask(new=new, fixed=held.effects if held else {}, model=nominal, train=train, heldout=heldout,
                       logs=tuple(logs), nominal_counts=counts, settings=settings,
                       fixed_samples=held.samples if held else {})

    for step in range(1, settings.max_effects + 1):
        held = selection.final
        previous = held.heldout.per_window if held else nominal_gap.per_window
        if step > 1 and bootstrap.at_floor(previous):
            break
        pool = [name for name in names if not law_of(name) & set(selection.kept)]
        fitted = {r.name: r for r in fit([task(name, held) for name in pool], step, previous) if not r.failure}
        if selection.at_floor:
            break
        evidence = {name: selection.over_previous[name] for name in fitted}
        added = {name: name.split("+")[-1] for name in fitted}
        chosen = choose(evidence, added, margin=ENTRY)
        if chosen is None:
            break
        refitted = _refit_forms(fitted[chosen], task(added[chosen], held), run)
        if refitted is not fitted[chosen]:
            selection.tried = [(s, refitted if r is fitted[chosen] else r) for s, r in selection.tried]
            fitted[chosen] = refitted
            selection.over_nominal[chosen] = bootstrap.evidence(nominal_gap.per_window, refitted.heldout.per_window)
            evidence[chosen] = selection.over_previous[chosen] = bootstrap.evidence(previous,
                                                                                     refitted.heldout.per_window)
        per_window = {name: result.heldout.per_window for name, result in fitted.items()}
        selection.confusable += confusable(chosen, evidence, added, previous, per_window, bootstrap)
        selection.kept.append(added[chosen])
    _backward(selection, bootstrap, nominal_gap, task, fit)
    return selection


def _backward(selection: Selection, bootstrap: Bootstrap, nominal_gap: GapResult, task: Callable, fit: Callable
              ) -> None:
    """Drop, one at a time, the kept effect whose removal costs the least while that cost's lower bound is not
    above ``MARGIN``: every effect finally kept reduces the held-out gap of the model holding all the others by
    the rule's margin (an effect that entered beside a stronger one it masked must earn its place)."""
    while selection.kept:
        final = selection.final
        without = {}
        for name in selection.kept:
            others = [other for other in selection.kept if other != name]
            model = selection.model(others) if others else None
            if others and model is None:
                held = selection.model(others[:-1]) if len(others) > 1 else None
                model = next((r for r in fit([task(others[-1], held)], len(others),
                                                   held.heldout.per_window if held else nominal_gap.per_window)
                              if not r.failure), None)
            # (a model without it that failed to fit leaves the effect judged against the nominal model)
            reference = model.heldout.per_window if model else nominal_gap.per_window
            without[name] = bootstrap.evidence(reference, final.heldout.per_window)
        weakest = min(selection.kept, key=lambda name: without[name].lower_bound)
        if without[weakest].lower_bound > MARGIN:
            break
        selection.kept.remove(weakest)
    selection.over_others = {name: without[name] for name in selection.kept}
    models = [nominal_gap] + [model.heldout for model in selection.accepted]
    selection.over_step = [bootstrap.evidence(before.per_window, after.per_window)
                           for before, after in zip(models[:-1], models[1:])]
    selection.confusable = [pair for pair in selection.confusable if pair["effects"][0] in selection.kept]


def _refit_forms(result: FitResult, task: FitTask, run: Callable) -> FitResult:
    """``result`` (an accepted model with earlier effects) fitted again with every other form of its earlier
    effects that have several (their form was chosen before the new effect was there to share the residual);
    the form with the lowest train gap is kept."""
    tasks, scales = [], scales_of(task.logs, task.model)
    for name, effect in task.fixed.items():
        for form in CANDIDATES[name].forms:
            if form.name != effect.form:
                tasks.append(dataclasses.replace(task, fixed={**task.fixed, name: _in_form(name, effect, form,
                                                                                             scales)}))
    if not tasks:
        return result
    fits = [fit for fit in (_as_fit(t, r) for t, r in zip(tasks, run(fit_task, tasks))) if not fit.failure]
    return min([result] + fits, key=lambda fit: fit.train_gap)


def _in_form(name: str, effect: Effect, form, scales) -> Effect:
    """``effect`` in another ``form`` of its candidate: the parameters both forms have keep their values, the
    others take the form's first start."""
    old = dict(zip(CANDIDATES[name].form(effect.form).params, effect.values))
    return Effect(form.name, tuple(old.get(param, start) for param, start in zip(form.params,
                                                                              form.starts(scales)[0])))


def _as_fit(task: FitTask, result) -> FitResult:
    """A task's result, a failed one as a FitResult with its reason."""
    if isinstance(result, Failure):
        return FitResult(task.name, {}, float("nan"), None, failure=result.reason)
    return result


def choice_text(selection: Selection) -> str:
    """Why the verdict, in one paragraph."""
    if not selection.kept:
        if selection.at_floor:
            return "The nominal model explains the held-out data to within their noise: no effect is needed."
        return ("No candidate, nor set of up to three, reduces the nominal model's held-out gap by the rule's "
                "margin.")
    total = selection.over_nominal[selection.final.name]
    text = (f"The model holding {', '.join(selection.kept)} reduces the nominal held-out gap by {total.reduction:.1%} "
            f"(5 % lower bound {total.lower_bound:.1%}). ")
    if len(selection.kept) > 1:
        text += "Without each of them the held-out gap of the others' model grows: " + "; ".join(
            f"{name} brings {selection.over_others[name].reduction:.1%} (lower bound "
            f"{selection.over_others[name].lower_bound:.1%})" for name in selection.kept) + "."
    if not selection.closes:
        text += f" That is less than the {CLOSES:.0%} that explains it: the gap is unexplained."
    for pair in selection.confusable:
        text += (f" {pair['effects'][1]} explains the held-out data as well as {pair['effects'][0]} "
                 f"({pair['why']}); {pair['effects'][0]} was accepted for its larger point reduction or fewer "
                 f"parameters.")
    return text


def nominal_config(rig: RigParameters, model: Model) -> SimulationConfig:
    """The Drake model of ``model`` (a diagnosis model of ``rig``) as a simulate config, open loop: users add
    their controller."""
    config = SimulationConfig.from_rig(model_rig(model, rig).replace(motor=rig.motor, effects=None))
    return dataclasses.replace(
        config,
        friction=FrictionParameters(arm=model.arm_friction, pendulum=model.pendulum_friction),
        actuator=dataclasses.replace(model_actuator(model), delay=model.delay),
        disturbance=dataclasses.replace(config.disturbance, arm_spring_stiffness=model.spring_stiffness,
                                        arm_spring_equilibrium=model.spring_equilibrium),
        encoder=dataclasses.replace(config.encoder, counts_per_rev=model.counts_per_rev,
                                    noise_std=model.noise_std))


def fitted_rig(rig: RigParameters, effects: dict[str, Effect], nominal: Model) -> RigParameters:
    """The rig file with the accepted effects added to (or replacing those of) its ``effects:`` section."""
    stated = dict(rig.effects or {})
    for name, effect in effects.items():
        params = describe(name, effect, nominal)
        stated[name] = {key: value for key, value in params.items()
                        if key == "form" or key in CANDIDATES[name].form(effect.form).params}
    return rig.replace(effects=stated or None)


def _params(result: FitResult, nominal: Model) -> tuple[dict, dict]:
    """The ranking's params and params_ci of a fitted model (prefixed 'effect.' when it holds several)."""
    params, intervals = {}, {}
    several = len(result.effects) > 1
    for name, effect in result.effects.items():
        prefix = f"{name}." if several else ""
        params.update({prefix + k: v for k, v in describe(name, effect, nominal).items()})
        samples = result.samples.get(name)
        if samples is None or samples.size == 0:
            continue
        described = [describe(name, Effect(effect.form, tuple(row)), nominal) for row in samples]
        for key, value in described[0].items():
            if key != "form":
                intervals[prefix + key] = list(interval(np.array([d[key] for d in described])))
    return params, intervals


def ranking(selection: Selection, nominal: Model) -> list[RankedCandidate]:
    """Every model tried, best first by its held-out reduction over the nominal model; failed ones last."""
    rows = []
    for step, result in selection.tried:
        if result.failure:
            rows.append(RankedCandidate(result.name, {}, None, None, None, step=step, status="failed",
                                        reason=result.failure))
            continue
        params, intervals = _params(result, nominal)
        over_nominal, over_previous = selection.over_nominal[result.name], selection.over_previous[result.name]
        rows.append(RankedCandidate(
            result.name, params, over_nominal.heldout_gap, over_nominal.reduction, over_nominal.lower_bound,
            params_ci=intervals, step=step, reduction_over_previous=over_previous.reduction,
            evidence_over_previous=over_previous.lower_bound, train_gap=result.train_gap,
            at_bounds=result.at_bounds))
    ok = [row for row in rows if row.status == "ok"]
    excess = {result.name: selection.over_nominal[result.name].excess for _, result in selection.tried
              if not result.failure}
    ok.sort(key=lambda row: (-row.heldout_reduction, excess[row.effect], row.step, row.effect))
    return ok + [row for row in rows if row.status != "ok"]


def consistency(logs: list[RunLog], rig: RigParameters, nominal: Model, names: list[str],
                settings: DiagnosisSettings, run: Callable, folds: int) -> Consistency:
    """The selection repeated on ``folds`` splits of all the logs (:func:`fold_split`): each fold's verdict and
    effects, the range of each accepted effect's parameters over the folds that accepted it, and a judgement."""
    verdicts, effects, values = [], [], {}
    for fold in range(folds):
        train, heldout = fold_split(logs, folds, fold, rig)
        selection = select_effects(nominal, train, make_windows(train, rig), make_windows(heldout, rig),
                                   rig.counts_per_rev, names, settings, run)
        verdicts.append(selection.verdict)
        effects.append(selection.effects)
        if selection.effects:
            for name, effect in selection.final.effects.items():
                for key, value in describe(name, effect, nominal).items():
                    if key != "form":
                        values.setdefault(f"{name}.{key}", []).append(value)
    ranges = {key: [float(min(v)), float(max(v))] for key, v in values.items()}
    return Consistency(folds, verdicts, effects, ranges, judgement(verdicts, effects, ranges, nominal))


def judgement(verdicts: list[str], effects: list[list[str]], ranges: dict[str, list[float]], nominal: Model
              ) -> str:
    """One line: how often the verdict and each effect came back, and the spread of the main parameters."""
    folds = len(verdicts)
    counts = {verdict: verdicts.count(verdict) for verdict in dict.fromkeys(verdicts)}
    if len(counts) == 1:
        text = f"same verdict ({verdicts[0]}) on {folds}/{folds} folds"
    else:
        text = "verdict " + ", ".join(f"{verdict} on {n}/{folds}" for verdict, n in counts.items()) + " folds"
    named = {name: sum(name in found for found in effects) for found in effects for name in found}
    if named and any(n < folds for n in named.values()):
        text += "; effects " + ", ".join(f"{name} {n}/{folds}" for name, n in named.items())
    mains = [f"{name} {CANDIDATES[name].main} {low:.4g}-{high:.4g}" for key, (low, high) in ranges.items()
             for name in [key.split(".")[0]] if key.split(".")[1] == CANDIDATES[name].main]
    return text + ("; " + ", ".join(mains) if mains else "")


def diagnose(*, rig: str | Path, train: list, heldout: list = (), candidates: list[str] | None = None,
             settings: DiagnosisSettings = DiagnosisSettings(), folds: int | None = None, workers: int | None = None,
             scheduler: str | None = None, progress: Callable | None = None,
             log_format: LogFormat = LogFormat()) -> Diagnosis:
    """Diagnose the gap between the rig file's nominal model and the logs.

    Parameters
    ----------
    rig : the rig file (``docs/diagnose.md``: bodies, encoder, limits, optional friction, motor and effects).
    train : logs the candidates are fitted on; heldout : logs every held-out figure uses (default: blocks of
        ``train`` held out, :func:`split_heldout`).
    candidates : the effects to try (default: the whole vocabulary).
    settings : sizes and seeds (:class:`DiagnosisSettings`); folds : with K >= 2, the decision is repeated on K
        splits of all logs and ``consistency`` reported.
    workers : processes (default: all cores); scheduler : address of a Dask scheduler that runs the fits instead;
        progress : called with each finished task; log_format : column mapping and units of the logs.
    """
    settings.validate()
    rig_path = Path(rig)
    rig_params = load_rig(rig_path)
    train_logs = load_logs(train, rig_params, rig_path, log_format)
    heldout_logs = load_logs(heldout, rig_params, rig_path, log_format) if heldout else []
    notes = [note for note in [ignored_columns_note(train_logs + heldout_logs)] if note]
    if heldout_logs:
        fit_logs, test_logs = train_logs, heldout_logs
        holdout_note = "held-out logs: " + ", ".join(log.name for log in heldout_logs)
    else:
        fit_logs, test_logs, holdout_note = split_heldout(train_logs)
    names = list(candidates or CANDIDATES)
    unknown = [name for name in names if name not in CANDIDATES]
    if unknown:
        from furuta_drake.errors import ConfigError
        raise ConfigError(f"unknown candidate effect {', '.join(unknown)} (the vocabulary: {', '.join(CANDIDATES)})")
    counts = rig_params.counts_per_rev
    nominal = rig_model(rig_params)
    train_windows, heldout_windows = make_windows(fit_logs, rig_params), make_windows(test_logs, rig_params)
    run = partial(run_tasks, workers=workers, scheduler=scheduler, done=progress)
    selection = select_effects(nominal, fit_logs, train_windows, heldout_windows, counts, names, settings, run)
    final = selection.final if selection.effects else None
    accepted_model = apply_effects(nominal, final.effects) if final else nominal
    bootstrap = Bootstrap(heldout_windows.count, settings.bootstrap, settings.seed)

    limits = []
    if settings.detection_limits:
        limits = detection_limits(accepted_model, list(final.effects) if final else [], heldout_windows,
                                  scales_of(fit_logs, nominal), counts, bootstrap, settings.seed)

    # The headline held-out figures come from Drake diagrams of the project's systems (the surrogate's when a
    # replay fails).
    replays = [(nominal, selection.nominal.initial_states)]
    if final:
        replays.append((accepted_model, final.heldout.initial_states))
    drake = replay_gaps(replays, rig_params, heldout_windows, workers, scheduler) if settings.replay \
        else [None] * len(replays)
    surrogate = [selection.nominal] + ([final.heldout] if final else [])
    gaps = [d if d is not None else s for d, s in zip(drake, surrogate)]
    evaluated_by = ("drake replay of the held-out windows" if all(d is not None for d in drake)
                    else "surrogate (the Drake replay " + ("was not run" if not settings.replay else "failed") + ")")
    nominal_heldout, accepted_heldout = gaps[0], gaps[-1]
    train_nominal = evaluate_gap(nominal, train_windows, counts).gap
    reduction = 1.0 - accepted_heldout.gap / nominal_heldout.gap if nominal_heldout.gap > 0 else 0.0
    before = window_residuals(nominal_heldout, heldout_windows, rig_params)
    after = window_residuals(accepted_heldout, heldout_windows, rig_params) if final else None

    consistency_result = None
    if folds is not None and folds >= 2:
        consistency_result = consistency(train_logs + heldout_logs, rig_params, nominal, names, settings, run, folds)
    steps = []
    for name, result, over_step in zip(selection.kept, selection.accepted if final else [], selection.over_step):
        params, _ = _params(result, nominal)
        over_nominal, over_others = selection.over_nominal[result.name], selection.over_others[name]
        steps.append(Step(name, params, over_nominal.heldout_gap, over_nominal.reduction, over_step.reduction,
                          over_others.reduction, over_others.lower_bound))
    record = input_record(rig_path=rig_path, train=train, heldout=heldout,
                          seeds={"bootstrap": settings.seed, "fit_windows": settings.seed},
                          options={"workers": workers, "scheduler": scheduler, "holdout": holdout_note,
                                   "candidates": names, "folds": folds, "settings": dataclasses.asdict(settings),
                                   "log_format": log_format.record()})
    curves = [effect_curve(name, describe(name, effect, nominal), rig_params)
              for name, effect in (final.effects.items() if final else [])]
    artifacts = Artifacts(before, after, nominal_heldout.sensor_variance, curves,
                          fitted_config=nominal_config(rig_params, accepted_model),
                          fitted_rig=fitted_rig(rig_params, final.effects if final else {}, nominal), record=record)
    return Diagnosis(
        verdict=selection.verdict, effects=selection.effects,
        gap=GapFigures(gap_metric_definition(horizon_seconds(rig_params)),
                       {"train": train_nominal, "heldout": nominal_heldout.gap},
                       {"train": final.train_gap if final else train_nominal, "heldout": accepted_heldout.gap},
                       reduction, nominal_heldout.per_signal, evaluated_by),
        ranking=ranking(selection, nominal),
        localization=localize(before, after, noise_variance=nominal_heldout.sensor_variance,
                              noise_variance_after=accepted_heldout.sensor_variance),
        steps=steps, uncertainty=UNCERTAINTY, detection_limits=limits, confusable=selection.confusable,
        consistency=consistency_result, choice=choice_text(selection), holdout=holdout_note,
        rule=threshold_note(settings.bootstrap, settings.seed), notes=notes, artifacts=artifacts)
