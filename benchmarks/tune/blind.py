"""Blind check of ``furuta-drake tune``: does the controller tuned from a diagnosis balance the "real" rig better
than the one a lab designs on its rig file?

The "real" rig is the independent simulator (benchmarks/independent/simulator.py: its own equations of motion, effects
in forms the package does not model). Ten cases carry effects the nominal rig file lacks: arm friction, an input
delay, a cable spring, an inertia error, alone and together, on a Lund-like rig (torque, 1 kHz) and a QUBE-like rig
(voltage, 500 Hz). For each case, as a lab would:

1. record the four 8 s logs of the diagnosis suite (balancing and hanging, train and held-out;
   :func:`benchmarks.diagnosis.independent.write_case`), and diagnose them with the command's default settings;
2. ``tune`` on that diagnosis;
3. run both designs on the simulator in closed loop, balancing from a small seeded disturbance
   (:func:`benchmarks.independent.simulator.regulate`): the nominal design (the LQR of the rig file on the HG observer)
   and the tuned one (its gain, its observer and its friction compensation), each as ``tune`` writes it
   (``nominal.yaml``, ``controller.yaml``) and run as a lab's controller
   (:class:`furuta_drake.lab_controller.LabController`: the same Drake blocks as ``tune``'s predictions, observers,
   Dahl observer, K_sigma adaptation and compensation included, fed the simulator's encoder samples).
   Each design runs from ``SEEDS`` seeds; the figures are theta's RMS and the limit cycle's amplitude over the
   steady part of each run (:mod:`furuta_drake.tune.limit_cycle`), their mean and run-to-run spread (the standard
   deviation over the seeds).

Per figure, a case counts as *better* when the tuned mean is below the nominal one, and as *worse beyond the
spread* when the tuned mean exceeds the nominal one by more than the two spreads added. Writes
``OUT/results.json``, ``OUT/table.md`` and ``OUT/config.json``; every stage is kept under ``OUT`` (``suite``,
``diagnosis``, ``tune``) and reused when the script is run again with the same ``--out``.

Run from the repository root: ``PYTHONPATH=. python benchmarks/tune/blind.py --out runs/tune_blind``
(``--only WORD ...``: the cases whose name holds a word; ``--workers N``: processes of each diagnosis and tune).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.design.suite import diagnosed
from benchmarks.diagnosis import independent as indep
from furuta_drake.config import SimulationConfig, load_config
from furuta_drake.errors import FurutaError
from furuta_drake.lab_controller import LabController
from furuta_drake.outputs import versions
from furuta_drake.tune.controller import initial_angle
from furuta_drake.tune.limit_cycle import limit_cycle, rms, steady_part
from furuta_drake.tune.output import write_tune
from furuta_drake.tune.pipeline import TuneSettings, tune

sim = indep.sim
LOG_SECONDS = 8.0  # [s] each of a case's four logs
RUN_SECONDS = 10.0  # [s] each closed-loop run on the simulator (its second half is the steady part)
SEEDS = (1, 2, 3, 4)  # the closed-loop runs of each design (seeded start and sensor noise)
DESIGNS = ("nominal", "tuned")
FIGURES_JUDGED = ("theta_rms", "limit_cycle_amplitude")
FILES = {"nominal": "nominal.yaml", "tuned": "controller.yaml"}  # each design's simulate config in tune's output


def cases() -> list[indep.Case]:
    """The eleven cases: friction, delay, spring and inertia alone and together on both rigs, and arm friction on a
    geared rig logged at 100 Hz."""
    make, karnopp = indep.make_case, (indep.arm_friction, "karnopp", 0.06, {"breakaway": 1.25})
    tanh = (indep.arm_friction, "tanh", 0.08, {"smoothing": 0.02})
    return [
        make("lund", karnopp, seed=31),
        make("qube", tanh, seed=32),
        make("lund", (indep.delay, 3), seed=33),
        make("qube", (indep.delay, 2), seed=34),
        make("lund", (indep.spring, 0.25, {"offset": 0.05}), seed=35),
        make("qube", (indep.inertia, {"pendulum_mass": 1.1, "arm_inertia": 1.2}), seed=36),
        make("lund", (indep.inertia, {"pendulum_mass": 1.15, "pendulum_com": 1.05, "arm_inertia": 0.85}), seed=37),
        make("lund", karnopp, (indep.delay, 3), seed=38),
        make("qube", tanh, (indep.delay, 2), (indep.inertia, {"pendulum_mass": 1.1, "arm_inertia": 1.2}), seed=39),
        make(
            "lund",
            (indep.arm_friction, "tanh", 0.05, {"smoothing": 0.02}),
            (indep.spring, 0.25, {"offset": 0.05}),
            (indep.delay, 2),
            seed=40,
        ),
        make("geared", (indep.arm_friction, "tanh", 0.03, {"smoothing": 0.02}), seed=41),
    ]


def disturbed(case: indep.Case, percent: float) -> indep.Case:
    """``case`` with an ongoing arm torque of ``percent`` % of the rig's torque limit RMS (the simulator's coloured
    disturbance, :class:`benchmarks.independent.simulator.ArmDisturbance`); its name ends in ``__d<percent>``."""
    if percent == 0:
        return case
    rig = case.world.rig
    level = percent / 100.0 * rig.command_limit * rig.torque_per_command
    world = dataclasses.replace(case.world, disturbance_rms=level)
    return dataclasses.replace(case, name=f"{case.name}__d{percent:g}", world=world)


def case_folder(case: indep.Case, out: Path) -> tuple[Path, dict]:
    """The case's nominal rig file and four logs (written once) and its answer."""
    folder = out / "suite" / case.name
    answer = folder / "answer.json"
    if not answer.is_file():
        folder.mkdir(parents=True, exist_ok=True)
        answer.write_text(json.dumps(indep.write_case(case, folder, LOG_SECONDS), indent=2) + "\n")
    return folder, json.loads(answer.read_text())


