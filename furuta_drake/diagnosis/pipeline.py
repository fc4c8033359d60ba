"""``furuta-drake diagnose`` as one function, :func:`diagnose`: load -> split into train and held-out data ->
windows -> select effects (fit on train, the held-out rule) -> detection limits -> replay in Drake -> localise,
returning a :class:`~furuta_drake.diagnosis.result.Diagnosis` (:func:`~furuta_drake.diagnosis.report.write_report`
writes it; ``docs/diagnose.md`` explains every figure).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from functools import partial
from pathlib import Path

import numpy as np

from furuta_drake.diagnosis.detection import detection_limits
from furuta_drake.diagnosis.fit import FitResult, interval, scales_of
from furuta_drake.diagnosis.folds import consistency
from furuta_drake.diagnosis.gap import (
    evaluate_gap,
    gap_metric_definition,
    horizon_seconds,
    make_windows,
    window_residuals,
)
from furuta_drake.diagnosis.localize import localize
from furuta_drake.diagnosis.log_format import LogFormat
from furuta_drake.diagnosis.logs import ignored_columns_note, load_logs
from furuta_drake.diagnosis.missing_torque import beyond_vocabulary
from furuta_drake.diagnosis.parallel import TaskPool, run_tasks
from furuta_drake.diagnosis.per_log import heldout_rms_per_log
from furuta_drake.diagnosis.record_text import choice_text, confusable_why, consistency_judgement, rule_text
from furuta_drake.diagnosis.replay import replay_gaps
from furuta_drake.diagnosis.report import effect_curve, input_record
from furuta_drake.diagnosis.result import Artifacts, Diagnosis, GapFigures, RankedCandidate, Step
from furuta_drake.diagnosis.rival import widen
from furuta_drake.diagnosis.rule import Bootstrap
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.diagnosis.split import split_heldout
from furuta_drake.diagnosis.stepwise import Selection, select_effects
from furuta_drake.diagnosis.torque_report import torque_parameters, torque_record
from furuta_drake.effects.corrected import fitted_rig, model_config
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import CANDIDATES, Effect, apply_effects, describe, rig_model
from furuta_drake.errors import ConfigError
from furuta_drake.rig_file import load_rig
from furuta_drake.yamlio import locate_in_file

UNCERTAINTY = (
    "95 % intervals from a block bootstrap over the fit's train windows (a window is a block), "
    "linearised at the fit: one Gauss-Newton step per resample; quantisation is read exactly, noise "
    "is bootstrapped over blocks of second differences; the accepted model's intervals also span the move of "
    "its parameters when the strongest candidate not accepted is fitted beside it (an effect below the "
    "detection limits may act)"
)


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
        for key in described[0]:
            if key != "form":
                intervals[prefix + key] = list(interval(np.array([d[key] for d in described])))
    return params, intervals


def ranking(selection: Selection, nominal: Model) -> list[RankedCandidate]:
    """Every model tried, best first by its held-out reduction over the nominal model; failed ones last."""
    rows = []
    for step, result in selection.tried:
        if result.failure:
            rows.append(
                RankedCandidate(result.name, {}, None, None, None, step=step, status="failed", reason=result.failure)
            )
            continue
        params, intervals = _params(result, nominal)
        over_nominal, over_previous = selection.over_nominal[result.name], selection.over_previous[result.name]
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
            )
        )
    ok = [row for row in rows if row.status == "ok"]
    excess = {
        result.name: selection.over_nominal[result.name].excess for _, result in selection.tried if not result.failure
    }
    ok.sort(key=lambda row: (-row.heldout_reduction, excess[row.effect], row.step, row.effect))
    return ok + [row for row in rows if row.status != "ok"]


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
    # One worker pool for every batch of tasks; with --folds the folds' selections run in a thread beside the
    # main selection, their fits filling the cores its small batches leave idle.
    with ThreadPoolExecutor(max_workers=2) as background, TaskPool(1 if scheduler else workers) as pool:
        return _diagnose(
            rig=rig,
            train=train,
            heldout=heldout,
            candidates=candidates,
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
    *, rig, train, heldout, candidates, settings, folds, workers, scheduler, progress, log_format, pool, background
) -> Diagnosis:
    """:func:`diagnose` with its worker ``pool`` and ``background`` threads for the folds and the replays."""
    settings.validate()
    rig_path = Path(rig)
    rig_params = load_rig(rig_path)
    if rig_params.unmodelled_torque is not None:  # the surrogate's fits could not hold it: refused, not ignored
        raise locate_in_file(
            rig_path,
            ConfigError(
                "unmodelled_torque: a diagnosis cannot start from a stated torque beyond the vocabulary (its fits "
                "would leave it out); remove the key to diagnose, keep it to simulate"
            ),
        )
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
        raise ConfigError(f"unknown candidate effect {', '.join(unknown)} (the vocabulary: {', '.join(CANDIDATES)})")
    counts = rig_params.counts_per_rev
    nominal = rig_model(rig_params)
    train_windows, heldout_windows = make_windows(fit_logs, rig_params), make_windows(test_logs, rig_params)
    run = partial(run_tasks, workers=workers, scheduler=scheduler, done=progress, pool=pool)
    fold_check = None
    if folds is not None and folds >= 2:
        fold_check = background.submit(
            consistency, train_logs + heldout_logs, rig_params, nominal, names, settings, run, folds
        )
    selection = select_effects(nominal, fit_logs, train_windows, heldout_windows, counts, names, settings, run)
    bootstrap = Bootstrap(heldout_windows.count, settings.bootstrap, settings.seed)
    missing, torque_notes = beyond_vocabulary(
        selection, nominal, train_windows, heldout_windows, counts, bootstrap, settings
    )
    notes += torque_notes
    torque = torque_record(missing) if missing else {}
    final = selection.final if selection.effects else None
    accepted_model = apply_effects(nominal, final.effects) if final else nominal

    # The headline held-out figures come from Drake diagrams of the project's systems (the surrogate's when a
    # replay fails); the replays run on the workers while this process finds the detection limits.
    replays = [(nominal, selection.nominal.initial_states)]
    if final:
        replays.append((accepted_model, final.heldout.initial_states))
    replay_run = partial(run_tasks, workers=workers, scheduler=scheduler, pool=pool)
    replaying = (
        background.submit(replay_gaps, replays, rig_params, heldout_windows, replay_run) if settings.replay else None
    )

    limits = []
    if settings.detection_limits:
        limits = detection_limits(
            accepted_model,
            list(final.effects) if final else [],
            heldout_windows,
            scales_of(fit_logs, nominal),
            counts,
            bootstrap,
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
    nominal_heldout, accepted_heldout = gaps[0], gaps[-1]
    train_nominal = evaluate_gap(nominal, train_windows, counts).gap
    reduction = 1.0 - accepted_heldout.gap / nominal_heldout.gap if nominal_heldout.gap > 0 else 0.0
    before = window_residuals(nominal_heldout, heldout_windows, rig_params)
    after = window_residuals(accepted_heldout, heldout_windows, rig_params) if final else None

    consistency_result = fold_check.result() if fold_check is not None else None
    if consistency_result is not None:
        consistency_result.judgement = consistency_judgement(
            consistency_result.verdicts, consistency_result.effects, consistency_result.params_range, nominal
        )
    steps = []
    for name, result, over_step in zip(selection.kept, selection.accepted if final else [], selection.over_step):
        params, _ = _params(result, nominal)
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
            )
        )
    record = input_record(
        rig_path=rig_path,
        train=train,
        heldout=heldout,
        seeds={"bootstrap": settings.seed, "fit_windows": settings.seed},
        options={
            "workers": workers,
            "scheduler": scheduler,
            "holdout": holdout_note,
            "candidates": names,
            "folds": folds,
            "settings": dataclasses.asdict(settings),
            "log_format": log_format.record(),
        },
    )
    curves = [
        effect_curve(name, describe(name, effect, nominal), rig_params)
        for name, effect in (final.effects.items() if final else [])
    ]
    artifacts = Artifacts(
        before,
        after,
        nominal_heldout.sensor_variance,
        curves,
        fitted_config=model_config(rig_params, accepted_model, torque_parameters(torque) if torque else None),
        fitted_rig=fitted_rig(
            rig_params, final.effects if final else {}, nominal, torque_parameters(torque) if torque else None
        ),
        record=record,
        torque_scatter=missing.scatter if missing else {},
    )
    return Diagnosis(
        verdict=selection.verdict,
        effects=selection.effects,
        gap=GapFigures(
            gap_metric_definition(horizon_seconds(rig_params)),
            {"train": train_nominal, "heldout": nominal_heldout.gap},
            {"train": final.train_gap if final else train_nominal, "heldout": accepted_heldout.gap},
            reduction,
            nominal_heldout.per_signal,
            evaluated_by,
            heldout_rms_per_log(before, after),
        ),
        ranking=widen(ranking(selection, nominal), selection, bootstrap, nominal),
        localization=localize(
            before,
            after,
            noise_variance=nominal_heldout.sensor_variance,
            noise_variance_after=accepted_heldout.sensor_variance,
        ),
        steps=steps,
        uncertainty=UNCERTAINTY,
        detection_limits=limits,
        confusable=[{"effects": pair["effects"], "why": confusable_why(pair)} for pair in selection.confusable],
        consistency=consistency_result,
        choice=choice_text(selection),
        holdout=holdout_note,
        rule=rule_text(settings.bootstrap, settings.seed, settings.max_effects),
        notes=notes,
        unmodelled_torque=torque,
        artifacts=artifacts,
    )
