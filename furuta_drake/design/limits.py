"""The detection limits a designed experiment is predicted to reach, for the effects it targets.

A diagnosis states, for every effect it did not accept, the smallest size its held-out windows would have
detected (:mod:`furuta_drake.diagnosis.selection.detection`: the effect injected into the accepted model's prediction
and judged by the acceptance rule's bootstrap). The prediction applies the same machinery to the held-out windows
the diagnosis would judge once the experiment's log joins its logs: its own held-out windows and the held-out
half of the experiment as the accepted model plays it in Drake, read through the accepted model's encoder
(rounding to its counts and its white noise, seeded). A target's size is the one that changes the rig's closed
loop (:mod:`furuta_drake.design.closed_loop`) or the one ``--target`` names; the prediction says whether the
new limit falls to it.
"""

from __future__ import annotations

import numpy as np

from furuta_drake.design.closed_loop import closed_loop_sizes, limited_targets, reaches
from furuta_drake.design.criterion import experiment_windows
from furuta_drake.design.hypotheses import Hypotheses
from furuta_drake.design.inputs import DiagnosisRecord
from furuta_drake.design.rollout import nominal_lqr_gain
from furuta_drake.diagnosis.gap.metric import Windows, make_windows
from furuta_drake.diagnosis.selection.detection import INJECTIONS, injected_limits
from furuta_drake.diagnosis.selection.rule import Bootstrap
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import UNITS, Scales
from furuta_drake.rig import encoder_resolution


def diagnosis_heldout_windows(record: DiagnosisRecord) -> Windows:
    """The held-out windows the diagnosis judged: its ``--heldout`` logs, or the blocks it held out of its train
    logs."""
    from furuta_drake.diagnosis.gap.split import split_heldout

    return make_windows(record.heldout if record.heldout else split_heldout(record.train)[1], record.rig)


def joined(first: Windows, second: Windows) -> Windows:
    """The windows of both, log after log."""
    return Windows(
        first.logs + second.logs,
        first.horizons + second.horizons,
        first.starts + second.starts,
        first.initial_states + second.initial_states,
        first.measured + second.measured,
        first.arm_paths + second.arm_paths,
    )


def read_through_encoder(angles: np.ndarray, model: Model, seed: int) -> np.ndarray:
    """True angles [rad] as ``model``'s sensor logs them: its white noise (seeded), then rounded to its
    encoder's counts."""
    noisy = angles + model.noise_std * np.random.default_rng(seed).standard_normal(angles.shape)
    step = encoder_resolution(model.counts_per_rev)
    return np.round(noisy / step) * step


def target_sizes(hypotheses: Hypotheses, named: list[tuple[str, float]], report: dict, rig) -> list[tuple[str, float]]:
    """The (effect, size) of every target hypothesis that has a detection limit (an injected effect: the
    unmodelled torque's detection is the pair's prediction): the ``--target`` ones given in ``named``, else those
    of the limits that matter on the rig's LQR (:func:`~furuta_drake.design.closed_loop.limited_targets`)."""
    held = {name for h in hypotheses.hypotheses if h.role == "target" for name in h.effects}
    if not held:
        return []
    sizes = named or limited_targets(report, closed_loop_sizes(rig, nominal_lqr_gain(rig)))
    return [(name, size) for name, size in sizes if name in held and name in INJECTIONS]


def predicted_limits(
    record: DiagnosisRecord,
    hypotheses: Hypotheses,
    targets: list[tuple[str, float]],
    experiment: tuple[np.ndarray, np.ndarray] | None,
    scales: Scales,
    resamples: int,
    seed: int,
) -> list[dict]:
    """Per target: its size, today's limit (the diagnosis' report), the limit predicted once the experiment
    joins the logs and whether it falls to the size. ``experiment``: the accepted model's true angles (N, 2)
    [rad] and its logged command (N,) [N m] under the design (None: no experiment, no prediction)."""
    if not targets:
        return []
    rig, accepted = record.rig, hypotheses.hypotheses[0]
    predicted = {}
    if experiment is not None:
        angles, command = experiment
        measured = read_through_encoder(angles, accepted.model, seed)
        new = experiment_windows(measured[:, :, None], command[None], rig.sample_period, rig)[1]
        windows = joined(diagnosis_heldout_windows(record), new)
        names = [name for name, _ in targets]
        found = injected_limits(
            accepted.model,
            list(accepted.effects),
            windows,
            scales,
            rig.counts_per_rev,
            Bootstrap(windows.count, resamples, seed),
            names,
        )
        predicted = {limit.effect: limit.value for limit in found}
    today = {limit["effect"]: limit.get("value") for limit in record.report.get("detection_limits") or []}
    return [
        {
            "effect": name,
            "param": INJECTIONS[name].param,
            "unit": UNITS[INJECTIONS[name].param],
            "size": size,
            "today": today.get(name),
            "predicted": predicted.get(name),
            "predicted_below_size": None if experiment is None else reaches(name, predicted.get(name), size),
        }
        for name, size in targets
    ]
