"""Blind validation of ``furuta-drake diagnose``: confusion matrix, accuracy, false alarms on ``none``, median
held-out gap reduction where right, the coverage of the 95 % parameter intervals, seconds per case.

The suite (:mod:`benchmarks.diagnosis.suite`): each vocabulary effect at two magnitudes on both rigs and the
seeds asked for, plus ``none`` cases, an effect outside the vocabulary (cogging torque, expected
``unexplained``) and cases with two and three effects acting together (all must be named). Its logs are simulated
into ``OUT/suite/cases/<case>/`` and the answers go to ``OUT/suite/answers.json``; the diagnosis is then run on each
case folder alone (rig.yaml, train_*.csv, heldout_*.csv), blind, and scored against the answers afterwards. Both
run on a Dask cluster, one case per task (:mod:`benchmarks.diagnosis.shards`; each case diagnosed with one worker
process): ``--scheduler ADDRESS`` for an existing cluster (its workers must import this repository and see ``OUT``),
else a local cluster of ``--workers`` single-threaded processes (default one per core). A line per case is printed as it
finishes; a case that raises is a wrong row naming the error.

Writes, as the cases finish, ``OUT/results.csv`` (one row per case), ``OUT/results.json`` (the figures and every
row) and ``OUT/verdicts.json`` (the verdict table every suite writes, to compare two runs:
``python benchmarks/diagnosis/shards.py OLD/verdicts.json NEW/verdicts.json``); and ``OUT/config.json`` (the options,
cases and versions). Targets: >= 90 % right, no false alarm on ``none``, median held-out reduction >= 50 % where right,
every effect named in >= 80 % of the cases with several, 85-99 % of the true parameters of right verdicts inside
their 95 % intervals, <= 60 s of the run's wall time per case of four 8 s logs at 1 kHz on 2 cores
(``run_seconds_per_case``; ``seconds_per_case`` is a case's own time on its one core). The run ends with the sum
of the case times over the wall time: its speed-up over one worker, which grows with the workers until each has
one case left (:mod:`benchmarks.diagnosis.shards`).

Run from the repository root: ``PYTHONPATH=. python benchmarks/diagnosis/confusion.py --out runs/confusion``
(``--quick``: a handful of cases with 8 s logs; ``--only WORD ...``: the cases whose name holds a word;
``--suite DIR`` reuses logs written earlier).
"""

from __future__ import annotations

import argparse
import csv
import json
import platform
import resource
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.diagnosis.shards import (
    Outcome,
    shard,
    speed_up_line,
    suite_parser,
    verdict_row,
    worker_count,
    write_verdicts,
)
from benchmarks.diagnosis.suite import CaseSpec, default_cases, verdict_is_right, write_case
from furuta_drake.diagnosis.pipeline import diagnose
from furuta_drake.diagnosis.report.files import write_report
from furuta_drake.rig import RIGS
from furuta_drake.sweep import dask_client, map_on_dask

QUICK = (
    CaseSpec("lund", (), 0, 1),
    CaseSpec("lund", ("input_delay",), 2, 1),
    CaseSpec("lund", ("arm_coulomb_friction",), 2, 1),
    CaseSpec("qube_servo2", ("actuator_lag",), 2, 1),
    CaseSpec("qube_servo2", ("arm_viscous_friction",), 2, 1),
    CaseSpec("lund", ("cogging_torque",), 2, 1),
)
TARGETS = {
    "accuracy": 0.9,
    "false_alarm_rate": 0.0,
    "median_reduction_where_right": 0.5,
    "several_effects_named": 0.8,
    "interval_coverage": (0.85, 0.99),
    "run_seconds_per_case": 60.0,
}


def _write_case(args):
    case, directory, duration = args
    return write_case(case, Path(directory), duration)


def generate(cases: list[CaseSpec], suite: Path, duration: float, client) -> list[dict]:
    """Simulate every case's logs on ``client``'s cluster; write and return the answers (kept apart from the case
    folders)."""
    tasks = [(case, str(suite / "cases" / case.name), duration) for case in cases]
    answers = map_on_dask(
        client,
        _write_case,
        tasks,
        progress=lambda done, total: print(f"\r  simulated {done}/{total} cases", end=""),
    )
    print()
    (suite / "answers.json").write_text(json.dumps(answers, indent=2, sort_keys=True) + "\n")
    return answers


def _cpu_seconds() -> float:
    own, children = resource.getrusage(resource.RUSAGE_SELF), resource.getrusage(resource.RUSAGE_CHILDREN)
    return own.ru_utime + own.ru_stime + children.ru_utime + children.ru_stime


