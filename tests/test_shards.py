"""The validation suites' sharding over Dask (benchmarks/diagnosis/shards.py) on a fake case function: an outcome for
every case in the cases' order, a raising case is an outcome with its error, progress in the order cases finish; and the
comparison of two verdict tables."""

from __future__ import annotations

import logging
import time

from dask.distributed import Client, LocalCluster

from benchmarks.diagnosis.shards import Outcome, compare, shard, speed_up_line, verdict_row


def fake_case(case: tuple[str, float, bool]) -> dict:
    """Sleep, then return the case's row or raise."""
    name, seconds, fails = case
    time.sleep(seconds)
    if fails:
        raise ValueError(f"{name} broke\nat some line")
    return {"case": name}


def test_every_case_has_its_outcome_in_order_and_progress_follows_completion():
    cases = [("slow", 1.0, False), ("broken", 0.0, True), ("quick", 0.1, False), ("quicker", 0.05, False)]
    calls = []
    with (
        LocalCluster(n_workers=2, threads_per_worker=1, processes=False, silence_logs=logging.CRITICAL) as cluster,
        Client(cluster) as client,
    ):
        outcomes = shard(client, fake_case, cases, lambda *call: calls.append(call))
    assert [o.value for o in outcomes] == [{"case": "slow"}, None, {"case": "quick"}, {"case": "quicker"}]
    assert [o.error for o in outcomes] == [None, "ValueError: broken broke", None, None]
    assert all(o.seconds >= seconds for o, (_, seconds, _) in zip(outcomes, cases))
    assert [done for done, *_ in calls] == [1, 2, 3, 4] and {total for _, total, *_ in calls} == {4}
    assert sorted(index for _, _, index, _ in calls) == [0, 1, 2, 3]
    assert calls[-1][2] == 0  # the slow case, first in order, finished last (the other worker took the rest)
    assert all(outcome is outcomes[index] for _, _, index, outcome in calls)
    finished = [Outcome(None, None, 3.0), Outcome(None, None, 1.6), Outcome(None, "KilledWorker: lost", None)]
    assert speed_up_line(finished, 2.0, 2).endswith("add up to 5 s: 2.30x one worker")


def test_two_verdict_tables_compare_case_by_case():
    def row(case, verdict, right):
        return verdict_row("suite", case, "arm_spring", verdict, [verdict] if right else [], right, 0.5, 10.0)

    old = [row("a", "arm_spring", True), row("b", "none", False), row("c", "arm_spring", True)]
    new = [row("a", "arm_spring", True), row("b", "arm_spring", True), row("c", "none", False), row("d", "none", False)]
    lines = compare(old, new)
    assert lines[0].startswith("fixed b: none") and lines[1].startswith("broken c: arm_spring")
    assert lines[2] == "+ d: none (new case)"
    assert lines[-1] == "1 cases the same; right 2/3 -> 2/4"
