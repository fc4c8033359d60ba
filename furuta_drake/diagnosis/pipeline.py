"""``furuta-drake diagnose`` as one function, :func:`diagnose`: load -> split into train and held-out data ->
windows -> select effects (fit on train, the held-out rule) -> detection limits -> replay in Drake -> localise,
returning a :class:`~furuta_drake.diagnosis.result.Diagnosis` (:func:`~furuta_drake.diagnosis.report.files.write_report`
writes it; ``docs/diagnose.md`` explains every figure).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from functools import partial
from pathlib import Path

import numpy as np

from furuta_drake.diagnosis.gap.localize import localize
from furuta_drake.diagnosis.gap.metric import (
    Windows,
    evaluate_gap,
    gap_metric_definition,
    horizon_seconds,
    make_windows,
    window_residuals,
)
from furuta_drake.diagnosis.gap.per_log import heldout_rms_per_log
from furuta_drake.diagnosis.gap.replay import replay_gaps
from furuta_drake.diagnosis.gap.split import split_heldout
from furuta_drake.diagnosis.logs.format import LogFormat
from furuta_drake.diagnosis.logs.load import RunLog, ignored_columns_note, load_logs
from furuta_drake.diagnosis.report.files import effect_curve, input_record
from furuta_drake.diagnosis.report.record_text import choice_text, confusable_why, consistency_judgement, rule_text
from furuta_drake.diagnosis.report.torque import beside_record, torque_record
from furuta_drake.diagnosis.result import Artifacts, Diagnosis, GapFigures, RankedCandidate, Step
from furuta_drake.diagnosis.selection.detection import detection_limits
from furuta_drake.diagnosis.selection.disturbance import equivalent_disturbance
from furuta_drake.diagnosis.selection.final_fit import refit_final
from furuta_drake.diagnosis.selection.fit import FitResult, FitTask, fit_task, interval, scales_of
from furuta_drake.diagnosis.selection.folds import consistency, pinned
from furuta_drake.diagnosis.selection.missing_torque import beyond_vocabulary
from furuta_drake.diagnosis.selection.remaining import remaining_record
from furuta_drake.diagnosis.selection.reselection import reselect_beside_torque
from furuta_drake.diagnosis.selection.rival import form_rival_tasks, widen
from furuta_drake.diagnosis.selection.rule import Bootstrap
from furuta_drake.diagnosis.selection.sensor import SensorFinding
from furuta_drake.diagnosis.selection.stepwise import Selection, select_effects
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects.corrected import fitted_rig, model_config
from furuta_drake.effects.surrogate import Model, load_kernel
from furuta_drake.effects.torque_library import library_terms, merged, torque_parameters_of
from furuta_drake.effects.vocabulary import CANDIDATES, Effect, apply_effects, describe, rig_model
from furuta_drake.errors import ConfigError
from furuta_drake.parallel import Failure, TaskPool, one_blas_thread, run_tasks
from furuta_drake.rig import RigParameters
from furuta_drake.rig_file import load_rig
from furuta_drake.yamlio import locate_in_file

UNCERTAINTY = (
    "95 % intervals from a block bootstrap over the fit's train windows (a window is a block; the accepted "
    "model's refit: every train window), "
    "linearised at the fit: one Gauss-Newton step per resample; quantisation is read exactly, noise "
    "is bootstrapped over blocks of second differences; the accepted model's intervals also span the move of "
    "its parameters when the strongest candidate not accepted is fitted beside it (an effect below the "
    "detection limits may act)"
)


def _params(result: FitResult, nominal: Model) -> tuple[dict, dict, dict]:
    """The ranking's params, params_ci and at_bound of a fitted model (prefixed 'effect.' when it holds several):
    a parameter fitted at an end of its search range has no interval (its bootstrap piles up on the bound)."""
    params, intervals = {}, {}
    several = len(result.effects) > 1
    bounded = {label.rsplit(" ", 1)[0]: label.rsplit(" ", 1)[1].strip("()") for label in result.at_bounds}
    at_bound = {}
    for name, effect in result.effects.items():
        prefix = f"{name}." if several else ""
        params.update({prefix + k: v for k, v in describe(name, effect, nominal).items()})
        at_bound.update(
            {prefix + label.split(".", 1)[1]: end for label, end in bounded.items() if label.startswith(f"{name}.")}
        )
        samples = result.samples.get(name)
        if samples is None or samples.size == 0:
            continue
        described = [describe(name, Effect(effect.form, tuple(row)), nominal) for row in samples]
        for key in described[0]:
            if key != "form" and prefix + key not in at_bound:
                intervals[prefix + key] = list(interval(np.array([d[key] for d in described])))
    return params, intervals, at_bound


def _sensor_params(finding: SensorFinding, nominal: Model) -> tuple[dict, dict]:
    """The params and params_ci of a sensor effect read from the data."""
    params = describe(finding.name, finding.effect, nominal)
    intervals = {}
    if finding.samples.size:
        described = [
            describe(finding.name, Effect(finding.effect.form, tuple(row)), nominal) for row in finding.samples
        ]
        intervals = {
            key: list(interval(np.array([d[key] for d in described]))) for key in described[0] if key != "form"
        }
    return params, intervals


def ranking(selection: Selection, nominal: Model) -> list[RankedCandidate]:
    """Every model tried, best first by its held-out reduction over the nominal model; those a step screened out
    (their values a screen's) after the fitted ones, failed ones last; then the sensor effects read beside the final
    model (their predictions are the final model's: what they claim is their ``sensor_share``, judged by their
    ``score_gain``)."""
    rows = []
    for step, result in selection.tried:
        if result.failure:
            rows.append(
                RankedCandidate(result.name, {}, None, None, None, step=step, status="failed", reason=result.failure)
            )
            continue
        params, intervals, at_bound = _params(result, nominal)
        over_nominal = selection.over_nominal[result.name]
        over_previous = selection.over_previous.get(result.name, over_nominal)
        rows.append(
            RankedCandidate(
                result.name,
                params,
                over_nominal.heldout_gap,
                over_nominal.reduction,
                over_nominal.lower_bound,
                params_ci=intervals,
                step=step,
                reduction_over_previous=over_previous.reduction,
                evidence_over_previous=over_previous.lower_bound,
                train_gap=result.train_gap,
                at_bounds=result.at_bounds,
                at_bound=at_bound,
                status="screened" if result.screened else "ok",
                reason=result.screened,
            )
        )
    excess = {
        result.name: selection.over_nominal[result.name].excess for _, result in selection.tried if not result.failure
    }
    ordered = sorted(
        (row for row in rows if row.status != "failed"),
        key=lambda row: (row.status != "ok", -row.heldout_reduction, excess[row.effect], row.step, row.effect),
    )
    return ordered + [row for row in rows if row.status == "failed"] + _sensor_rows(selection, nominal)


def _sensor_rows(selection: Selection, nominal: Model) -> list[RankedCandidate]:
    """A ranking row per sensor effect read: beside the final model (whose predictions it keeps), its parameters,
    the share of the nominal held-out mean squared excess it would account for and its held-out score."""
    base = selection.final if selection.accepted else None
    over = selection.over_nominal[base.name] if base else None
    gap = over.heldout_gap if over else selection.nominal.gap
    before = max(float(selection.nominal.per_window.mean()), 1e-12)
    rows = []
    for finding in selection.sensors:
        params, intervals = _sensor_params(finding, nominal)
        rows.append(
            RankedCandidate(
                finding.name,
                params,
                gap,
                over.reduction if over else 0.0,
                over.lower_bound if over else 0.0,
                params_ci=intervals,
                step=len(selection.accepted) + 1,
                reduction_over_previous=0.0,
                evidence_over_previous=0.0,
                sensor_share=float(np.mean(finding.claimed)) / before,
                score_gain=finding.score_gain,
                score_evidence=finding.lower_bound,
                note=finding.note,
            )
        )
    return rows


def diagnose(
    *,
    rig: str | Path,
    train: list,
    heldout: list = (),
    candidates: list[str] | None = None,
    settings: DiagnosisSettings = DiagnosisSettings(),
    folds: int | None = None,
    workers: int | None = None,
    scheduler: str | None = None,
    progress: Callable | None = None,
    log_format: LogFormat = LogFormat(),
) -> Diagnosis:
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
    # Bad input is refused before any worker process starts. One worker pool then serves every batch of tasks;
    # with --folds the folds' selections run in a thread beside the main selection, their fits filling the cores
    # its small batches leave idle.
    settings.validate()
    inputs = _inputs(Path(rig), train, heldout, candidates, log_format)
    load_kernel()  # before the workers fork: they inherit the compiled kernel
    with (
        one_blas_thread(),
        ThreadPoolExecutor(max_workers=2) as background,
        TaskPool(1 if scheduler else workers) as pool,
    ):
        return _diagnose(
            inputs=inputs,
            train=train,
            heldout=heldout,
            settings=settings,
            folds=folds,
            workers=workers,
            scheduler=scheduler,
            progress=progress,
            log_format=log_format,
            pool=pool,
            background=background,
        )


def _diagnose(
    *, inputs, train, heldout, settings, folds, workers, scheduler, progress, log_format, pool, background
) -> Diagnosis:
    """:func:`diagnose` on its checked ``inputs``, with its worker ``pool`` and ``background`` threads for the
    folds and the replays."""
    run = partial(run_tasks, workers=workers, scheduler=scheduler, done=progress, pool=pool)
    fold_check = None
    if folds is not None and folds >= 2:
        fold_check = background.submit(
            consistency, inputs.all_logs, inputs.rig, inputs.nominal, inputs.names, settings, run, folds
        )
    selection, bootstrap, missing, torque_notes = _select(inputs, settings, run)
    replay_run = partial(run_tasks, workers=workers, scheduler=scheduler, pool=pool)
    heldout_gaps, limits = _heldout_gaps(inputs, selection, settings, bootstrap, replay_run, background)
    record = input_record(
        rig_path=inputs.rig_path,
        train=train,
        heldout=heldout,
        seeds={"bootstrap": settings.seed, "fit_windows": settings.seed},
        options={
            "workers": workers,
            "scheduler": scheduler,
            "holdout": inputs.holdout_note,
            "candidates": inputs.names,
            "folds": folds,
            "settings": dataclasses.asdict(settings),
            "log_format": log_format.record(),
        },
    )
    return _diagnosis(
        inputs,
        settings,
        selection,
        bootstrap,
        heldout_gaps=heldout_gaps,
        limits=limits,
        consistency_result=_consistency(fold_check, inputs.nominal, selection.effects),
        missing=missing,
        notes=inputs.notes + torque_notes,
        record=record,
    )


@dataclass(frozen=True)
class _Inputs:
    """The checked inputs of a diagnosis: the rig file and its nominal model, the logs (``all_logs`` for the
    folds) split into the logs fitted on and their train and held-out windows, the candidate effects."""

    rig_path: Path
    rig: RigParameters
    nominal: Model
    all_logs: list[RunLog]
    train_logs: list[RunLog]
    heldout_logs: list[RunLog]
    train_windows: Windows
    heldout_windows: Windows
    holdout_note: str
    names: list[str]
    notes: list[str]  # on the logs' columns left unread


def _inputs(rig_path: Path, train, heldout, candidates, log_format: LogFormat) -> _Inputs:
    """Load and check the rig file, the logs and the candidates; split the logs and cut their windows."""
    rig_params = _diagnosable_rig(rig_path)
    given_train = load_logs(train, rig_params, rig_path, log_format)
    given_heldout = load_logs(heldout, rig_params, rig_path, log_format) if heldout else []
    notes = [note for note in [ignored_columns_note(given_train + given_heldout)] if note]
    if given_heldout:
        train_logs, heldout_logs = given_train, given_heldout
        holdout_note = "held-out logs: " + ", ".join(log.name for log in given_heldout)
    else:
        train_logs, heldout_logs, holdout_note = split_heldout(given_train)
    nominal = rig_model(rig_params)
    names = list(candidates or [name for name, candidate in CANDIDATES.items() if candidate.offered(nominal)])
    unknown = [name for name in names if name not in CANDIDATES]
    if unknown:
        raise ConfigError(f"unknown candidate effect {', '.join(unknown)} (the vocabulary: {', '.join(CANDIDATES)})")
    driveless = [name for name in names if not CANDIDATES[name].offered(nominal)]
    if driveless:
        raise ConfigError(
            f"candidate effect {', '.join(driveless)}: an effect of a drive needs the rig file's drive: section "
            f"(its gear_ratio and rotor_inertia give the rotor's inertia)"
        )
    return _Inputs(
        rig_path,
        rig_params,
        nominal,
        given_train + given_heldout,
        train_logs,
        heldout_logs,
        make_windows(train_logs, rig_params),
        make_windows(heldout_logs, rig_params),
        holdout_note,
        names,
        notes,
    )


def _diagnosable_rig(rig_path: Path) -> RigParameters:
    """The rig file; ConfigError naming its line when its torque beyond the vocabulary is not a sum of the
    library's terms (the surrogate's fits hold those alone)."""
    rig_params = load_rig(rig_path)
    try:
        library_terms(rig_params.unmodelled_torque)
    except ConfigError as err:
        raise locate_in_file(rig_path, err) from None
    return rig_params


def _select(inputs: _Inputs, settings: DiagnosisSettings, run):
    """The selection of effects, the held-out rule's bootstrap and the torque beyond the vocabulary (None when
    none passes the rule) with its notes. Without such a torque the accepted model is then refitted on every train
    window (:func:`refit_final`); a kept torque was found beside the selection's fit, which stays. Last, the kept
    friction laws are fitted in their other forms (:func:`form_rival_tasks`: the intervals' form rivals)."""
    counts = inputs.rig.counts_per_rev
    selection = select_effects(
        inputs.nominal,
        inputs.train_logs,
        inputs.train_windows,
        inputs.heldout_windows,
        counts,
        inputs.names,
        settings,
        run,
    )
    bootstrap = Bootstrap(inputs.heldout_windows.count, settings.bootstrap, settings.seed)
    missing, torque_notes = beyond_vocabulary(
        selection, inputs.nominal, inputs.train_windows, inputs.heldout_windows, counts, bootstrap, settings
    )
    selection, missing, notes = reselect_beside_torque(
        selection,
        missing,
        inputs.nominal,
        lambda base: select_effects(
            base, inputs.train_logs, inputs.train_windows, inputs.heldout_windows, counts, inputs.names, settings, run
        ),
        inputs.train_windows,
        inputs.heldout_windows,
        counts,
        bootstrap,
        settings,
    )
    if missing is None:
        selection, refit_notes = refit_final(
            selection,
            inputs.nominal,
            inputs.train_windows,
            inputs.heldout_windows,
            inputs.train_logs,
            counts,
            settings,
            bootstrap,
            run,
        )
        notes = notes + refit_notes
    template = FitTask(
        new="",
        fixed={},
        model=inputs.nominal,
        train=inputs.train_windows,
        heldout=inputs.heldout_windows,
        logs=tuple(inputs.train_logs),
        nominal_counts=counts,
        settings=settings,
        regressed=selection.regressed,
    )
    tasks = form_rival_tasks(selection, template)
    selection.form_rivals = [result for result in run(fit_task, tasks) if not isinstance(result, Failure)]
    return selection, bootstrap, missing, torque_notes + notes


def _heldout_gaps(inputs: _Inputs, selection: Selection, settings, bootstrap: Bootstrap, replay_run, background):
    """The held-out gaps of the nominal and the accepted model with what evaluated them, and the detection limits.

    The headline held-out figures come from Drake diagrams of the project's systems (the surrogate's when a
    replay fails); the replays run on the workers while this process finds the detection limits."""
    final = _final(selection)
    accepted_model = _accepted_model(inputs.nominal, final)
    replays = [(inputs.nominal, selection.nominal.initial_states)]
    if final:
        replays.append((accepted_model, final.heldout.initial_states))
    replaying = (
        background.submit(replay_gaps, replays, inputs.rig, inputs.heldout_windows, replay_run)
        if settings.replay
        else None
    )
    limits = []
    if settings.detection_limits:
        limits = detection_limits(
            accepted_model,
            (list(final.effects) if final else []) + [f.name for f in selection.sensor_effects if selection.closes],
            inputs.heldout_windows,
            scales_of(inputs.train_logs, inputs.nominal),
            inputs.rig.counts_per_rev,
            selection.rule_bootstrap(bootstrap),
            settings.seed,
        )
    drake = replaying.result() if replaying is not None else [None] * len(replays)
    surrogate = [selection.nominal] + ([final.heldout] if final else [])
    gaps = [d if d is not None else s for d, s in zip(drake, surrogate)]
    evaluated_by = (
        "drake replay of the held-out windows"
        if all(d is not None for d in drake)
        else "surrogate (the Drake replay " + ("was not run" if not settings.replay else "failed") + ")"
    )
    return (gaps[0], gaps[-1], evaluated_by), limits


def _final(selection: Selection):
    """The selection's final fit, None when it kept no effect."""
    return selection.final if selection.effects else None


def _accepted_model(nominal: Model, final) -> Model:
    """The nominal model with the final fit's effects (the nominal one without a final fit)."""
    return apply_effects(nominal, final.effects) if final else nominal


def _consistency(fold_check, nominal: Model, effects: list[str]):
    """The folds' consistency with its judgement and the diagnosis' ``effects`` it pins down, None without
    folds."""
    consistency_result = fold_check.result() if fold_check is not None else None
    if consistency_result is None:
        return None
    consistency_result = pinned(effects, consistency_result)
    consistency_result.judgement = consistency_judgement(consistency_result, nominal)
    return consistency_result


def _diagnosis(
    inputs: _Inputs,
    settings: DiagnosisSettings,
    selection: Selection,
    bootstrap: Bootstrap,
    *,
    heldout_gaps: tuple,
    limits: list,
    consistency_result,
    missing,
    notes: list[str],
    record: dict,
) -> Diagnosis:
    """Assemble the :class:`Diagnosis` record from the stages' results: ``heldout_gaps`` (the nominal and the
    accepted model's held-out gaps, what evaluated them), ``missing`` (the torque beyond the vocabulary or None)."""
    nominal_heldout, accepted_heldout, evaluated_by = heldout_gaps
    final, nominal, rig_params = _final(selection), inputs.nominal, inputs.rig
    before = window_residuals(nominal_heldout, inputs.heldout_windows, rig_params)
    after = window_residuals(accepted_heldout, inputs.heldout_windows, rig_params) if final else None
    torque = torque_record(missing) if missing else {}
    ranked = widen(ranking(selection, nominal), selection, bootstrap, nominal)
    gap = _gap_figures(inputs, selection, nominal_heldout, accepted_heldout, evaluated_by, before, after)
    localization = localize(
        before,
        after,
        noise_variance=nominal_heldout.sensor_variance,
        noise_variance_after=accepted_heldout.sensor_variance,
    )
    confusable = [{"effects": pair["effects"], "why": confusable_why(pair)} for pair in selection.confusable]
    accepted = list(final.effects) if final else []
    artifacts = _artifacts(inputs, selection, torque, missing, before, after, nominal_heldout.sensor_variance, record)
    disturbance = equivalent_disturbance(artifacts.corrected, inputs.heldout_logs, settings.seed)
    if disturbance is not None:
        artifacts.fitted_rig = artifacts.fitted_rig.replace(disturbance=disturbance)
        artifacts.fitted_config = artifacts.fitted_config.with_arm_torque(disturbance)
    return Diagnosis(
        verdict=selection.verdict,
        effects=selection.effects,
        gap=gap,
        ranking=ranked,
        localization=localization,
        steps=_steps(selection, nominal),
        uncertainty=UNCERTAINTY,
        detection_limits=limits,
        confusable=confusable,
        consistency=consistency_result,
        choice=choice_text(selection),
        holdout=inputs.holdout_note,
        rule=rule_text(settings.bootstrap, settings.seed, settings.max_effects),
        notes=notes,
        unmodelled_torque=torque,
        beside_torque=beside_record(selection.accepted, ranked, torque),
        remaining=remaining_record(
            gap, accepted_heldout.per_signal, localization, ranked, accepted, confusable, limits
        ),
        disturbance={} if disturbance is None else dataclasses.asdict(disturbance),
        artifacts=artifacts,
    )


def _gap_figures(
    inputs: _Inputs, selection: Selection, nominal_heldout, accepted_heldout, evaluated_by, before, after
) -> GapFigures:
    """The gap of the nominal and the accepted model on train and held-out windows, its reduction by the
    predictions, and apart from it what the accepted sensor effects (and a credited jitter) account for."""
    final = _final(selection)
    train_nominal = evaluate_gap(inputs.nominal, inputs.train_windows, inputs.rig.counts_per_rev).gap
    reduction = 1.0 - accepted_heldout.gap / nominal_heldout.gap if nominal_heldout.gap > 0 else 0.0
    floor = inputs.heldout_windows.floor
    claimed = float(selection.claimed().mean()) if selection.closes else 0.0
    left = max(float(accepted_heldout.per_window.mean()), 0.0)
    return GapFigures(
        gap_metric_definition(horizon_seconds(inputs.rig)),
        {"train": train_nominal, "heldout": nominal_heldout.gap},
        {"train": final.train_gap if final else train_nominal, "heldout": accepted_heldout.gap},
        reduction,
        nominal_heldout.per_signal,
        evaluated_by,
        heldout_rms_per_log(before, after),
        sensor_variance={"nominal": floor, "with_effects": floor + claimed},
        sensor_share=min(claimed, left) / max(float(nominal_heldout.per_window.mean()), 1e-12),
    )


def _steps(selection: Selection, nominal: Model) -> list[Step]:
    """Each accepted step's effect, parameters and held-out reductions (over nominal, the step, the others), then
    each accepted sensor effect with its share and score."""
    steps = []
    accepted = selection.step_models if _final(selection) else []
    for name, result, over_step in zip(selection.accepted, accepted, selection.over_step):
        params, _, at_bound = _params(result, nominal)
        over_nominal, over_others = selection.over_nominal[result.name], selection.over_others[name]
        steps.append(
            Step(
                name,
                params,
                over_nominal.heldout_gap,
                over_nominal.reduction,
                over_step.reduction,
                over_others.reduction,
                over_others.lower_bound,
                at_bound=at_bound,
            )
        )
    rows = {row.effect: row for row in _sensor_rows(selection, nominal)} if selection.closes else {}
    for finding in selection.sensor_effects if selection.closes else []:
        row = rows[finding.name]
        steps.append(
            Step(
                finding.name,
                row.params,
                row.heldout_gap,
                row.heldout_reduction,
                0.0,
                sensor_share=row.sensor_share,
                score_gain=row.score_gain,
                score_evidence=row.score_evidence,
            )
        )
    return steps


def _artifacts(inputs: _Inputs, selection, torque: dict, missing, before, after, sensor_variance, record) -> Artifacts:
    """The residual tables, effect curves, fitted config and rig files and the input record. With a kept torque
    the fitted files hold the listed effects kept beside it even when they alone leave the gap unexplained: the
    torque was found beside them."""
    nominal, rig_params = inputs.nominal, inputs.rig
    final = _final(selection)
    fitted = selection.final if torque else final
    sensors = {f.name: f.effect for f in selection.sensor_effects} if selection.closes else {}
    effects = {**(fitted.effects if fitted else {}), **sensors}
    # the rig file's torque and the one found beside it, written together
    terms = merged(nominal.unmodelled_terms + tuple(missing.terms)) if torque else nominal.unmodelled_terms
    parameters = torque_parameters_of(terms) if torque else None
    curves = [
        effect_curve(name, describe(name, effect, nominal), rig_params)
        for name, effect in {**(final.effects if final else {}), **sensors}.items()
    ]
    return Artifacts(
        before,
        after,
        sensor_variance,
        curves,
        fitted_config=model_config(rig_params, apply_effects(nominal, effects), parameters),
        fitted_rig=fitted_rig(rig_params, effects, nominal, parameters),
        corrected=apply_effects(nominal, effects).replace(unmodelled_terms=tuple(terms)),
        record=record,
        torque_scatter=missing.scatter if missing else {},
    )
