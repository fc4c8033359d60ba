"""Memory and time of ``furuta-drake diagnose`` on a 10-minute 1 kHz log (600k rows) against a 1-minute log.

The logs are one simulated closed-loop run of the Lund rig (the paper's 0.015 N m Coulomb friction on the arm, a
multisine torque and a square-wave arm reference keeping the arm moving): the 10-minute log is the whole run,
the 1-minute log its first minute. Both are diagnosed in this process, the short one first, with one worker
(``--workers 1``: the candidate fits run in this process, so its memory figures cover all of the diagnosis).

Per log and stage (load: ``load_log``; diagnose: ``diagnose`` and ``write_report``, which load again, fits, replays
in Drake and
writes the report), printed: wall time; the peak resident memory during the stage (sampled from /proc every
20 ms) and its rise over the resident memory before the stage; for the load stage also the tracemalloc peak of
its Python and numpy allocations (tracemalloc slows the diagnosis' Python loops several-fold, so it is not used
for that stage); the process's ``ru_maxrss`` at the end; then the 10-minute / 1-minute ratios (10 would be
linear in the log length). The resident figures include the ~0.2 GB of Drake, numpy and matplotlib that any
run has.

Run from the repository root: ``PYTHONPATH=. python benchmarks/speed/diagnosis_memory.py [--data DIR]`` (``--data``
keeps the simulated logs there and reuses them on the next run).
"""

from __future__ import annotations

import argparse
import dataclasses
import gc
import resource
import tempfile
import threading
import time
import tracemalloc
from pathlib import Path

from furuta_drake.config import ExcitationConfig, SimulationConfig
from furuta_drake.diagnosis.logs.load import load_log
from furuta_drake.diagnosis.pipeline import diagnose
from furuta_drake.diagnosis.report.files import write_report
from furuta_drake.friction import FrictionParameters, JointFrictionParameters
from furuta_drake.results import write_log_csv
from furuta_drake.rig import lund_rig
from furuta_drake.rig_file import load_rig
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import dump_yaml_dataclass

LONG_S, SHORT_S = 600.0, 60.0


def make_logs(data: Path) -> tuple[Path, Path, Path]:
    """rig.yaml, the 10-minute log and its first minute under ``data`` (simulated once, then reused)."""
    rig_path, long_path, short_path = data / "rig.yaml", data / "long_10min.csv", data / "short_1min.csv"
    if long_path.exists() and short_path.exists() and rig_path.exists():
        return rig_path, long_path, short_path
    data.mkdir(parents=True, exist_ok=True)
    rig = lund_rig()
    base = SimulationConfig.from_rig(rig)
    config = dataclasses.replace(
        base,
        duration=LONG_S,
        seed=3,
        initial_state=[0.02, 0.0, 0.0, 0.0],
        friction=FrictionParameters(arm=JointFrictionParameters.coulomb(0.015, 1e-4, regularization_velocity=1e-2)),
        controller=dataclasses.replace(base.controller, velocity_source="true"),
        excitation=ExcitationConfig(torque_rms=0.02, arm_reference_amplitude=0.3, arm_reference_period=4.0),
    )
    start = time.perf_counter()
    result = simulate(config)
    print(f"simulated the {LONG_S:.0f} s log in {time.perf_counter() - start:.0f} s")
    rig_path.write_text(dump_yaml_dataclass(rig))
    write_log_csv(result, long_path)
    with long_path.open() as source, short_path.open("w") as target:
        for i, line in enumerate(source):
            if i > SHORT_S / rig.sample_period:
                break
            target.write(line)
    return rig_path, long_path, short_path


def resident_mb() -> float:
    """The process's current resident set size [MB] (Linux /proc)."""
    with open("/proc/self/statm") as statm:
        return int(statm.read().split()[1]) * resource.getpagesize() / 2**20


