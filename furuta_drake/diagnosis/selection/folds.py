"""Is the verdict stable across data? ``--folds K`` repeats the selection on K splits of all the logs
(:func:`~furuta_drake.diagnosis.gap.split.fold_split`) and judges how often the verdict and each effect came back and
how far the accepted effects' parameters spread."""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor

from furuta_drake.diagnosis.gap.metric import make_windows
from furuta_drake.diagnosis.gap.split import fold_split
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.diagnosis.result import Consistency
from furuta_drake.diagnosis.selection.stepwise import select_effects
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import describe
from furuta_drake.rig import RigParameters


def consistency(
    logs: list[RunLog],
    rig: RigParameters,
    nominal: Model,
    names: list[str],
    settings: DiagnosisSettings,
    run: Callable,
    folds: int,
) -> Consistency:
    """The selection repeated on ``folds`` splits of all the logs (:func:`fold_split`): each fold's verdict and
    effects, the range of each accepted effect's parameters over the folds that accepted it (its judgement in words is
    :func:`furuta_drake.diagnosis.report.record_text.consistency_judgement`'s).
    The folds' selections run at once, each in a thread handing its fits to ``run`` (a shared worker pool then
    stays busy between one selection's small batches)."""

    def selection_on(fold: int):
        train, heldout = fold_split(logs, folds, fold, rig)
        return select_effects(
            nominal,
            train,
            make_windows(train, rig),
            make_windows(heldout, rig),
            rig.counts_per_rev,
            names,
            settings,
            run,
        )

    with ThreadPoolExecutor(max_workers=folds) as threads:
        selections = list(threads.map(selection_on, range(folds)))
    verdicts, effects, values = [], [], {}
    for selection in selections:
        verdicts.append(selection.verdict)
        effects.append(selection.effects)
        if selection.effects:
            dynamic = selection.final.effects if selection.final else {}
            sensors = {finding.name: finding.effect for finding in selection.sensor_effects}
            for name, effect in {**dynamic, **sensors}.items():
                for key, value in describe(name, effect, nominal).items():
                    if key != "form":
                        values.setdefault(f"{name}.{key}", []).append(value)
    ranges = {key: [float(min(v)), float(max(v))] for key, v in values.items()}
    return Consistency(folds, verdicts, effects, ranges)


def pinned(effects: list[str], consistency_result: Consistency) -> Consistency:
    """``consistency_result`` with the diagnosis' ``effects`` split by the folds: those every fold names
    (``settled``) and, for every effect the diagnosis or a fold names that not every fold names, how many folds do
    (``unsettled``): the effects these logs cannot pin down (a different split of the same logs adds or drops
    them)."""
    folds = consistency_result.effects
    count = {name: sum(name in found for found in folds) for name in dict.fromkeys([*effects, *sum(folds, [])])}
    settled = [name for name in effects if count[name] == len(folds)]
    unsettled = {name: n for name, n in count.items() if n < len(folds)}
    return dataclasses.replace(consistency_result, settled=settled, unsettled=unsettled)
