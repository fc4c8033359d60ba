"""Blind check of ``furuta-drake tune``: does the controller tuned from a diagnosis balance the "real" rig better
than the one a lab designs on its rig file?

The "real" rig is the independent simulator (benchmarks/independent_sim.py: its own equations of motion, effects
in forms the package does not model). Ten cases carry effects the nominal rig file lacks: arm friction, an input
delay, a cable spring, an inertia error, alone and together, on a Lund-like rig (torque, 1 kHz) and a QUBE-like rig
(voltage, 500 Hz). For each case, as a lab would:

1. record the four 8 s logs of the diagnosis suite (balancing and hanging, train and held-out;
   :func:`benchmarks.diagnosis_independent.write_case`), and diagnose them with the command's default settings;
2. ``tune`` on that diagnosis;
3. run both designs on the simulator in closed loop, balancing from a small seeded disturbance
   (:func:`benchmarks.independent_sim.balance`): the nominal design (the LQR of the rig file) and the tuned one (its
   gain and its friction compensation). The simulator's controller has its own velocity estimate (a dirty
   derivative), so the comparison is of the gains and the compensation, not of the package's observers.
   Each design runs from ``SEEDS`` seeds; the figures are theta's RMS and the limit cycle's amplitude over the
   steady part of each run (:mod:`furuta_drake.tune.limit_cycle`), their mean and run-to-run spread (the standard
   deviation over the seeds).

A case counts as *better* when the tuned mean is below the nominal one for theta's RMS, and as *worse beyond the
spread* when the tuned mean exceeds the nominal one by more than the two spreads added. Writes
``OUT/results.json``, ``OUT/table.md`` and ``OUT/config.json``; every stage is kept under ``OUT`` (``suite``,
``diagnosis``, ``tune``) and reused when the script is run again with the same ``--out``.

Run from the repository root: ``PYTHONPATH=. python benchmarks/tune_blind.py --out runs/tune_blind``
(``--only WORD ...``: the cases whose name holds a word; ``--seeds N``: runs per design).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

from benchmarks import diagnosis_independent as indep
from benchmarks.design_suite import diagnosed
from furuta_drake.outputs import versions

sim = indep.sim
LOG_SECONDS = 8.0  # [s] each of a case's four logs


def cases() -> list[indep.Case]:
    """The ten cases: friction, delay, spring and inertia alone and together, on both rigs."""
    make, karnopp, tanh = indep.make_case, (indep.arm_friction, "karnopp", 0.06, {"breakaway": 1.25}), None
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
    ]


def case_folder(case: indep.Case, out: Path) -> tuple[Path, dict]:
    """The case's nominal rig file and four logs (written once) and its answer."""
    folder = out / "suite" / case.name
    answer = folder / "answer.json"
    if not answer.is_file():
        folder.mkdir(parents=True, exist_ok=True)
        answer.write_text(json.dumps(indep.write_case(case, folder, LOG_SECONDS), indent=2) + "\n")
    return folder, json.loads(answer.read_text())


def run_case(case: indep.Case, out: Path, args) -> dict:
    """Logs, diagnosis (and, in later stages, tune and the closed-loop runs) of one case."""
    folder, answer = case_folder(case, out)
    train, heldout = sorted(folder.glob("train_*.csv")), sorted(folder.glob("heldout_*.csv"))
    report = diagnosed(out / "diagnosis" / case.name, folder / "rig.yaml", train, heldout, args.workers)
    return {
        "case": case.name,
        "expected": answer["expected"],
        "verdict": report["verdict"],
        "effects": report["effects"],
    }


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--only", nargs="+", help="the cases whose name contains one of these words")
    parser.add_argument("--workers", type=int, default=1, help="processes of each diagnosis (default 1)")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    start, rows = time.perf_counter(), []
    for case in indep.select(cases(), False, args.only):
        rows.append(run_case(case, args.out, args))
        print(f"{case.name}: {rows[-1]['verdict']} {rows[-1]['effects']}", flush=True)
    (args.out / "results.json").write_text(json.dumps(rows, indent=2) + "\n")
    config = {"argv": sys.argv[1:] if argv is None else argv, "cases": [row["case"] for row in rows]}
    config["wall_time_s"] = time.perf_counter() - start
    (args.out / "config.json").write_text(json.dumps({**config, **versions()}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