def measure(stage, traced: bool = False) -> dict:
    """Wall time of ``stage()``, its peak resident memory and the rise over the memory before it [MB], and with
    ``traced`` the tracemalloc peak of its allocations [MB]."""
    gc.collect()
    before = resident_mb()
    peak = [before]
    done = threading.Event()

    def sample() -> None:
        while not done.wait(0.02):
            peak[0] = max(peak[0], resident_mb())

    sampler = threading.Thread(target=sample, daemon=True)
    sampler.start()
    if traced:
        tracemalloc.start()
    start = time.perf_counter()
    stage()
    seconds = time.perf_counter() - start
    figures = {"seconds": seconds}
    if traced:
        figures["traced_peak_mb"] = tracemalloc.get_traced_memory()[1] / 2**20
        tracemalloc.stop()
    done.set()
    sampler.join()
    peak[0] = max(peak[0], resident_mb())
    figures.update(rss_peak_mb=peak[0], rss_rise_mb=peak[0] - before)
    return figures


def stages(rig_path: Path, log_path: Path, out: Path, workers: int) -> dict:
    rig = load_rig(rig_path)
    return {
        "load": lambda: load_log(log_path, rig),
        "diagnose": lambda: write_report(
            out / log_path.stem, diagnose(rig=rig_path, train=[log_path], workers=workers), force=True
        ),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, help="directory for the simulated logs (kept and reused)")
    parser.add_argument("--workers", type=int, default=1, help="processes for the candidate fits (default 1)")
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as scratch:
        rig_path, long_path, short_path = make_logs(args.data or Path(scratch) / "logs")
        logs = {"1 min": short_path, "10 min": long_path}
        rows = {name: sum(1 for _ in path.open()) - 1 for name, path in logs.items()}
        print(
            f"logs: {rows['1 min']} and {rows['10 min']} rows ({short_path.stat().st_size / 2**20:.1f} and "
            f"{long_path.stat().st_size / 2**20:.1f} MB of CSV); workers {args.workers}",
            flush=True,
        )
        figures = {}
        for name, path in logs.items():
            runs = stages(rig_path, path, Path(scratch) / "reports", args.workers)
            figures[name] = {"load": measure(runs["load"], traced=True), "diagnose": measure(runs["diagnose"])}
            print(f"  {name}: {figures[name]}", flush=True)
        maxrss = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024  # Linux: KiB
    print(
        f"\n{'log':7} {'stage':9} {'time [s]':>9} {'peak RSS [MB]':>14} {'RSS rise [MB]':>14} "
        f"{'tracemalloc peak [MB]':>22}"
    )
    for name in logs:
        for stage in ("load", "diagnose"):
            f = figures[name][stage]
            traced = f"{f['traced_peak_mb']:22.1f}" if "traced_peak_mb" in f else f"{'-':>22}"
            print(f"{name:7} {stage:9} {f['seconds']:9.2f} {f['rss_peak_mb']:14.0f} {f['rss_rise_mb']:14.0f} {traced}")
    print(f"ru_maxrss of the process: {maxrss:.0f} MB")
    print("\nratios 10 min / 1 min (10 would be linear in the log length):")
    for stage in ("load", "diagnose"):
        long, short = figures["10 min"][stage], figures["1 min"][stage]
        traced = (
            f", tracemalloc peak {long['traced_peak_mb'] / short['traced_peak_mb']:.1f}x"
            if "traced_peak_mb" in long
            else ""
        )
        print(
            f"  {stage:9} time {long['seconds'] / short['seconds']:.1f}x, RSS rise "
            f"{long['rss_rise_mb'] / max(short['rss_rise_mb'], 1.0):.1f}x{traced}"
        )
    per_row = figures["10 min"]["diagnose"]["rss_rise_mb"] * 2**20 / rows["10 min"]
    print(f"  the diagnosis of the 10-minute log adds {per_row:.0f} bytes of resident memory per row")


if __name__ == "__main__":
    main()
