"""Wall and CPU time of ``furuta-drake diagnose`` per case, and where it goes.

Each case folder (``rig.yaml``, ``train_*.csv``, ``heldout_*.csv``, as the suites of
``benchmarks/diagnosis/confusion.py`` and ``benchmarks/diagnosis/independent.py`` write them with
``--generate-only``) is diagnosed in this process, once per case. Printed per case: wall time, CPU time (this
process and its finished worker processes), the wall time on free cores, the wall time of each stage of the
pipeline (loading, windows, the selection's tasks by phase: forward steps with their joint refits, pair entry,
form refits, backward refits, exchanges; detection limits, Drake replays, ``--folds``) with each phase's tasks
and their CPU time, and the verdict; then the median and the worst of each suite.

On a machine shared with other jobs the wall time counts their time slices too; the wall time on free cores
estimates it for an idle machine: this process's CPU time outside the batches of tasks plus, per batch, the
time its tasks' CPU times take on ``--workers`` cores handed out in order, and at least CPU / cores. Work that
runs at once (the folds' selections, the replays beside the detection limits) breaks the sum: there the
estimate is CPU / cores, reached when the concurrent work keeps every core busy.
With ``--profile`` the cases run in this process (one worker) under cProfile and the functions holding the
most cumulative time are printed. ``--reports DIR`` writes every case's report (to compare the results of two
versions of the code: ``--compare DIR`` prints, per case, whether the verdict, effects and every parameter
printed in ``report.md`` are identical to those of the reports in DIR).

A machine's speed can drift by more than a lever's gain within the hour a suite takes, so two suites run one
after the other do not compare. ``--reference DIR`` (another checkout of this repository, e.g. ``git worktree add
DIR <commit>``, its numba cache warmed by one small case) interleaves instead: every case runs with the code of
DIR, then with this code, each in a process of its own, and the table prints both times and their CPU ratio.
The drift then falls on both alike.

Run from the repository root, e.g.
``PYTHONPATH=. python benchmarks/speed/diagnosis.py --suite own runs/own/suite/cases/* --workers 2``.
"""

from __future__ import annotations

import argparse
import cProfile
import inspect
import json
import os
import pstats
import re
import resource
import statistics
import subprocess
import sys
import time
from collections import defaultdict
from pathlib import Path

import benchmarks
from furuta_drake.diagnosis import pipeline
from furuta_drake.diagnosis.gap import replay
from furuta_drake.diagnosis.report.files import write_report

PHASES = {  # the selection's function that asked for a batch of fits -> the phase it is reported as
    "step": "forward",
    "joint_refits": "forward",
    "_enter_pair": "pair entry",
    "_refit_forms": "form refits",
    "_backward": "backward",
    "_exchange": "exchange",
}
STAGES = ("load_logs", "make_windows", "detection_limits", "replay_gaps", "consistency", "localize")


def _cpu_seconds() -> float:
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


class CpuTimed:
    """A task function that also returns the CPU seconds it took (in whichever process ran it)."""

    def __init__(self, function):
        self.function = function

    def __call__(self, task):
        start = time.process_time()
        result = self.function(task)
        return result, time.process_time() - start


def makespan(seconds: list[float], workers: int) -> float:
    """Wall time of tasks of these CPU seconds handed in order to ``workers`` free cores (each to the first
    core free, as the pool does)."""
    free = [0.0] * max(1, min(workers, len(seconds)))
    for s in seconds:
        free[free.index(min(free))] += s
    return max(free, default=0.0)