def tuned(directory: Path, diagnosis: Path, workers: int | None) -> dict:
    """tune.json of ``tune`` on the diagnosis (written once), or ``{"refused": reason}``."""
    refused = directory / "refused.txt"
    if refused.is_file():
        return {"refused": refused.read_text()}
    if not (directory / "tune.json").is_file():
        try:
            write_tune(directory, tune(diagnosis, TuneSettings(workers=workers)), force=True)
        except FurutaError as err:
            directory.mkdir(parents=True, exist_ok=True)
            refused.write_text(str(err))
            return {"refused": str(err)}
    return json.loads((directory / "tune.json").read_text())


def closed_loop(case: indep.Case, config: SimulationConfig, seed: int) -> dict:
    """One balancing run of a design (its simulate config) on the case's true rig: theta's RMS and the limit
    cycle's amplitude over the steady part of the encoder's theta [rad], and whether it fell."""
    rig = case.world.rig
    controller = LabController(config)

    def command(measured: np.ndarray) -> float:  # the rig's command units
        return controller(measured) / rig.torque_per_command

    log = sim.regulate(case.world, command, RUN_SECONDS, seed, initial_angle(seed))
    theta = log.measured[:, 0]
    amplitude, frequency = limit_cycle(theta, rig.sample_period)
    return {
        "seed": seed,
        "theta_rms": rms(steady_part(theta)),
        "limit_cycle_amplitude": amplitude,
        "limit_cycle_frequency": frequency,
        "effort_rms": rms(steady_part(log.command)),
        "fell": log.fell,
    }


def closed_loops(case: indep.Case, directory: Path, path: Path) -> dict:
    """Every design's runs on the case's true rig (written once to ``path``); ``directory``: tune's output."""
    if not path.is_file():
        runs = {
            name: [closed_loop(case, load_config(directory / FILES[name]), seed) for seed in SEEDS] for name in DESIGNS
        }
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(runs, indent=2) + "\n")
    return json.loads(path.read_text())


