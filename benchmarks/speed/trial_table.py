"""Time and memory of ``furuta-drake diagnose --run-column`` on a trial table: N trials of 4 s at 125 Hz in one
file, as identification data often comes.

The trials are one open-loop run of the QUBE-Servo 2 under the low-rate benchmark's bang-bang command (+-7 V,
random 25-75 ms dwells; :mod:`benchmarks.diagnosis.low_rate`) with the arm's Coulomb friction of the project's simulator
suite, cut into 4 s pieces, each with its own time base from 0 and started wherever the last one left the rig; a
``trial`` column numbers them. Each table is diagnosed in a child process (``furuta-drake diagnose --run-column
trial --workers W``).

Printed per trial count: rows, the file's size, the wall time, the CPU time of the diagnosis and its workers
(user + system), the peak resident memory of the largest process (``ru_maxrss`` of the children), the verdict;
then the ratios between the largest and the smallest trial count (the data grow by the trial ratio). With
``--one-run`` each table's samples are also diagnosed as one run (time continued, no trial column): the CPU
difference is what the many-runs path itself costs. Target:
200 trials within 10 minutes on 2 cores, memory that does not grow per trial beyond the data.

Run from the repository root: ``PYTHONPATH=. nice -n 10 python benchmarks/speed/trial_table.py --out DIR [--trials 20
200] [--workers 2]``; ``DIR`` keeps the tables and reports (a table already there is reused).
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.diagnosis.low_rate import RATES, lab_rig, run_config
from benchmarks.diagnosis.suite import CaseSpec
from furuta_drake.diagnosis.logs.writers import write_log
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import dump_yaml_dataclass

TRIAL_S = 4.0
CASE = CaseSpec("qube_servo2", ("arm_coulomb_friction",), 2, 1)


def write_table(out: Path, trials: int) -> tuple[Path, Path]:
    """The rig file and a CSV of ``trials`` 4 s trials (time from 0 in each, a 'trial' column)."""
    rig = lab_rig(CASE.rig, RATES["125Hz"])
    rig_path, table = out / "rig.yaml", out / f"trials_{trials}.csv"
    rig_path.write_text(dump_yaml_dataclass(rig))
    if table.exists():
        return rig_path, table
    result = simulate(run_config(rig, CASE, seed=7, duration=trials * TRIAL_S))
    per_trial = int(round(TRIAL_S / rig.sample_period))
    n = trials * per_trial
    index = np.arange(n)
    columns = {
        "trial": (index // per_trial).astype(float),
        "time": (index % per_trial) * rig.sample_period,
        "theta": result.measured[:n, 0],
        "phi": result.measured[:n, 1],
        "torque": result.torque[:n],
    }
    write_log(table, columns)
    return rig_path, table


def one_run(table: Path) -> Path:
    """The same samples as one run (time continued across the trials, no trial column): the per-run overhead's
    baseline."""
    data = np.genfromtxt(table, delimiter=",", names=True)
    columns = {name: data[name] for name in ("theta", "phi", "torque")}
    path = table.with_name(table.stem + "_one_run.csv")
    write_log(path, {"time": np.arange(data.size) * RATES["125Hz"], **columns})
    return path


def diagnose(rig_path: Path, table: Path, out: Path, workers: int, by_run: bool = True) -> dict:
    """Diagnose ``table`` in a child process: wall, CPU and peak RSS of it and its workers, and its verdict."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    command = [sys.executable, "-m", "furuta_drake.cli", "diagnose", "--rig", str(rig_path), "--train", str(table)]
    command += (["--run-column", "trial"] if by_run else []) + ["--workers", str(workers), "--out", str(out), "--force"]
    subprocess.run(command, check=True, stdout=subprocess.DEVNULL)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    report = json.loads((out / "report.json").read_text())
    return {"wall_s": wall, "cpu_s": cpu, "peak_rss_mb": after.ru_maxrss / 1024, "verdict": report["verdict"]}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--trials", nargs="+", type=int, default=[20, 200])
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--one-run", action="store_true", help="also diagnose each table's samples as one run")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    print(f"{'trials':>6} {'rows':>7} {'MB':>6} {'wall s':>7} {'CPU s':>7} {'peak RSS MB':>11}  verdict")
    for trials in sorted(args.trials):
        rig_path, table = write_table(args.out, trials)
        row = {
            "trials": trials,
            "rows": trials * int(round(TRIAL_S / RATES["125Hz"])),
            "mb": table.stat().st_size / 1e6,
        }
        row.update(diagnose(rig_path, table, args.out / f"report_{trials}", args.workers))
        rows.append(row)
        print(
            f"{trials:>6} {row['rows']:>7} {row['mb']:>6.1f} {row['wall_s']:>7.0f} {row['cpu_s']:>7.0f} "
            f"{row['peak_rss_mb']:>11.0f}  {row['verdict']}",
            flush=True,
        )
        if args.one_run:
            alone = diagnose(rig_path, one_run(table), args.out / f"report_{trials}_one_run", args.workers, False)
            print(
                f"{'1 run':>6} {'':>7} {'':>6} {alone['wall_s']:>7.0f} {alone['cpu_s']:>7.0f} {'':>11}  "
                f"{alone['verdict']}  (the same samples as one run)",
                flush=True,
            )
    if len(rows) > 1:
        small, large = rows[0], rows[-1]
        print(
            f"ratios {large['trials']}/{small['trials']} trials (data x{large['rows'] / small['rows']:.0f}): wall "
            f"x{large['wall_s'] / small['wall_s']:.1f}, CPU x{large['cpu_s'] / small['cpu_s']:.1f}, peak RSS "
            f"x{large['peak_rss_mb'] / small['peak_rss_mb']:.2f}"
        )
    (args.out / "trial_table.json").write_text(json.dumps(rows, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
