"""``furuta-drake reproduce --only real``: the paper's observers and the closed loop on the real QUBE-Servo 2 runs,
before and after the diagnosis' correction, and the files that say so.

:func:`run_real_rig` runs, in order: the diagnosis that corrects the nominal model
(:func:`furuta_drake.real_rig.runs.diagnose_corrected_model`), the observers on measured data
(:mod:`furuta_drake.real_rig.observers_study`), the controller's check against the logs and the closed loop
real against simulated (:mod:`furuta_drake.real_rig.closed_loop_study`), then the diagnosis of the part the
corrected model leaves open (the balancing) and the closed loop once more on the model it corrects further.
:func:`write_real_rig` writes ``real_observers.csv``, ``real_observer_sweep.csv``, ``real_closed_loop.csv``,
``real_closed_loop_gap.csv``, ``controller_fit.json``, the plots, both diagnoses' reports
(``diagnosis_corrected/``, ``diagnosis_balancing/``), the logs they read (``segments/``), every simulated run's
log and config (``logs/``), and :func:`real_rig_markdown` the report that reads them. Every number comes from the
logs and the simulations.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from furuta_drake.config import SimulationConfig, dump_config
from furuta_drake.controllers.quanser_swingup import QuanserSwingUpParameters, quanser_command
from furuta_drake.diagnosis.report.files import write_report_files
from furuta_drake.effects.corrected import rig_config
from furuta_drake.observers.filtered_derivative import filtered_derivative
from furuta_drake.paper.reproduce import PAPER_TABLE2, report_progress
from furuta_drake.plotting import (
    plot_controller_fit,
    plot_limit_cycle_spectra,
    plot_real_closed_loop,
    plot_real_observers,
)
from furuta_drake.real_rig import closed_loop_study as real_closed_loop_study
from furuta_drake.real_rig import observers_study as real_observers_study
from furuta_drake.real_rig.closed_loop_study import LIMIT_CYCLE_MIN_HZ, balancing_spectrum
from furuta_drake.real_rig.runs import (
    CHIRP,
    OSCILLATING_SWINGUP,
    REFERENCE_CUTOFF_HZ,
    SETTLE,
    SWINGUPS,
    TRAIN_SWINGUP,
    RealRuns,
    diagnose_corrected_model,
    load_real_runs,
    reference_properties,
    reference_velocity,
)
from furuta_drake.results import config_yaml_with_provenance, write_json, write_log_csv, write_table_csv

SMALL_SWINGUPS = (TRAIN_SWINGUP, SWINGUPS[1], OSCILLATING_SWINGUP)  # the small run's closed loop
CLOSED = 0.5  # a figure whose gap the correction closed by less than this share "does not close"
SOURCES = {
    "real": "the real rig",
    "sim_nominal": "simulated, nominal model",
    "sim_fitted": "simulated, corrected model",
    "sim_refitted": "simulated, corrected model + balancing effects",
}


@dataclass
class RealRigOutcome:
    """Everything ``--only real`` computed (:func:`run_real_rig`)."""

    runs: RealRuns
    corrected: object  # Diagnosis: the nominal model corrected
    corrected_inputs: tuple[list, list]
    observers: real_observers_study.ObserverStudy
    closed_loop: real_closed_loop_study.ClosedLoopStudy
    balancing: object  # Diagnosis of the balancing, from the corrected model
    balancing_inputs: tuple[list, list]
    reference: dict
    small: bool


def run_real_rig(folder: Path, small: bool = False, progress=None) -> RealRigOutcome:
    """Run the studies; the diagnoses' logs are written under ``folder``. ``small``: quick diagnoses, three
    candidates of each observer, three swing-ups and no catch-time spread (tests, notebooks)."""
    runs = load_real_runs()
    corrected, train, heldout = diagnose_corrected_model(runs, folder / "segments", small)
    report_progress(progress, f"diagnosis of the nominal model: {corrected.verdict}")
    models = {"nominal": rig_config(runs.rig), "fitted": corrected.artifacts.fitted_config}
    observers = real_observers_study.study(runs, models, small=small, progress=progress)
    params = QuanserSwingUpParameters()
    closed = real_closed_loop_study.study(
        runs, models, params, logs=SMALL_SWINGUPS if small else SWINGUPS, spread=not small, progress=progress
    )
    balancing, btrain, bheld = real_closed_loop_study.balancing_diagnosis(
        runs, corrected.artifacts.fitted_rig, folder / "segments", small
    )
    report_progress(progress, f"diagnosis of the balancing: {balancing.verdict}")
    closed.add_model(runs, "refitted", balancing.artifacts.fitted_config, params, spread=not small, progress=progress)
    motion = max(
        row["limit_cycle_hz"] for row in closed.rows if row["source"] == "real" and math.isfinite(row["limit_cycle_hz"])
    )
    reference = reference_properties(runs.rig, runs.logs[TRAIN_SWINGUP].sample_period, motion)
    return RealRigOutcome(
        runs, corrected, (train, heldout), observers, closed, balancing, (btrain, bheld), reference, small
    )


def write_real_rig(staging: Path, outcome: RealRigOutcome) -> dict:
    """Write the files of ``outcome`` into ``staging`` (the studies' segments are already there); returns the
    figures report.md reads."""
    closed, observers = outcome.closed_loop, outcome.observers
    write_table_csv(observers.rows, staging / "real_observers.csv")
    write_table_csv(observers.sweep, staging / "real_observer_sweep.csv")
    write_table_csv(closed.rows, staging / "real_closed_loop.csv")
    write_table_csv(closed.gap, staging / "real_closed_loop_gap.csv")
    write_json(staging / "controller_fit.json", closed.controller_fit)
    for name, diagnosis in (("diagnosis_corrected", outcome.corrected), ("diagnosis_balancing", outcome.balancing)):
        (staging / name).mkdir()
        write_report_files(staging / name, diagnosis)
    logs = staging / "logs"
    logs.mkdir(exist_ok=True)
    for (source, log), config in closed.configs.items():
        stem = f"{source}_{Path(log).stem}"
        write_log_csv(closed.runs[(source, log)][0], logs / f"{stem}.csv")
        (logs / f"{stem}.yaml").write_text(dump_config(config))
    plot_real_observers(
        {key: value for key, value in observers.estimates.items() if key[1] in (SWINGUPS[1], CHIRP)},
        staging / "real_observers.png",
    )
    spectra = {}
    for log in dict.fromkeys(log for _, log in closed.runs):
        sources = {source: closed.runs[(source, log)] for source, name in closed.runs if name == log}
        plot_real_closed_loop(sources, f"{log}: real and simulated", staging / f"closed_loop_{Path(log).stem}.png")
        spectra[log] = {
            source: spectrum
            for source, (result, _) in sources.items()
            if (spectrum := balancing_spectrum(result)) is not None
        }
    plot_limit_cycle_spectra(spectra, staging / "limit_cycle_spectra.png")
    log = outcome.runs.logs[TRAIN_SWINGUP]
    params = dataclasses.replace(
        QuanserSwingUpParameters(),
        rest_direction=real_closed_loop_study.rest_direction(log, QuanserSwingUpParameters()),
    )
    angles = np.column_stack([log.theta, log.phi])
    replayed = {
        label: quanser_command(params, np.column_stack([angles, velocity]))[0]
        for label, velocity in (
            (f"law, {REFERENCE_CUTOFF_HZ:g} Hz zero-phase Butterworth velocities", reference_velocity(log)),
            (
                f"law, server's filtered derivative ({closed.corner:.1f} rad/s)",
                filtered_derivative(angles, log.sample_period, closed.corner),
            ),
        )
    }
    plot_controller_fit(
        log.time,
        log.input,
        replayed,
        f"{TRAIN_SWINGUP}: logged voltage and the controller's",
        staging / "controller_fit.png",
    )
    return {"real_observers": observers.rows, "real_closed_loop": closed.rows, "controller_fit": closed.controller_fit}


def nominal_run_config(outcome: RealRigOutcome) -> SimulationConfig:
    """The simulate config of the train swing-up on the nominal model (the command's ``config.yaml``)."""
    return outcome.closed_loop.configs[("sim_nominal", TRAIN_SWINGUP)]


def real_rig_markdown(outcome: RealRigOutcome) -> str:
    """report.md's real-rig section: each table with the reading the numbers support."""
    lines = [
        "# The paper's observers and the closed loop on a real QUBE-Servo 2",
        "",
        "Measured data: the swing-ups and the chirp of `data/qube-servo2-real` (SimuRLacra's QUBE-Servo 2, "
        "BSD-3). "
        + _parts(outcome)
        + (" Small run (quick diagnoses, fewer candidates and runs)." if outcome.small else ""),
        "",
    ]
    lines += correction_section(outcome)
    lines += observer_section(outcome)
    lines += controller_section(outcome)
    lines += closed_loop_section(outcome)
    lines += open_part_section(outcome)
    return "\n".join(lines) + "\n"


def _parts(outcome: RealRigOutcome) -> str:
    runs = outcome.runs
    by_part = {}
    for name in runs.logs:
        by_part.setdefault(runs.part(name), []).append(f"`{name}`")
    return (
        "Train: "
        + ", ".join(by_part.get("train", []))
        + " and the chirp's train blocks; held out: "
        + ", ".join(by_part.get("heldout", []))
        + " and the chirp's held-out blocks; never fitted on: "
        + ", ".join(by_part.get("oscillating", []))
        + " (it balances in a saturated oscillation)."
    )


def correction_section(outcome: RealRigOutcome) -> list[str]:
    d = outcome.corrected
    lines = [
        "## The corrected model (`diagnosis_corrected/`)",
        "",
        f"The diagnosis of the nominal model (train: the train swing-up and the chirp without the observers' "
        f"held-out blocks; held out: the held-out swing-ups) says **{d.verdict}** "
        f"(effects: {', '.join(d.effects) or 'none'}); held-out gap {_g(d.gap.nominal['heldout'])} -> "
        f"{_g(d.gap.with_effects['heldout'])} counts ({_pct(d.gap.heldout_reduction)} reduction).",
    ]
    for step in d.steps:
        params = ", ".join(f"{key} {_g(value)}" for key, value in step.params.items() if not isinstance(value, str))
        lines.append(f"- {step.effect}: {params}")
    friction = real_observers_study.dahl_of(d.artifacts.fitted_config.friction.arm)
    lines += [
        "",
        "Its arm friction calibrates the Dahl observer: "
        + (
            f"Fc+ {_g(friction.coulomb_pos)}, Fc- {_g(friction.coulomb_neg)} N m, sigma0 {_g(friction.sigma0)} N m/rad."
            if friction is not None
            else "none (the corrected model has no arm friction: F_hat = 0 and the VFE's "
            "eps_hat_F carries all the friction, as with the nominal model)."
        ),
        "",
    ]
    return lines


def observer_section(outcome: RealRigOutcome) -> list[str]:
    study, ref = outcome.observers, outcome.reference
    lines = [
        "## Observers on measured data (`real_observers.csv`, `real_observers.png`)",
        "",
        f"Reference velocity: the paper's zero-phase Butterworth of the encoder angles' derivative at "
        f"{ref['cutoff_hz']:g} Hz (the paper's 5 Hz would erase the balancing loop's motion, which reaches "
        f"{ref['motion_hz']:g} Hz on these runs). On a {ref['motion_hz']:g} Hz sinusoid it keeps "
        f"{ref['gain_at_motion']:.1%} of the amplitude at zero phase; the rig's quantisation, differentiated "
        f"at {1 / outcome.runs.logs[TRAIN_SWINGUP].sample_period:g} Hz, leaves "
        f"{ref['quantisation_rms']:.3g} rad/s RMS in it. The observers are linearised at the upright for the "
        f"balancing parts (from the catch, judged from {SETTLE:g} s after it) and at the hanging equilibrium for "
        f"the chirp (while the pendulum stays within the linear range), with the motor's back-EMF; each is "
        f"tuned per model on the train segments (`real_observer_sweep.csv`):",
        "",
    ]
    for (model, equilibrium), tuned in study.tuned.items():
        edge = [
            observer for observer, value in tuned.items() if _at_edge(study.sweep, model, equilibrium, observer, value)
        ]
        lines.append(
            f"- {model} model, {equilibrium}: HG eps = {tuned['hg'] * 1e3:g} ms, VFE eigenvalues x "
            f"{tuned['vfe']:g}" + (f" (at the edge of the sweep: {', '.join(o.upper() for o in edge)})" if edge else "")
        )
    lines += [
        "",
        "Mean squared velocity error on the held-out segments [(rad/s)^2]:",
        "",
        "| log | model | HG phi_dot | VFE phi_dot | HG / VFE | HG theta_dot | VFE theta_dot | HG / VFE |",
        "|---|---|---|---|---|---|---|---|",
    ]
    by = {(row["observer"], row["model"], row["log"]): row for row in study.rows}
    pairs = list(dict.fromkeys((row["log"], row["model"]) for row in study.rows))
    for log, model in pairs:
        hg, vfe = by[("HG", model, log)], by[("VFE", model, log)]
        lines.append(
            f"| {log} | {model} | {_g(hg['phi_dot_mse'])} | {_g(vfe['phi_dot_mse'])} | "
            f"{hg['phi_dot_mse'] / vfe['phi_dot_mse']:.2f} | {_g(hg['theta_dot_mse'])} | "
            f"{_g(vfe['theta_dot_mse'])} | {hg['theta_dot_mse'] / vfe['theta_dot_mse']:.2f} |"
        )
    vfe_wins = sum(by[("HG", m, log)]["phi_dot_mse"] > by[("VFE", m, log)]["phi_dot_mse"] for log, m in pairs)
    helped = {
        observer: sum(
            by[(observer, "fitted", log)]["phi_dot_mse"] < by[(observer, "nominal", log)]["phi_dot_mse"]
            for log in dict.fromkeys(log for log, _ in pairs)
            if (observer, "fitted", log) in by
        )
        for observer in ("HG", "VFE")
    }
    logs = len(dict.fromkeys(log for log, _ in pairs))
    paper_hg, paper_vfe = PAPER_TABLE2[("phi_dot", "mean")]
    lines += [
        "",
        f"Reading: the VFE has the lower arm velocity error in {vfe_wins} of the {len(pairs)} (log, model) "
        f"pairs; on the paper's rig HG / VFE was {paper_hg / paper_vfe:.1f}. With the corrected model the arm velocity "
        f"error falls for the HG observer on {helped['HG']} and for the VFE on {helped['VFE']} of the {logs} "
        f"held-out logs. " + _ratio_sentence(by, pairs),
        "",
    ]
    return lines


def _ratio_sentence(by: dict, pairs: list) -> str:
    parts = []
    for model in ("nominal", "fitted"):
        ratios = [
            by[("HG", model, log)]["phi_dot_mse"] / by[("VFE", model, log)]["phi_dot_mse"]
            for log, m in pairs
            if m == model
        ]
        if ratios:
            parts.append(f"HG / VFE (arm) ranges {min(ratios):.2f}-{max(ratios):.2f} with the {model} model")
    return "; ".join(parts) + "."


def _at_edge(sweep: list[dict], model: str, equilibrium: str, observer: str, value: float) -> bool:
    values = [
        row["value"]
        for row in sweep
        if (row["model"], row["equilibrium"], row["observer"]) == (model, equilibrium, observer)
    ]
    return value in (min(values), max(values))


def controller_section(outcome: RealRigOutcome) -> list[str]:
    fit = outcome.closed_loop.controller_fit
    lines = [
        "## The controller against the logs (`controller_fit.json`, `controller_fit.png`)",
        "",
        f"Quanser's swing-up and balance law (`controllers/quanser_swingup.py`) fed each swing-up's logged "
        f"angles, with the zero-phase Butterworth velocities and with the server's filtered derivative "
        f"(corner fitted on the train swing-up's balancing voltage: {fit['velocity_filter_corner']:.2f} rad/s):",
        "",
        "| log | part | voltage RMS [V] | RMSE, Butterworth [V] | RMSE, server filter [V] | swing RMSE, "
        "server [V] | balance RMSE, server [V] |",
        "|---|---|---|---|---|---|---|",
    ]
    for name, entry in fit["logs"].items():
        lines.append(
            f"| {name} | {entry['part']} | {_g(entry['voltage_rms'])} | {_g(entry['voltage_rmse'])} | "
            f"{_g(entry['voltage_rmse_server_filter'])} | {_g(entry['swing']['voltage_rmse_server_filter'])} |"
            f" {_g(entry['balance']['voltage_rmse_server_filter'])} |"
        )
    worst = max(entry["voltage_rmse_server_filter"] / entry["voltage_rms"] for entry in fit["logs"].values())
    zero_phase = min(entry["voltage_rmse"] / entry["voltage_rms"] for entry in fit["logs"].values())
    lines += [
        "",
        f"Reading: with the server's causal filter the law gives back every logged voltage to within "
        f"{worst:.1%} of its RMS; with the zero-phase reference the error is at least {zero_phase:.0%} of it: "
        f"the controller is the law as written, and the rig's velocities are the causal filter's (the "
        f"simulations use it).",
        "",
    ]
    return lines


def closed_loop_section(outcome: RealRigOutcome) -> list[str]:
    closed = outcome.closed_loop
    figures = real_closed_loop_study.FIGURES
    lines = [
        "## The closed loop, real and simulated (`real_closed_loop.csv`, `closed_loop_*.png`, "
        "`limit_cycle_spectra.png`)",
        "",
        "Each real swing-up's experiment run in simulation from its first sample at rest, at its sample "
        f"period, with the {QuanserSwingUpParameters().voltage_limit:g} V clip, "
        f"{outcome.runs.rig.counts_per_rev}-count encoders and the server's velocity filter; the balancing figures "
        f"are read from {SETTLE:g} s after the catch, the limit cycle above {LIMIT_CYCLE_MIN_HZ:g} Hz. The "
        f"simulated catch time's range over starts {', '.join(f'{c:+d}' for c in real_closed_loop_study.SPREAD_COUNTS)}"
        " counts off the logged pendulum angle is in `catch_time_min/max`.",
        "",
        "| log | source | " + " | ".join(figures) + " | catch range |",
        "|---|---|" + "---|" * (len(figures) + 1),
    ]
    for row in closed.rows:
        lines.append(
            f"| {row['log']} | {row['source']} | "
            + " | ".join(_g(row[f]) for f in figures)
            + f" | {_g(row['catch_time_min'])}-{_g(row['catch_time_max'])} |"
        )
    models = closed.models
    lines += [
        "",
        "The gap (mean over the runs that balance quietly of |simulated - real|) and the share of the "
        "nominal model's gap each correction closed (`real_closed_loop_gap.csv`):",
        "",
        "| figure | real (mean) | "
        + " | ".join(f"gap, {m}" for m in models)
        + " | "
        + " | ".join(f"closed, {m}" for m in models if m != "nominal")
        + " |",
        "|---|---|" + "---|" * (2 * len(models) - 1),
    ]
    for entry in closed.gap:
        lines.append(
            f"| {entry['figure']} | {_g(entry['real'])} | "
            + " | ".join(_g(entry[f"gap_{m}"]) for m in models)
            + " | "
            + " | ".join(_pct(entry[f"closed_{m}"]) for m in models if m != "nominal")
            + " |"
        )
    closed_well = [e["figure"] for e in closed.gap if e.get("closed_fitted", float("nan")) >= CLOSED]
    open_ = [e["figure"] for e in closed.gap if not e.get("closed_fitted", float("nan")) >= CLOSED]
    lines += [
        "",
        f"Reading: the correction closes at least {CLOSED:.0%} of the gap in {', '.join(closed_well) or 'no figure'}"
        f"; it leaves open {', '.join(open_) or 'nothing'}. "
        + _catch_sentence(closed.rows)
        + " "
        + _offset_sentence(closed.rows, outcome.runs.rig),
        "",
    ]
    return lines


def _catch_sentence(rows: list[dict]) -> str:
    """How robust each source's catch time is over the starts a few counts apart."""
    parts = []
    for source in dict.fromkeys(row["source"] for row in rows):
        mine = [row for row in rows if row["source"] == source and row["part"] != "oscillating"]
        low, high = min(r["catch_time_min"] for r in mine), max(r["catch_time_max"] for r in mine)
        parts.append(f"{source} {_g(low)} to {_g(high)} s")
    return (
        "The catch is one swing or another: over the quietly balancing runs (and, simulated, over starts a few "
        "counts apart) it falls at " + ", ".join(parts) + "."
    )


def _offset_sentence(rows: list[dict], rig) -> str:
    """Where the real loop balances against where the simulations do."""
    real = [row for row in rows if row["source"] == "real"]
    sims = [row for row in rows if row["source"] != "real"]
    return (
        f"The real loop balances with theta at {_g(min(r['theta_mean'] for r in real))} to "
        f"{_g(max(r['theta_mean'] for r in real))} rad (about "
        f"{np.mean([r['theta_mean'] for r in real]) / rig.encoder_resolution:.1f} counts) off the encoder's upright "
        f"and the arm at {_g(min(r['phi_mean'] for r in real))} to {_g(max(r['phi_mean'] for r in real))} rad; "
        f"the simulated loops' mean theta stays within {_g(max(abs(r['theta_mean']) for r in sims))} rad of the "
        f"upright: an offset of the balance point that no model holds."
    )


def open_part_section(outcome: RealRigOutcome) -> list[str]:
    d = outcome.balancing
    loc = d.localization
    lines = [
        "## Where it does not close: the balancing (`diagnosis_balancing/`)",
        "",
        "The diagnosis run again on the balancing (every swing-up from its catch on), starting from the "
        "corrected model: fitted on the swing-ups that balance quietly, judged on the one that balances in a "
        f"saturated oscillation. Verdict **{d.verdict}** (effects: {', '.join(d.effects) or 'none'}); held-out "
        f"gap {_g(d.gap.nominal['heldout'])} -> {_g(d.gap.with_effects['heldout'])} counts "
        f"({_pct(d.gap.heldout_reduction)} reduction).",
        "",
    ]
    for step in d.steps:
        params = ", ".join(f"{key} {_g(value)}" for key, value in step.params.items() if not isinstance(value, str))
        lines.append(f"- {step.effect}: {params}")
    lines += [
        "",
        "Its localisation of the corrected model's held-out gap:",
        "",
        "- signals: " + ", ".join(f"{k} {_pct(v)}" for k, v in loc["signals"].items()),
        "- regimes: "
        + ", ".join(
            f"{r['regime']} {_pct(r['share_of_gap'])} of the gap ({_pct(r.get('share_of_samples'))} of the samples)"
            for r in loc["regimes"]
            if r["share_of_gap"] and r["share_of_gap"] > 0.05
        ),
        "- frequency bands: "
        + ", ".join(f"{b['low_hz']:g}-{b['high_hz']:.0f} Hz {_pct(b['share_of_gap'])}" for b in loc["frequency_bands"]),
        "- worst windows: "
        + "; ".join(f"{w['log']} {w['start']:.2f}-{w['end']:.2f} s ({w['why']})" for w in loc["windows"][:4]),
        "",
    ]
    gap = {entry["figure"]: entry for entry in outcome.closed_loop.gap}
    if "refitted" in outcome.closed_loop.models:
        lines += [
            "With the effects this diagnosis accepted added to the corrected model (`sim_refitted` rows), the "
            "share of the nominal model's gap closed becomes: "
            + ", ".join(
                f"{figure} {_pct(gap[figure]['closed_fitted'])} -> {_pct(gap[figure]['closed_refitted'])}"
                for figure in real_closed_loop_study.FIGURES
            )
            + ".",
            "",
        ]
    rows = {(row["source"], row["log"]): row for row in outcome.closed_loop.rows}
    if ("real", OSCILLATING_SWINGUP) in rows:
        real = rows[("real", OSCILLATING_SWINGUP)]
        sims = [rows[(f"sim_{m}", OSCILLATING_SWINGUP)] for m in outcome.closed_loop.models]
        lines += [
            f"The saturated oscillation of `{OSCILLATING_SWINGUP}` ({_g(real['limit_cycle_hz'])} Hz, "
            f"{_g(real['limit_cycle_amplitude'])} rad, {_g(real['voltage_rms'])} V RMS) against the largest "
            f"simulated balancing limit cycle: {_g(max(s['limit_cycle_amplitude'] for s in sims))} rad.",
            "",
        ]
    return lines


def _g(value) -> str:
    return "n/a" if value is None or (isinstance(value, float) and not math.isfinite(value)) else f"{value:.4g}"


def _pct(value) -> str:
    return "n/a" if value is None or (isinstance(value, float) and not math.isfinite(value)) else f"{value:.0%}"


def reproduce_real(settings, staging: Path, figures: dict, progress) -> str:
    """``reproduce --only real`` inside :func:`furuta_drake.paper.report.run_reproduction` (its ``real``): the
    real-rig studies and their files in ``staging``, under ``settings`` (a ``ReproductionSettings``); returns their
    report.md part. Alone, they also write the nominal run's ``config.yaml``."""
    outcome = run_real_rig(staging, small=settings.small_real, progress=progress)
    figures["real"] = write_real_rig(staging, outcome)
    if set(settings.only) == {"real"}:
        (staging / "config.yaml").write_text(config_yaml_with_provenance(nominal_run_config(outcome)))
    return real_rig_markdown(outcome)


__all__ = [
    "RealRigOutcome",
    "run_real_rig",
    "write_real_rig",
    "nominal_run_config",
    "real_rig_markdown",
    "reproduce_real",
    "correction_section",
    "observer_section",
    "controller_section",
    "closed_loop_section",
    "open_part_section",
]