class StageClock:
    """Wall time per stage: the pipeline's stage functions and its task runner wrapped while a case runs; also
    each batch's task CPU times, from which the wall time on ``workers`` free cores is estimated."""

    def __init__(self, workers: int):
        self.workers = workers
        self.seconds: dict[str, float] = defaultdict(float)
        self.tasks: dict[str, int] = defaultdict(int)
        self.main_in_batches = 0.0  # CPU seconds of this process while batches ran
        self.task_cpu: dict[str, float] = defaultdict(float)  # per phase, CPU seconds inside its tasks
        self.ideal = 0.0  # the batches' wall times on free cores
        self._saved = {}

    def _timed(self, label, function):
        def wrapper(*args, **kwargs):
            start = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                self.seconds[label] += time.perf_counter() - start

        return wrapper

    def _timed_run(self, function):
        def wrapper(task_function, tasks, **kwargs):
            callers = [frame.function for frame in inspect.stack()[1:8]]
            phase = next((PHASES[name] for name in callers if name in PHASES), "other tasks")
            if "selection_on" in callers:  # a fold's selection (its own thread)
                phase = "folds: " + phase
            if "replay_gaps" in callers:
                phase = "replays"
            start, main = time.perf_counter(), time.process_time()
            try:
                timed = function(CpuTimed(task_function), tasks, **kwargs)
            finally:
                self.seconds["tasks: " + phase] += time.perf_counter() - start
                self.tasks["tasks: " + phase] += len(tasks)
            cpu = [r[1] if isinstance(r, tuple) else 0.0 for r in timed]
            main = time.process_time() - main  # the tasks' CPU when they ran in this process, else pickling's
            self.main_in_batches += main
            self.task_cpu["tasks: " + phase] += sum(cpu)
            self.ideal += max(makespan(cpu, self.workers), main)
            return [r[0] if isinstance(r, tuple) else r for r in timed]

        return wrapper

    def __enter__(self):
        for name in STAGES:
            self._saved[name] = getattr(pipeline, name)
            setattr(pipeline, name, self._timed(name, self._saved[name]))
        for module in (pipeline, replay):
            self._saved[module, "run_tasks"] = module.run_tasks
            module.run_tasks = self._timed_run(module.run_tasks)
        return self

    def __exit__(self, *exc):
        for name, function in self._saved.items():
            module, name = name if isinstance(name, tuple) else (pipeline, name)
            setattr(module, name, function)


TRIAL_SECONDS, TRIAL_PERIOD = 4.0, 0.008  # a trial set: many short logs at 125 Hz


def _write_trial(args) -> None:
    import dataclasses

    from benchmarks.diagnosis.suite import run_configs, with_effect
    from furuta_drake.results import write_log_csv
    from furuta_drake.simulate import simulate

    rig, folder, trial = args
    configs = run_configs(rig, trial, TRIAL_SECONDS)
    config = with_effect(configs["hanging"], "input_delay", 2)
    write_log_csv(simulate(dataclasses.replace(config, seed=trial)), folder / f"trial_{trial:03d}.csv")


