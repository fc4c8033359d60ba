"""The accepted model fitted once more on every train window (stage 4d of the diagnosis).

The selection fits each candidate on a seeded draw of ``DiagnosisSettings.fit_windows`` train windows, for speed.
A law with a sharp feature (a Stribeck peak, a stick-slip event) is then fitted to the events those windows hold,
and its parameters carry the draw's bias. Once the selection has decided the accepted effects, their model is
fitted again on every train window, started from the selection's values (a warm start: a few least-squares
iterations) and, for the effect that entered last, also from its forms' own starts; the fit of least train cost
is kept, and its bootstrap resamples every train window. The report's parameters, intervals and final
held-out figures are the refit's; the decision stays the selection's: a refit that would change the verdict or the
effects' names is not reported (the selection's fit is).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from furuta_drake.diagnosis.gap.metric import Windows
from furuta_drake.diagnosis.selection.fit import FitResult, FitTask, fit_task
from furuta_drake.diagnosis.selection.rule import Bootstrap
from furuta_drake.diagnosis.selection.stepwise import Selection
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import CANDIDATES
from furuta_drake.parallel import Failure


def every_window_tasks(
    fitted: FitResult,
    model: Model,
    train: Windows,
    heldout: Windows | None,
    logs: tuple,
    counts: int,
    settings: DiagnosisSettings,
    regressed: dict | None = None,
) -> list[FitTask]:
    """The refits of ``fitted`` (effects fitted beside ``model``) on every window of ``train``: every fitted effect
    from its value (a warm start; the last one as the task's new effect, in its form), and the same with the last
    one from its forms' own starts (the drawn windows' fit can sit in another basin of the cost on every window: a
    Stribeck peak shaped to the stick-slip events the draw holds); sensor effects kept as they are. Empty when
    ``train`` holds no more than ``settings.fit_windows`` windows (the fit saw them all) or no effect is fitted."""
    names = [name for name in fitted.effects if CANDIDATES[name].fit]
    if train.count <= settings.fit_windows or not names:
        return []
    new = names[-1]
    task = FitTask(
        new=new,
        fixed={name: effect for name, effect in fitted.effects.items() if name != new},
        model=model,
        train=train,
        heldout=heldout,
        logs=tuple(logs),
        nominal_counts=counts,
        settings=dataclasses.replace(settings, fit_windows=train.count),
        fixed_samples=fitted.samples,
        regressed=regressed or {},
    )
    return [dataclasses.replace(task, start=fitted.effects[new]), task]


def refit(fitted: FitResult, tasks: list[FitTask], run: Callable) -> FitResult | None:
    """Of ``tasks`` (:func:`every_window_tasks` of ``fitted``) run by ``run``, the fit of least mean excess squared
    residual on the train windows, named and ordered as ``fitted``; None when every one failed (or none was
    given)."""
    results = [result for result in run(fit_task, tasks) if not isinstance(result, Failure)]
    if not results:
        return None
    best = min(results, key=lambda result: result.train_excess)
    return dataclasses.replace(best, name=fitted.name, effects={name: best.effects[name] for name in fitted.effects})


def refit_final(
    selection: Selection,
    model: Model,
    train: Windows,
    heldout: Windows,
    logs: tuple,
    counts: int,
    settings: DiagnosisSettings,
    bootstrap: Bootstrap,
    run: Callable,
) -> tuple[Selection, list[str]]:
    """``selection`` with its final model refitted on every train window (module docstring) and the evidence of
    that model over the nominal one, the step before and each model without one of its effects evaluated again;
    ``selection`` itself when there is nothing to refit. Also the report's notes (a refit not reported)."""
    final = selection.final
    tasks = (
        every_window_tasks(final, model, train, heldout, logs, counts, settings, selection.regressed) if final else []
    )
    if not tasks:
        return selection, []
    refitted = refit(final, tasks, run)
    if refitted is None:
        return selection, [
            "the accepted model's refit on every train window failed; its fit on the drawn windows is reported"
        ]
    out = _with_final(selection, refitted, bootstrap)
    if out.verdict != selection.verdict or out.effects != selection.effects:
        return selection, [
            "the accepted model refitted on every train window would change the verdict or the effects' names; "
            "its fit on the drawn windows is reported"
        ]
    return out, []


def _with_final(selection: Selection, refitted: FitResult, bootstrap: Bootstrap) -> Selection:
    """``selection`` with ``refitted`` in place of its final model and the final model's held-out evidence (over
    the nominal model, over the step before, over each model without one kept effect) that of ``refitted``: the
    rule's figures read as the selection read them (:meth:`Selection.rule_bootstrap`)."""
    final, nominal = selection.final, selection.nominal.per_window
    out = dataclasses.replace(
        selection,
        tried=[(step, refitted if result is final else result) for step, result in selection.tried],
        over_nominal={
            **selection.over_nominal,
            refitted.name: bootstrap.evidence(nominal, refitted.heldout.per_window),
        },
        subset_fit=final,
    )
    judge = selection.rule_bootstrap(bootstrap)
    chain = [nominal] + [model.heldout.per_window for model in out.step_models]
    out.over_previous = {**selection.over_previous, refitted.name: judge.evidence(chain[-2], chain[-1])}
    out.over_step = [*selection.over_step[:-1], out.over_previous[refitted.name]]
    without = {name: out.model([other for other in out.accepted if other != name]) for name in out.accepted}
    out.over_others = {
        name: judge.evidence(model.heldout.per_window if model else nominal, chain[-1])
        for name, model in without.items()
    }
    return out
