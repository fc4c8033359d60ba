"""The diagnosis' task runner contains every task: an exception or a dead worker process is that task's Failure,
the other tasks' results come back in order, whatever the number of workers."""

import os

import pytest

from furuta_drake.diagnosis.parallel import Failure, run_tasks


def _task(x):
    if x == "raise":
        raise FloatingPointError("prediction diverged\nsecond line")
    if x == "die":
        os._exit(3)  # a worker killed mid-task (OOM killer, a crash in native code)
    return x * 2


@pytest.mark.parametrize("workers", [1, 2])
def test_a_raising_task_is_a_one_line_failure_and_the_others_finish(workers):
    results = run_tasks(_task, [1, "raise", 3], workers=workers)
    assert results[0] == 2 and results[2] == 6
    assert results[1] == Failure("FloatingPointError: prediction diverged")


def test_a_task_whose_worker_dies_fails_alone():
    done = []
    results = run_tasks(_task, [1, 2, "die", 4, 5], workers=2, done=done.append)
    assert results[:2] == [2, 4] and results[3:] == [8, 10]
    assert isinstance(results[2], Failure) and "worker process died" in results[2].reason
    assert sorted(map(str, done)) == sorted(map(str, results))  # every task reported once