def summary(runs: list[dict]) -> dict:
    """Mean and run-to-run spread (standard deviation over the seeds) of each figure; a run that fell counts as
    the pendulum's fall, inf."""
    out = {"fell": sum(run["fell"] for run in runs)}
    for figure in FIGURES_JUDGED:
        values = np.array([math.inf if run["fell"] else run[figure] for run in runs])
        out[figure] = {"mean": float(np.mean(values)), "spread": float(np.std(values))}
    return out


def judged(row: dict, count: float) -> dict:
    """Per figure (theta's RMS, the limit cycle's amplitude): ``better`` when the tuned mean is below the nominal
    one, ``worse`` when it is above it by more than the two spreads added, ``clearly_better`` when it is below it
    by more than that, and ``room`` when the nominal's mean exceeds one encoder count (``count`` [rad]) by more
    than its spread (where a tuned design should be clearly better); and per design the predicted theta RMS over
    the measured mean (``predicted_over_measured``)."""
    nominal, tuned_ = row["nominal"], row["tuned"]
    out = {}
    for figure in FIGURES_JUDGED:
        difference = tuned_[figure]["mean"] - nominal[figure]["mean"]
        spread = nominal[figure]["spread"] + tuned_[figure]["spread"]
        out[f"better_{figure}"] = bool(difference < 0)
        out[f"worse_{figure}"] = bool(difference > spread)
        out[f"clearly_better_{figure}"] = bool(-difference > spread)
        out[f"room_{figure}"] = bool(nominal[figure]["mean"] > count + nominal[figure]["spread"])
    out["predicted_over_measured"] = {
        name: (row["predicted"][name].get("theta_rms") or math.nan) / row[name]["theta_rms"]["mean"] for name in DESIGNS
    }
    return out


def run_case(case: indep.Case, out: Path, args) -> dict:
    """Logs, diagnosis, tune and both designs' closed-loop runs of one case."""
    folder, answer = case_folder(case, out)
    train, heldout = sorted(folder.glob("train_*.csv")), sorted(folder.glob("heldout_*.csv"))
    report = diagnosed(out / "diagnosis" / case.name, folder / "rig.yaml", train, heldout, args.workers)
    row = {
        "case": case.name,
        "expected": answer["expected"],
        "verdict": report["verdict"],
        "effects": report["effects"],
    }
    document = tuned(out / "tune" / case.name, out / "diagnosis" / case.name, args.workers)
    if "refused" in document:
        return {**row, "refused": document["refused"]}
    runs = closed_loops(case, out / "tune" / case.name, out / "closed_loop" / f"{case.name}.json")
    row.update({name: summary(runs[name]) for name in DESIGNS})
    row["predicted"] = {name: document["designs"][name]["predicted"] for name in DESIGNS}
    row["disturbance_read"] = document.get("disturbance")
    row["tuned_design"] = {
        "lqr_gain": document["designs"]["tuned"]["lqr_gain"],
        "compensation": document["designs"]["tuned"]["friction_compensation"]["gain"],
        "observer": document["designs"]["tuned"]["observer"]["kind"],
        "family_member": document["designs"]["tuned"].get("family_member"),
    }
    rig = case.world.rig
    return {**row, **judged(row, 2 * math.pi / rig.counts_per_rev)}


def _figure(entry: dict, figure: str) -> str:
    value = entry[figure]
    if not math.isfinite(value["mean"]):
        return "fell"
    return f"{1e3 * value['mean']:.3g} +- {1e3 * value['spread']:.2g}"


def _design(design: dict) -> str:
    """The tuned design in a few words: its member of the family, or the nominal design kept."""
    member = design.get("family_member")
    if member is None:
        return "nominal kept"
    weights = f"Q_theta x {member['theta_weight_scale']:g}, Q_phi x {member['phi_weight_scale']:g}"
    text = f"{design['observer']} x {member['observer_scale']:g}, {weights}, R x {member['input_weight_scale']:g}"
    return text + (f", K_sigma {design['compensation']:g}" if design["observer"] == "vfe" else "")