def write_trials(folder: Path, count: int, workers: int) -> None:
    """``count`` trials of ``TRIAL_SECONDS`` on the QUBE-Servo 2 sampled at 125 Hz with a transport delay of two
    samples (hanging under an open-loop multisine seeded by the trial's number), and the nominal rig file."""
    import dataclasses
    from concurrent.futures import ProcessPoolExecutor

    from furuta_drake.rig import qube_servo2_rig
    from furuta_drake.yamlio import dump_yaml_dataclass

    folder.mkdir(parents=True, exist_ok=True)
    rig = dataclasses.replace(qube_servo2_rig(), sample_period=TRIAL_PERIOD)
    (folder / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    with ProcessPoolExecutor(workers) as pool:
        list(pool.map(_write_trial, [(rig, folder, trial) for trial in range(count)]))


def case_inputs(folder: Path) -> dict:
    """The diagnose() inputs of a case folder; of the real QUBE logs (no train_/heldout_ names) the two 5 s
    logs are held out."""
    train, heldout = sorted(folder.glob("train_*.csv")), sorted(folder.glob("heldout_*.csv"))
    if not train and list(folder.glob("trial_*.csv")):  # a trial set: part of every trial held out
        return {"rig": folder / "rig.yaml", "train": sorted(folder.glob("trial_*.csv")), "heldout": []}
    if not train:
        logs = sorted(folder.glob("*.csv"))
        heldout = [log for log in logs if "_5s_" in log.name]
        train = [log for log in logs if log not in heldout]
    return {"rig": folder / "rig.yaml", "train": train, "heldout": heldout}


def run_case(folder: Path, workers: int | None, folds: int | None, reports: Path | None) -> dict:
    inputs = case_inputs(folder)
    with StageClock(workers) as clock:
        start, cpu, own = time.perf_counter(), _cpu_seconds(), time.process_time()
        diagnosis = pipeline.diagnose(**inputs, workers=workers, folds=folds)
        wall, cpu, own = time.perf_counter() - start, _cpu_seconds() - cpu, time.process_time() - own
    if reports is not None:
        write_report(reports / folder.name, diagnosis, force=True)
    return {
        "case": folder.name,
        "wall": wall,
        "cpu": cpu,
        "quiet": max(own - clock.main_in_batches + clock.ideal, cpu / max(workers, 1)),
        "stages": dict(clock.seconds),
        "tasks": dict(clock.tasks),
        "task_cpu": dict(clock.task_cpu),
        "verdict": diagnosis.verdict,
        "effects": diagnosis.effects,
    }


def print_table(suite: str, rows: list[dict]) -> None:
    print(f"\n## {suite}: {len(rows)} cases\n")
    print("| case | wall [s] | CPU [s] | wall on free cores [s] | verdict | where the wall time goes [s] (tasks) |")
    print("|---|---:|---:|---:|---|---|")
    for row in rows:
        stages = ", ".join(
            f"{name} {seconds:.1f}"
            + (f" ({row['tasks'][name]} tasks, {row['task_cpu'][name]:.1f} s CPU)" if name in row["tasks"] else "")
            for name, seconds in sorted(row["stages"].items(), key=lambda item: -item[1])
            if seconds >= 0.05
        )
        print(
            f"| {row['case']} | {row['wall']:.1f} | {row['cpu']:.1f} | {row['quiet']:.1f} | {row['verdict']} | "
            f"{stages} |"
        )
    for key, label in (("wall", "wall"), ("cpu", "CPU"), ("quiet", "wall on free cores")):
        values = [row[key] for row in rows]
        print(f"\n{label}: median {statistics.median(values):.1f} s, worst {max(values):.1f} s", end="")
    print(f"\nload average {os.getloadavg()} ({os.cpu_count()} cores)")


def run_elsewhere(checkout: Path, folder: Path, workers: int, folds: int | None, reports: Path | None) -> dict:
    """Wall and CPU time [s] of ``folder`` diagnosed by the code of ``checkout`` (a checkout of this repository),
    in a process of its own: this script there, on that one case."""
    # This script's path there; a checkout from before the benchmarks were grouped in folders has it at the former one.
    paths = ("benchmarks/speed/diagnosis.py", "benchmarks/diagnosis_speed.py")
    script = next((path for path in paths if (checkout / path).is_file()), paths[0])
    command = [sys.executable, script, "--suite", "one", str(folder.resolve())]
    command += ["--workers", str(workers)] + (["--folds", str(folds)] if folds else [])
    command += ["--reports", str(reports.resolve())] if reports is not None else []
    environment = {**os.environ, "PYTHONPATH": str(checkout.resolve())}
    done = subprocess.run(command, cwd=checkout, env=environment, capture_output=True, text=True)
    timed = re.search(rf"^{re.escape(folder.name)}: ([\d.]+) s wall, ([\d.]+) s CPU$", done.stderr, re.MULTILINE)
    if done.returncode != 0 or timed is None:
        raise RuntimeError(f"{checkout}: {folder.name} was not timed:\n{done.stderr[-2000:]}")
    return {"case": folder.name, "wall": float(timed[1]), "cpu": float(timed[2])}


def print_pairs(suite: str, reference: Path, pairs: list[tuple[dict, dict]]) -> None:
    """The interleaved runs' table: per case the reference code's and this code's times, and their CPU ratio."""
    print(f"\n## {suite}: {len(pairs)} cases, interleaved with the code of {reference}\n")
    print("| case | reference: wall / CPU [s] | this code: wall / CPU [s] | CPU ratio |\n|---|---:|---:|---:|")
    for before, after in pairs:
        print(
            f"| {before['case']} | {before['wall']:.1f} / {before['cpu']:.1f} | {after['wall']:.1f} / "
            f"{after['cpu']:.1f} | {after['cpu'] / before['cpu']:.2f} |"
        )
    for key, label in (("wall", "wall"), ("cpu", "CPU")):
        before, after = ([pair[i][key] for pair in pairs] for i in (0, 1))
        print(
            f"\n{label}: median {statistics.median(before):.1f} -> {statistics.median(after):.1f} s, "
            f"worst {max(before):.1f} -> {max(after):.1f} s",
            end="",
        )
    ratios = [after["cpu"] / before["cpu"] for before, after in pairs]
    print(f"\nCPU ratio: median {statistics.median(ratios):.2f}, from {min(ratios):.2f} to {max(ratios):.2f}")


def _fingerprint(report: dict) -> dict:
    """What must not change: the verdict, the effects, and every model's parameters as report.md prints them."""
    ranking = {row["effect"]: row.get("params") for row in report.get("ranking", [])}
    return {"verdict": report.get("verdict"), "effects": report.get("effects"), "ranking": ranking}


def compare(reports: Path, before: Path, cases: list[str]) -> None:
    print("\n| case | verdict, effects, ranking and report.md identical to the reference |\n|---|---|")
    for case in cases:
        new, old = reports / case, before / case
        same_md = (new / "report.md").read_text() == (old / "report.md").read_text()
        same = _fingerprint(json.loads((new / "report.json").read_text())) == _fingerprint(
            json.loads((old / "report.json").read_text())
        )
        print(f"| {case} | {'yes' if same and same_md else 'NO'} (report.json {same}, report.md {same_md}) |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--suite", nargs="+", action="append", help="a suite's name followed by its case folders")
    parser.add_argument(
        "--write-trials", nargs=2, metavar=("DIR", "N"), help="write a set of N 4 s trials at 125 Hz to DIR and stop"
    )
    parser.add_argument("--workers", type=int, default=2, help="diagnose's worker processes (default 2)")
    parser.add_argument("--folds", type=int, help="also check consistency on this many folds")
    parser.add_argument("--profile", action="store_true", help="cProfile each case in this process (one worker)")
    parser.add_argument("--reports", type=Path, help="write every case's report here")
    parser.add_argument("--compare", type=Path, help="compare the reports with those written earlier here")
    parser.add_argument("--reference", type=Path, help="interleave every case with the code of this checkout")
    args = parser.parse_args(argv)
    if args.reference is not None and args.profile:
        parser.error("--profile runs the cases in this process; --reference runs them in processes of their own")
    if args.write_trials:
        write_trials(Path(args.write_trials[0]), int(args.write_trials[1]), args.workers)
        return 0
    here = Path(benchmarks.__file__).resolve().parent.parent  # the repository holding this script
    for suite, *folders in args.suite or []:
        if args.reference is not None:
            pairs = [
                (
                    run_elsewhere(args.reference, folder, args.workers, args.folds, None),
                    run_elsewhere(here, folder, args.workers, args.folds, args.reports),
                )
                for folder in map(Path, folders)
            ]
            print_pairs(suite, args.reference, pairs)
            if args.compare and args.reports:
                compare(args.reports, args.compare, [Path(folder).name for folder in folders])
            continue
        rows = []
        for folder in map(Path, folders):
            profiler = cProfile.Profile() if args.profile else None
            if profiler:
                profiler.enable()
            rows.append(run_case(folder, 1 if profiler else args.workers, args.folds, args.reports))
            if profiler:
                profiler.disable()
                print(f"\n### profile of {folder.name}")
                pstats.Stats(profiler).sort_stats("cumulative").print_stats(35)
            print(f"{folder.name}: {rows[-1]['wall']:.1f} s wall, {rows[-1]['cpu']:.1f} s CPU", file=sys.stderr)
        print_table(suite, rows)
        if args.compare and args.reports:
            compare(args.reports, args.compare, [Path(folder).name for folder in folders])
    return 0


if __name__ == "__main__":
    sys.exit(main())