def diagnose_blind(case_dir: Path, out: Path) -> tuple[dict, float, float]:
    """Run the diagnosis on one case folder (no answer in sight) with one worker process; return its report, wall
    time and CPU time (on a shared machine, the CPU time estimates the wall time the case would take with a
    core to itself)."""
    start, cpu = time.perf_counter(), _cpu_seconds()
    diagnosis = diagnose(
        rig=case_dir / "rig.yaml",
        train=sorted(case_dir.glob("train_*.csv")),
        heldout=sorted(case_dir.glob("heldout_*.csv")),
        workers=1,
    )
    seconds, cpu = time.perf_counter() - start, _cpu_seconds() - cpu
    write_report(out, diagnosis, force=True)
    return json.loads((out / "report.json").read_text()), seconds, cpu


def coverage(answer: dict, report: dict) -> tuple[int, int]:
    """(true parameters inside their 95 % interval, true parameters with an interval) of the accepted model,
    for a verdict that names every hidden effect."""
    names = [step["effect"] for step in report.get("steps", [])]
    entry = next((row for row in report["ranking"] if row["effect"].split("+") == names), None)
    if entry is None or not verdict_is_right(answer, report):
        return 0, 0
    inside = total = 0
    for effect, truth in answer["truth"].items():
        for param, value in truth.items():
            key = f"{effect}.{param}" if len(names) > 1 else param
            if effect not in names or key not in entry.get("params_ci", {}):
                continue
            low, high = entry["params_ci"][key]
            inside += low <= value <= high
            total += 1
    return inside, total


def confusion(rows: list[dict]) -> tuple[list[str], list[str], np.ndarray]:
    expected = sorted({row["expected"] for row in rows})
    found = sorted({row["found"] for row in rows} | set(expected))
    matrix = np.zeros((len(expected), len(found)), dtype=int)
    for row in rows:
        matrix[expected.index(row["expected"]), found.index(row["found"])] += 1
    return expected, found, matrix


def print_confusion(expected: list[str], found: list[str], matrix: np.ndarray) -> None:
    short = {name: f"{i:>2}" for i, name in enumerate(found)}
    width = max(len(name) for name in expected)
    print("\nconfusion matrix (rows: expected, columns: found)")
    for name in found:
        print(f"  [{short[name]}] {name}")
    print(" " * (width + 2) + " ".join(short[name] for name in found))
    for i, name in enumerate(expected):
        cells = " ".join(f"{v:>2}" if v else " ." for v in matrix[i])
        print(f"  {name:<{width}}{cells}")


def summarise(rows: list[dict]) -> dict:
    right = [row for row in rows if row["right"]]
    none_rows = [row for row in rows if row["expected"] == "none"]
    reductions = [row["heldout_reduction"] for row in right if row["expected"] != "none"]
    several = [row for row in rows if row["several"]]
    intervals = sum(row["params_with_interval"] for row in rows)
    seconds = [row["seconds"] for row in rows if row["seconds"] is not None]  # None: the case's worker was lost
    cpu = [row["cpu_seconds"] for row in rows if row["cpu_seconds"] is not None]
    return {
        "several_effects_named": (sum(row["right"] for row in several) / len(several)) if several else float("nan"),
        "interval_coverage": sum(row["params_inside"] for row in rows) / intervals if intervals else float("nan"),
        "parameters_with_interval": intervals,
        "cases": len(rows),
        "right": len(right),
        "accuracy": len(right) / len(rows) if rows else float("nan"),
        "false_alarm_rate": (
            sum(row["found"] != "none" for row in none_rows) / len(none_rows) if none_rows else float("nan")
        ),
        "median_reduction_where_right": float(np.median(reductions)) if reductions else float("nan"),
        "seconds_per_case": float(np.mean(seconds)) if seconds else float("nan"),
        "max_seconds": float(np.max(seconds)) if seconds else float("nan"),
        "cpu_seconds_per_case": float(np.mean(cpu)) if cpu else float("nan"),
    }


def select_cases(args) -> list[CaseSpec]:
    if args.quick:
        return list(QUICK)
    cases = default_cases(rigs=tuple(args.rigs), seeds=tuple(args.seeds), levels=tuple(args.levels))
    if args.only:
        cases = [case for case in cases if any(word in case.name for word in args.only)]
    return cases


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command line's options."""
    parser = suite_parser(__doc__.splitlines()[0], f"{len(QUICK)} cases only")
    parser.add_argument("--rigs", nargs="+", default=["lund", "qube_servo2"], choices=list(RIGS))
    parser.add_argument("--seeds", nargs="+", type=int, default=[1])
    parser.add_argument("--levels", nargs="+", type=int, default=[1, 2])
    return parser.parse_args(argv)