def _predicted(row: dict) -> str:
    """Theta's RMS predicted on the corrected model [mrad], nominal -> tuned."""
    values = [row["predicted"][name].get("theta_rms") for name in DESIGNS]
    return " -> ".join("fell" if v is None else f"{1e3 * v:.3g}" for v in values)


def _verdict(row: dict, prefix: str) -> str:
    return ", ".join("yes" if row[f"{prefix}{figure}"] else "no" for figure in FIGURES_JUDGED)


def _room(row: dict) -> str:
    """Per figure: '-' where the nominal design leaves no room (within a count), else whether the tuned one is
    better beyond the spread."""
    return ", ".join(
        ("yes" if row[f"clearly_better_{f}"] else "no") if row[f"room_{f}"] else "-" for f in FIGURES_JUDGED
    )


def table(rows: list[dict]) -> str:
    """The Markdown table of the runs: per case, both designs' theta RMS and limit-cycle amplitude [mrad] (mean +-
    run-to-run spread over the seeds) and the verdict."""
    lines = [
        "| case | diagnosis | tuned design | theta RMS predicted [mrad] | theta RMS nominal [mrad] "
        "| theta RMS tuned | limit cycle nominal [mrad] | limit cycle tuned | tuned better (theta, limit cycle) "
        "| worse beyond the spread | better beyond the spread where the nominal exceeds a count "
        "| predicted / measured theta RMS (nominal, tuned) |",
        "|---|---|---|---|---:|---:|---:|---:|---|---|---|---|",
    ]
    for row in rows:
        effects = "+".join(row["effects"]) or row["verdict"]
        if "refused" in row:
            lines.append(f"| {row['case']} | {effects} | refused: {row['refused']} | | | | | | | | | |")
            continue
        lines.append(
            f"| {row['case']} | {effects} | {_design(row['tuned_design'])} | {_predicted(row)} | "
            f"{_figure(row['nominal'], 'theta_rms')} | {_figure(row['tuned'], 'theta_rms')} | "
            f"{_figure(row['nominal'], 'limit_cycle_amplitude')} | {_figure(row['tuned'], 'limit_cycle_amplitude')} | "
            f"{_verdict(row, 'better_')} | {_verdict(row, 'worse_')} | {_room(row)} | "
            + ", ".join(f"{row['predicted_over_measured'][name]:.2f}" for name in DESIGNS)
            + " |"
        )
    judged_rows = [row for row in rows if "refused" not in row]
    for figure in FIGURES_JUDGED:
        better = sum(row[f"better_{figure}"] for row in judged_rows)
        worse = sum(row[f"worse_{figure}"] for row in judged_rows)
        lines.append(f"\n{figure}: tuned better in {better} of {len(rows)} cases, worse beyond the spread in {worse}.")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--only", nargs="+", help="the cases whose name contains one of these words")
    parser.add_argument("--workers", type=int, default=1, help="processes of each diagnosis and tune (default 1)")
    parser.add_argument(
        "--disturbance",
        type=float,
        nargs="+",
        default=[0.0],
        help="the rigs' ongoing arm torque, RMS in %% of the torque limit (coloured); one suite per level (default 0)",
    )
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    start, rows = time.perf_counter(), []
    chosen = indep.select(cases(), False, args.only)
    for case in [disturbed(case, level) for level in args.disturbance for case in chosen]:
        rows.append(run_case(case, args.out, args))
        print(f"{case.name}: {rows[-1]['verdict']} {rows[-1]['effects']}", flush=True)
        (args.out / "results.json").write_text(json.dumps(rows, indent=2) + "\n")
    text = table(rows)
    (args.out / "table.md").write_text(text)
    print(text)
    config = {"argv": sys.argv[1:] if argv is None else argv, "cases": [row["case"] for row in rows]}
    config.update(seeds=list(SEEDS), run_seconds=RUN_SECONDS, log_seconds=LOG_SECONDS)
    config["disturbance_percent"] = args.disturbance
    config["wall_time_s"] = time.perf_counter() - start
    (args.out / "config.json").write_text(json.dumps({**config, **versions()}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
