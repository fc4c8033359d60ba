"""Is the verdict stable across data? ``--folds K`` repeats the selection on K splits of all the logs
(:func:`~furuta_drake.diagnosis.split.fold_split`) and judges how often the verdict and each effect came back and
how far the accepted effects' parameters spread."""

from __future__ import annotations

from collections.abc import Callable

from furuta_drake.diagnosis.gap import make_windows
from furuta_drake.diagnosis.logs import RunLog
from furuta_drake.diagnosis.result import Consistency
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.diagnosis.split import fold_split
from furuta_drake.diagnosis.stepwise import select_effects
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
    effects and the range of each accepted effect's parameters over the folds that accepted it (its judgement in
    words is the report's: :func:`furuta_drake.diagnosis.record_text.consistency_judgement`)."""
    verdicts, effects, values = [], [], {}
    for fold in range(folds):
        train, heldout = fold_split(logs, folds, fold, rig)
        selection = select_effects(
            nominal,
            train,
            make_windows(train, rig),
            make_windows(heldout, rig),
            rig.counts_per_rev,
            names,
            settings,
            run,
        )
        verdicts.append(selection.verdict)
        effects.append(selection.effects)
        if selection.effects:
            for name, effect in selection.final.effects.items():
                for key, value in describe(name, effect, nominal).items():
                    if key != "form":
                        values.setdefault(f"{name}.{key}", []).append(value)
    ranges = {key: [float(min(v)), float(max(v))] for key, v in values.items()}
    return Consistency(folds, verdicts, effects, ranges)