def reused_answers(suite: Path, cases: list[CaseSpec]) -> list[dict]:
    """The answers of a suite written earlier, restricted to ``cases`` (all of them if none is there)."""
    answers = json.loads((suite / "answers.json").read_text())
    names = {case.name for case in cases}
    return [a for a in answers if a["case"] in names] or answers


def fitted_params(report: dict) -> dict:
    """The parameters of the accepted model (the ranking entry whose effects are the report's steps)."""
    accepted = (r for r in report["ranking"] if r["effect"].split("+") == [step["effect"] for step in report["steps"]])
    return next((r["params"] for r in accepted), {})


def score_case(answer: dict, report: dict, seconds: float, cpu: float) -> dict:
    """One row of the results: the case, what was expected and found, the interval coverage, the held-out gap
    and the times."""
    found = "+".join(sorted(report["effects"])) if "+" in answer["expected_verdict"] else report["verdict"]
    inside, with_interval = coverage(answer, report)
    return {
        "case": answer["case"],
        "rig": answer["rig"],
        "expected": answer["expected_verdict"],
        "found": found,
        "right": verdict_is_right(answer, report),
        "several": "+" in answer["expected_verdict"],
        "params_inside": inside,
        "params_with_interval": with_interval,
        "confusable": json.dumps(report.get("confusable", [])),
        "heldout_reduction": report["gap"]["heldout_reduction"],
        "nominal_heldout_gap": report["gap"]["nominal"]["heldout"],
        "runner_up": report["ranking"][0]["effect"] if report["ranking"] else "",
        "fitted": json.dumps(fitted_params(report), sort_keys=True),
        "seconds": seconds,
        "cpu_seconds": cpu,
    }


def error_row(answer: dict, error: str, seconds: float | None) -> dict:
    """The row of a case whose diagnosis raised: wrong, with the error as what was found."""
    return {
        "case": answer["case"],
        "rig": answer["rig"],
        "expected": answer["expected_verdict"],
        "found": f"ERROR {error}"[:200],
        "right": False,
        "several": "+" in answer["expected_verdict"],
        "params_inside": 0,
        "params_with_interval": 0,
        "confusable": "[]",
        "heldout_reduction": None,
        "nominal_heldout_gap": None,
        "runner_up": "",
        "fitted": "{}",
        "seconds": seconds,
        "cpu_seconds": None,
    }


def _diagnose_case(task: tuple[dict, Path, Path]) -> tuple[dict, list[str]]:
    """A task: diagnose one case blind; its scored row and the report's effects."""
    answer, suite, out = task
    report, seconds, cpu = diagnose_blind(suite / "cases" / answer["case"], out / "reports" / answer["case"])
    return score_case(answer, report, seconds, cpu), report["effects"]


def verdicts(rows: list[dict], effects: list[list[str]]) -> list[dict]:
    """The rows and their reports' effects as the verdict table every suite writes
    (:mod:`benchmarks.diagnosis.shards`)."""
    return [
        verdict_row(
            "confusion",
            row["case"],
            row["expected"],
            row["found"],
            found,
            row["right"],
            row["heldout_reduction"],
            row["seconds"],
        )
        for row, found in zip(rows, effects)
    ]


def diagnose_all(answers: list[dict], suite: Path, out: Path, client) -> tuple[list[dict], list[list[str]]]:
    """Diagnose every case folder blind on ``client``'s cluster, one case per task; print a line per case as it
    finishes and write the results so far; return one scored row per case and its report's effects, in the
    answers' order."""
    rows: list[dict | None] = [None] * len(answers)
    effects: list[list[str]] = [[] for _ in answers]

    def finished(done: int, total: int, index: int, outcome: Outcome) -> None:
        if outcome.error is None:
            rows[index], effects[index] = outcome.value
        else:
            rows[index] = error_row(answers[index], outcome.error, outcome.seconds)
        row = rows[index]
        mark = "ok " if row["right"] else "BAD"
        reduction = "-" if row["heldout_reduction"] is None else f"{row['heldout_reduction']:6.1%}"
        cpu = "-" if row["cpu_seconds"] is None else f"{row['cpu_seconds']:5.1f}"
        seconds = "-" if row["seconds"] is None else f"{row['seconds']:5.1f}"
        print(
            f"[{done}/{total}] {mark} {row['case']:<55} -> {row['found']:<24} "
            f"reduction {reduction}  {seconds} s (CPU {cpu} s)",
            flush=True,
        )
        done_rows = [(r, e) for r, e in zip(rows, effects) if r is not None]
        write_all(out, [r for r, _ in done_rows], [e for _, e in done_rows])

    start = time.perf_counter()
    outcomes = shard(client, _diagnose_case, [(answer, suite, out) for answer in answers], finished)
    print(speed_up_line(outcomes, time.perf_counter() - start, worker_count(client)))
    return rows, effects


