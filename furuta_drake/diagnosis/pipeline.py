"""``furuta-drake diagnose``: load -> windows and gap -> fit candidates -> select -> replay in Drake ->
localise -> report (spec/diagnosis-interface.md)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from furuta_drake.config import SimulationConfig
from furuta_drake.diagnosis.candidates import CANDIDATES, apply_effects, describe
from furuta_drake.diagnosis.fit import fit_all
from furuta_drake.diagnosis.gap import (
    evaluate_gap, gap_metric_definition, horizon_seconds, make_windows, window_residuals,
)
from furuta_drake.diagnosis.localize import localize
from furuta_drake.diagnosis.log_format import LogFormat
from furuta_drake.diagnosis.logs import RunLog, ignored_columns_note, load_logs, load_rig
from furuta_drake.diagnosis.replay import model_actuator, model_rig, replay_gaps
from furuta_drake.diagnosis.report import effect_curve, input_record, write_report
from furuta_drake.diagnosis.select import (
    THRESHOLD_NOTE, Decision, best_single, decide, nominal_at_floor, rank,
)
from furuta_drake.diagnosis.surrogate import Model
from furuta_drake.friction import FrictionParameters

HOLDOUT_FRACTION = 0.3
HOLDOUT_BLOCKS = 10
MIN_BLOCK_S = 1.0  # [s]: three or more gap windows per block
MIN_BLOCKS = 3
# Variants of one law (each holds an arm Coulomb level): a pair of two of them explains nothing new.
SAME_LAW = ({"arm_coulomb_friction", "arm_stribeck", "friction_asymmetry"},)


STATIC_EXCESS = 0.1  # a Stribeck fit whose static level is within 10 % of its Coulomb level has no Stribeck part


def name_static_free_stribeck(decision: Decision, fits: dict) -> Decision:
    """An accepted ``arm_stribeck`` whose fitted static level does not exceed its Coulomb level by
    ``STATIC_EXCESS`` is Coulomb friction by the vocabulary's own definition (static friction *above* the
    Coulomb level): the verdict says so (the ranking keeps the fit under its candidate's name)."""
    if decision.accepted is None or "arm_stribeck" not in decision.effects:
        return decision
    coulomb, static = fits[decision.accepted].effects["arm_stribeck"][:2]
    if static > (1.0 + STATIC_EXCESS) * coulomb:
        return decision
    effects = ["arm_coulomb_friction" if name == "arm_stribeck" else name for name in decision.effects]
    return dataclasses.replace(decision, verdict=effects[0], effects=effects)


def pair_groups(order: list[str], best: str) -> list[tuple[str, str]]:
    """The pairs tried for a combined verdict: the best single candidate with every other candidate that is not
    a variant of its own law (a second effect can be masked alone: a delay fits to zero under strong friction);
    a pair fit starts from the best candidate's single fit."""
    family = next((law for law in SAME_LAW if best in law), {best})
    partners = [name for name in order if name not in family]
    return [(best, partner) for partner in partners]


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
        blocks = min(HOLDOUT_BLOCKS, int(log.time.size * log.sample_period / MIN_BLOCK_S))
        if blocks < MIN_BLOCKS:
            edges, held = [0, int(log.time.size * (1.0 - HOLDOUT_FRACTION)), log.time.size], {1}
        else:
            edges, held = np.linspace(0, log.time.size, blocks + 1).astype(int).tolist(), _held_out_blocks(blocks)
        for k, (first, last) in enumerate(zip(edges[:-1], edges[1:])):
            part = heldout if k in held else train
            sl = slice(first, last)
            part.append(dataclasses.replace(
                log, name=f"{log.name} (t = {log.time[first]:.2f}-{log.time[last - 1]:.2f} s)", time=log.time[sl],
                theta=log.theta[sl], phi=log.phi[sl], input=log.input[sl]))
    return train, heldout, (
        f"no --heldout logs: each train log was cut into up to {HOLDOUT_BLOCKS} equal blocks of at least "
        f"{MIN_BLOCK_S:g} s and {HOLDOUT_FRACTION:.0%} of them, spread over the run, were held out and never used "
        f"for fitting (a log shorter than {MIN_BLOCKS} blocks held out its last {HOLDOUT_FRACTION:.0%}): "
        + ", ".join(log.name for log in heldout))


def fitted_config(rig, model: Model) -> SimulationConfig:
    """The corrected Drake model as a simulate config (open loop: users add their controller)."""
    config = SimulationConfig.from_rig(model_rig(model, rig).replace(motor=rig.motor))
    return dataclasses.replace(
        config,
        friction=FrictionParameters(arm=model.arm_friction, pendulum=model.pendulum_friction),
        actuator=dataclasses.replace(model_actuator(model), delay=model.delay),
        disturbance=dataclasses.replace(config.disturbance, arm_spring_stiffness=model.spring_stiffness,
                                        arm_spring_equilibrium=model.spring_equilibrium),
        encoder=dataclasses.replace(config.encoder, counts_per_rev=model.counts_per_rev,
                                    noise_std=model.noise_std))


def run_diagnosis(*, rig_path, train_paths, heldout_paths=(), out, force=False, workers=None, progress=None,
                  echo=print, candidates=None, log_format: LogFormat = LogFormat()) -> dict:
    """Diagnose the gap between the rig file's nominal model and the logs; write the report to ``out``.
    ``candidates``: the effects to try (default: the whole vocabulary); ``log_format``: the logs' column names,
    angle unit and MCAP topic."""
    rig = load_rig(rig_path)
    logs = load_logs(train_paths, rig, rig_path, log_format)
    heldout_logs = load_logs(heldout_paths, rig, rig_path, log_format) if heldout_paths else []
    note = ignored_columns_note(logs + heldout_logs)
    if note:
        echo(note)
    if heldout_logs:
        holdout_note = "held-out logs: " + ", ".join(log.name for log in heldout_logs)
    else:
        logs, heldout_logs, holdout_note = split_heldout(logs)
    train_windows, heldout_windows = make_windows(logs, rig), make_windows(heldout_logs, rig)
    counts = rig.counts_per_rev
    nominal = Model.from_rig(rig)

    singles = [(name,) for name in (candidates or CANDIDATES)]
    fits = fit_all(singles, nominal, train_windows, logs, counts, workers=workers, progress=progress)
    heldout = {name: evaluate_gap(apply_effects(nominal, fit.effects), heldout_windows, counts)
               for name, fit in fits.items()}
    nominal_heldout = evaluate_gap(nominal, heldout_windows, counts)
    single = best_single(rank(nominal_heldout.per_window, {name: g.per_window for name, g in heldout.items()}))
    order = sorted(heldout, key=lambda name: heldout[name].gap)
    # No pair when the nominal model already sits at the floor: the verdict is none whatever a pair does.
    pairs = [] if nominal_at_floor(nominal_heldout.per_window) else pair_groups(
        order, single["name"] if single else order[0])
    warm = {pair: {pair[0]: fits[pair[0]].effects[pair[0]]} for pair in pairs}
    pair_fits = fit_all(pairs, nominal, train_windows, logs, counts, workers=workers, progress=progress,
                        fitted=warm)
    fits.update(pair_fits)
    heldout.update({name: evaluate_gap(apply_effects(nominal, fit.effects), heldout_windows, counts)
                    for name, fit in pair_fits.items()})
    decision = name_static_free_stribeck(
        decide(nominal_heldout.per_window, {name: g.per_window for name, g in heldout.items()}), fits)

    accepted = apply_effects(nominal, fits[decision.accepted].effects) if decision.accepted else nominal
    # The headline held-out figures come from Drake diagrams of the project's systems.
    replays = [(nominal, nominal_heldout.initial_states)]
    if decision.accepted:
        replays.append((accepted, heldout[decision.accepted].initial_states))
    gaps = replay_gaps(replays, rig, heldout_windows, workers)
    drake_nominal, drake_accepted = gaps[0], gaps[-1]  # the same without an accepted effect
    train_nominal = evaluate_gap(nominal, train_windows, counts).gap
    train_accepted = fits[decision.accepted].train_gap if decision.accepted else train_nominal
    reduction = 1.0 - drake_accepted.gap / drake_nominal.gap if drake_nominal.gap > 0 else 0.0

    ranking = []
    for row in decision.ranking:
        fit = fits[row["name"]]
        params = {}
        for name, values in fit.effects.items():
            prefix = f"{name}." if "+" in row["name"] else ""
            params.update({prefix + k: v for k, v in describe(name, values, nominal).items()})
        ranking.append({"effect": row["name"], "params": params, "heldout_gap": row["heldout_gap"],
                        "heldout_reduction": row["heldout_reduction"], "evidence": row["evidence"],
                        "train_gap": fit.train_gap, "at_bounds": fit.at_bounds, "evaluated_by": "surrogate"})
    before = window_residuals(drake_nominal, heldout_windows, rig)
    after = window_residuals(drake_accepted, heldout_windows, rig) if decision.accepted else None
    report = {
        "verdict": decision.verdict,
        "effects": decision.effects,
        "gap": {"metric": gap_metric_definition(horizon_seconds(rig)),
                "nominal": {"train": train_nominal, "heldout": drake_nominal.gap},
                "with_effects": {"train": train_accepted, "heldout": drake_accepted.gap},
                "heldout_reduction": reduction,
                "per_signal_nominal_heldout": drake_nominal.per_signal,
                "evaluated_by": "drake replay of the held-out windows"},
        "ranking": ranking,
        "localization": localize(before, after, noise_variance=drake_nominal.sensor_variance,
                                 noise_variance_after=drake_accepted.sensor_variance),
    }
    curves = [effect_curve(name, describe(name, values, nominal), rig)
              for name, values in (fits[decision.accepted].effects.items() if decision.accepted else [])]
    record = input_record(rig_path=rig_path, train=train_paths, heldout=heldout_paths,
                          seeds={"bootstrap": 0, "fit_windows": 0},
                          options={"workers": workers, "holdout": holdout_note,
                                   "candidates": list(candidates or CANDIDATES), "log_format": log_format.record()})
    write_report(out, report, before=before, after=after, curves=curves,
                 fitted_config=fitted_config(rig, accepted), config_record=record,
                 threshold_note=THRESHOLD_NOTE, holdout_note=holdout_note,
                 noise_variance=drake_nominal.sensor_variance, force=force,
                 protect=[Path(rig_path), *map(Path, train_paths), *map(Path, heldout_paths)])
    return report
