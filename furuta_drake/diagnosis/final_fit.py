"""The accepted model fitted once more on every train window (stage 4d of the diagnosis).

The selection fits each candidate on a seeded draw of ``DiagnosisSettings.fit_windows`` train windows, for speed.
A law with a sharp feature (a Stribeck peak, a stick-slip event) is then fitted to the events those windows hold,
and its parameters carry the draw's bias. Once the selection has decided the accepted effects, their model is
fitted again on every train window, started from the selection's values (a warm start: a few least-squares
iterations), and its bootstrap resamples every train window. The report's parameters, intervals and final
held-out figures are the refit's; the decision stays the selection's: a refit that would change the verdict or the
effects' names is not reported (the selection's fit is).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable

from furuta_drake.diagnosis.fit import FitResult, FitTask, fit_task
from furuta_drake.diagnosis.gap import Windows
from furuta_drake.diagnosis.parallel import Failure
from furuta_drake.diagnosis.rule import Bootstrap
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.diagnosis.stepwise import Selection
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import CANDIDATES

REFIT_NFEV = 6  # cost evaluations of the warm-started refit (it starts near the minimum)


def every_window_task(
    fitted: FitResult,
    model: Model,
    train: Windows,
    heldout: Windows | None,
    logs: tuple,
    counts: int,
    settings: DiagnosisSettings,
) -> FitTask | None:
    """The refit of ``fitted`` (effects fitted beside ``model``) on every window of ``train``, each fitted effect
    started from its value (the last one as the task's new effect, in its form), sensor effects kept as they are;
    None when ``train`` holds no more than ``settings.fit_windows`` windows (the fit saw them all) or no effect is
    fitted."""
    names = [name for name in fitted.effects if CANDIDATES[name].fit]
    if train.count <= settings.fit_windows or not names:
        return None
    new = names[-1]
    return FitTask(
        new=new,
        fixed={name: effect for name, effect in fitted.effects.items() if name != new},
        model=model,
        train=train,
        heldout=heldout,
        logs=tuple(logs),
        nominal_counts=counts,
        settings=dataclasses.replace(settings, fit_windows=train.count, max_nfev=REFIT_NFEV),
        fixed_samples=fitted.samples,
        start=fitted.effects[new],
    )


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
    task = every_window_task(final, model, train, heldout, logs, counts, settings) if final else None
    if task is None:
        return selection, []
    (result,) = run(fit_task, [task])
    if isinstance(result, Failure):
        return selection, [f"the accepted model's refit on every train window failed ({result.reason})"]
    refit = dataclasses.replace(result, name=final.name, effects={name: result.effects[name] for name in final.effects})
    out = _with_final(selection, refit, bootstrap)
    if out.verdict != selection.verdict or out.effects != selection.effects:
        return selection, [
            "the accepted model refitted on every train window would change the verdict; "
            "its fit on the selection's windows is reported"
        ]
    return out, []


def _with_final(selection: Selection, refit: FitResult, bootstrap: Bootstrap) -> Selection:
    """``selection`` with ``refit`` in place of its final model and the final model's held-out evidence (over the
    nominal model, over the step before, over each model without one kept effect) that of ``refit``."""
    final, nominal = selection.final, selection.nominal.per_window
    out = dataclasses.replace(
        selection,
        tried=[(step, refit if result is final else result) for step, result in selection.tried],
        over_nominal={**selection.over_nominal, refit.name: bootstrap.evidence(nominal, refit.heldout.per_window)},
        subset_fit=final,
    )
    chain = [nominal] + [model.heldout.per_window for model in out.step_models]
    out.over_previous = {**selection.over_previous, refit.name: bootstrap.evidence(chain[-2], chain[-1])}
    out.over_step = [*selection.over_step[:-1], out.over_previous[refit.name]]
    without = {name: out.model([other for other in out.accepted if other != name]) for name in out.accepted}
    out.over_others = {
        name: bootstrap.evidence(model.heldout.per_window if model else nominal, chain[-1])
        for name, model in without.items()
    }
    return out