def print_figures(figures: dict) -> None:
    """The summary figures on one line, then the targets."""
    print(
        f"\naccuracy {figures['accuracy']:.1%} ({figures['right']}/{figures['cases']}), "
        f"false alarms on none {figures['false_alarm_rate']:.0%}, "
        f"median held-out reduction where right {figures['median_reduction_where_right']:.1%}, "
        f"all effects named in {figures['several_effects_named']:.0%} of the cases with several, "
        f"interval coverage {figures['interval_coverage']:.1%} of {figures['parameters_with_interval']} true "
        f"parameters, "
        f"{figures['run_seconds_per_case']:.1f} s of the run per case; a case {figures['seconds_per_case']:.1f} s "
        f"on its core (max {figures['max_seconds']:.1f} s; {figures['cpu_seconds_per_case']:.1f} CPU s)"
    )
    print("targets: " + ", ".join(f"{k} {v}" for k, v in TARGETS.items()))


def write_results(out: Path, rows: list[dict], figures: dict, confusion_matrix: tuple) -> None:
    """``results.csv`` (one row per case) and ``results.json`` (figures, targets, confusion matrix, rows)."""
    expected, found, matrix = confusion_matrix
    with open(out / "results.csv", "w", newline="") as handle:
        writer = csv.DictWriter(handle, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    (out / "results.json").write_text(
        json.dumps(
            {
                "figures": figures,
                "targets": TARGETS,
                "confusion": {"expected": expected, "found": found, "matrix": matrix.tolist()},
                "rows": rows,
            },
            indent=2,
        )
        + "\n"
    )


def write_all(out: Path, rows: list[dict], effects: list[list[str]]) -> None:
    """``results.csv``, ``results.json`` and ``verdicts.json`` of the rows (and their reports' effects) so far."""
    write_results(out, rows, summarise(rows), confusion(rows))
    write_verdicts(out / "verdicts.json", verdicts(rows, effects))


def write_config(out: Path, argv: list[str] | None, args: argparse.Namespace, suite: Path, answers: list[dict]) -> None:
    """``config.json``: the options, the suite, the cases and the versions."""
    (out / "config.json").write_text(
        json.dumps(
            {
                "argv": sys.argv[1:] if argv is None else argv,
                "suite": str(suite),
                "duration_s": args.duration,
                "cases": [a["case"] for a in answers],
                "workers": args.workers,
                "python": platform.python_version(),
                "numpy": np.__version__,
                "pydrake": _drake_version(),
            },
            indent=2,
        )
        + "\n"
    )


def main(argv: list[str] | None = None) -> int:
    """Simulate (or reuse) the suite, diagnose every case blind, print and write the scores."""
    args = parse_args(argv)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    cases = select_cases(args)
    with dask_client(args.scheduler, args.workers, len(cases)) as client:
        if args.suite is not None:
            suite = args.suite
            answers = reused_answers(suite, cases)
        else:
            suite = out / "suite"
            print(f"simulating {len(cases)} cases ({args.duration:g} s logs) into {suite}")
            start = time.perf_counter()
            answers = generate(cases, suite, args.duration, client)
            print(f"  {time.perf_counter() - start:.0f} s")
            if args.generate_only:
                return 0
        write_config(out, argv, args, suite, answers)
        start = time.perf_counter()
        rows, effects = diagnose_all(answers, suite, out, client)
        wall = time.perf_counter() - start
    expected, found, matrix = confusion(rows)
    print_confusion(expected, found, matrix)
    figures = {**summarise(rows), "run_seconds_per_case": wall / len(rows) if rows else float("nan")}
    print_figures(figures)
    write_results(out, rows, figures, (expected, found, matrix))
    write_verdicts(out / "verdicts.json", verdicts(rows, effects))
    return 0


def _drake_version() -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("drake")
    except PackageNotFoundError:
        return "unknown"


if __name__ == "__main__":
    sys.exit(main())
