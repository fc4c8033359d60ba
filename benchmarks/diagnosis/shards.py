"""The validation suites' cases on a Dask cluster, and the verdict table every suite writes.

A suite's cases are independent: each is a task (:func:`shard`), diagnosed on one worker with ``workers=1``,
so a cluster of N single-threaded workers runs N cases at once. The suite prints a line per case as it finishes
(``[done/total]``, in the order they finish) and writes its results as they come; a case that raises is that
case's row (``Outcome.error``), never the run's end. Every suite also writes ``verdicts.json``, one row per case
in the same fields (:data:`VERDICT_FIELDS`), so that two runs compare case by case:
``python benchmarks/diagnosis/shards.py OLD/verdicts.json NEW/verdicts.json``.

Speed-up: the run takes about the larger of (cases / workers) x the mean case time and the longest case, plus
the cluster's start (each worker's first case also pays the imports and numba's compilation). So it scales with
the workers while every worker has cases left, up to cases / workers = 1, where the longest case sets the time;
a suite prints the sum of its case times over its wall time, the speed-up over one worker. On a machine shared
with other jobs the workers also share its cores: more workers than free cores lengthen every case.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

from dask.distributed import as_completed

VERDICT_FIELDS = ("suite", "case", "expected", "verdict", "effects", "right", "heldout_reduction", "seconds")


@dataclass(frozen=True)
class Outcome:
    """What a task gave: ``value`` (the function's return, None if it raised), ``error`` ('Type: message' of
    what it raised, else None) and ``seconds`` (its wall time on the worker; None if the worker was lost)."""

    value: object
    error: str | None
    seconds: float | None


def _timed(function: Callable, item) -> Outcome:
    """``function(item)`` on a worker, timed, its exception caught (the task itself never fails)."""
    start = time.perf_counter()
    try:
        return Outcome(function(item), None, time.perf_counter() - start)
    except Exception as error:  # the case's row says it; the other cases run on
        message = str(error).strip().splitlines()[0] if str(error).strip() else ""
        return Outcome(None, f"{type(error).__name__}: {message}", time.perf_counter() - start)


def shard(
    client,
    function: Callable,
    items: Sequence,
    progress: Callable[[int, int, int, Outcome], None] | None = None,
) -> list[Outcome]:
    """``function(item)`` for every item as a task on ``client``'s cluster; the outcomes in the order of
    ``items``. A task is handed out when a worker thread is free, in the items' order, so no case waits behind a
    long one while a worker idles. ``progress(done, total, index, outcome)`` is called as each finishes (``index``
    into ``items``). A task whose worker is lost is an outcome with its error."""
    queue = iter(enumerate(items))
    running, position = as_completed(), {}

    def hand_out() -> None:
        index, item = next(queue, (None, None))
        if index is not None:
            future = client.submit(_timed, function, item, pure=False)
            position[future.key] = index
            running.add(future)

    for _ in range(max(1, threads(client))):
        hand_out()
    outcomes: list[Outcome | None] = [None] * len(items)
    try:
        for done, future in enumerate(running, start=1):
            index = position[future.key]
            try:
                outcomes[index] = future.result()
            except Exception as error:  # the worker died under the task (KilledWorker) or it was cancelled
                outcomes[index] = Outcome(None, f"{type(error).__name__}: {error}", None)
            hand_out()
            if progress is not None:
                progress(done, len(items), index, outcomes[index])
    finally:
        client.cancel(list(running.futures))
    return outcomes


def suite_parser(description: str, quick: str) -> argparse.ArgumentParser:
    """The options every blind suite takes: ``--out``, ``--quick`` (``quick`` says which cases), ``--only``,
    ``--duration``, ``--suite``, ``--generate-only``, ``--workers``, ``--scheduler``; a suite adds its own."""
    parser = argparse.ArgumentParser(description=description)
    parser.add_argument("--out", type=Path, required=True, help="output directory (suite, reports, results)")
    parser.add_argument("--quick", action="store_true", help=quick)
    parser.add_argument("--only", nargs="+", help="keep the cases whose name contains one of these words")
    parser.add_argument("--duration", type=float, default=8.0, help="length of every log [s] (default 8)")
    parser.add_argument("--suite", type=Path, help="reuse a suite written earlier (its answers.json and cases/)")
    parser.add_argument("--generate-only", action="store_true", help="write the suite and stop")
    parser.add_argument("--workers", type=int, help="the local cluster's worker processes (default: one per core)")
    parser.add_argument("--scheduler", help="Dask scheduler address (default: a local cluster started here)")
    return parser


def verdict_row(
    suite: str, case: str, expected: str, verdict: str, effects, right: bool, heldout_reduction, seconds
) -> dict:
    """A row of ``verdicts.json`` (:data:`VERDICT_FIELDS`)."""
    values = (suite, case, expected, verdict, sorted(effects), bool(right), heldout_reduction, seconds)
    return dict(zip(VERDICT_FIELDS, values))


def verdict_rows(suite: str, rows: list[dict]) -> list[dict]:
    """The :func:`verdict_row` of each of a suite's result rows (their keys ``case``, ``expected``, ``verdict``,
    ``effects``, ``right``, ``heldout_reduction``, ``seconds``)."""
    keys = ("case", "expected", "verdict", "effects", "right", "heldout_reduction", "seconds")
    return [verdict_row(suite, *(row[key] for key in keys)) for row in rows]


def write_verdicts(path: Path, rows: list[dict]) -> None:
    """``verdicts.json``: the rows (:func:`verdict_row`) in case order."""
    path.write_text(json.dumps(rows, indent=2) + "\n")


def speed_up_line(outcomes: Sequence[Outcome | None], wall: float, workers: int) -> str:
    """The run's wall time beside the sum of its case times: the speed-up over one worker."""
    busy = sum(o.seconds for o in outcomes if o is not None and o.seconds is not None)
    return (
        f"{len(outcomes)} cases in {wall:.0f} s on {workers} workers; the cases' own times add up to {busy:.0f} s: "
        f"{busy / wall if wall > 0 else float('nan'):.2f}x one worker"
    )


def compare(old: list[dict], new: list[dict]) -> list[str]:
    """Lines for the cases whose verdict, effects or rightness differ between two verdict tables, then a count."""
    before = {row["case"]: row for row in old}
    lines, same = [], 0
    for row in new:
        was = before.pop(row["case"], None)
        if was is None:
            lines.append(f"+ {row['case']}: {row['verdict']} (new case)")
        elif (was["verdict"], was["effects"], was["right"]) != (row["verdict"], row["effects"], row["right"]):
            mark = "fixed" if row["right"] and not was["right"] else "broken" if was["right"] else "changed"
            change = f"{was['verdict']} {was['effects']} -> {row['verdict']} {row['effects']}"
            lines.append(f"{mark} {row['case']}: {change}")
        else:
            same += 1
    lines += [f"- {case}: {row['verdict']} (gone)" for case, row in before.items()]
    right = (sum(r["right"] for r in old), len(old), sum(r["right"] for r in new), len(new))
    return lines + [f"{same} cases the same; right {right[0]}/{right[1]} -> {right[2]}/{right[3]}"]


def worker_count(client) -> int:
    """The cluster's workers."""
    return len(client.scheduler_info()["workers"])


def threads(client) -> int:
    """The cluster's worker threads: the cases that run at once."""
    return sum(worker["nthreads"] for worker in client.scheduler_info()["workers"].values())


def main(argv: list[str]) -> int:
    """Compare two verdict tables: ``shards.py OLD/verdicts.json NEW/verdicts.json``."""
    if len(argv) != 2:
        print("usage: python benchmarks/diagnosis/shards.py OLD/verdicts.json NEW/verdicts.json", file=sys.stderr)
        return 2
    old, new = (json.loads(Path(path).read_text()) for path in argv)
    print("\n".join(compare(old, new)))
    return 0


__all__ = [
    "Outcome",
    "VERDICT_FIELDS",
    "compare",
    "shard",
    "speed_up_line",
    "threads",
    "verdict_row",
    "worker_count",
    "write_verdicts",
]

if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
