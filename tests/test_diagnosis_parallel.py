"""The diagnosis' task runner contains every task: an exception or a dead worker process is that task's Failure,
the other tasks' results come back in order, whatever the number of workers."""

import os

import pytest
import scipy.linalg  # noqa: F401 - its BLAS loaded before the runner's first limit, as in a diagnosis
from threadpoolctl import threadpool_info

from furuta_drake.parallel import Failure, run_tasks

pytestmark = pytest.mark.slow  # end-to-end runs: `pytest -m "not slow"` leaves them out


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


def _blas_threads(_=None) -> list[int]:
    return [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]


@pytest.mark.parametrize("workers", [1, 2])
def test_every_task_runs_its_blas_on_one_thread_and_the_caller_keeps_its_own(workers):
    """The parallelism is across tasks: a task's BLAS threads would only spin on the cores the other tasks use.
    The caller's own BLAS threads are as they were after the tasks."""
    before = _blas_threads()
    results = run_tasks(_blas_threads, [0, 1], workers=workers)
    assert all(threads and set(threads) == {1} for threads in results)
    assert _blas_threads() == before


def test_a_task_whose_worker_dies_fails_alone():
    done = []
    results = run_tasks(_task, [1, 2, "die", 4, 5], workers=2, done=done.append)
    assert results[:2] == [2, 4] and results[3:] == [8, 10]
    assert isinstance(results[2], Failure) and "worker process died" in results[2].reason
    assert sorted(map(str, done)) == sorted(map(str, results))  # every task reported once


def test_a_dask_cluster_gives_the_same_diagnosis_as_one_process(tmp_path):
    """diagnose --scheduler: the fits and replays run on an existing Dask cluster's workers, and the report is
    the one a single process writes (every task is a pure function of its inputs)."""
    import json

    from distributed import LocalCluster

    from benchmarks.diagnosis.suite import run_configs, with_effect
    from furuta_drake.diagnosis.pipeline import diagnose
    from furuta_drake.diagnosis.report.files import report_json
    from furuta_drake.diagnosis.settings import FAST
    from furuta_drake.results import write_log_csv
    from furuta_drake.rig import qube_servo2_rig
    from furuta_drake.simulate import simulate
    from furuta_drake.yamlio import dump_yaml_dataclass

    rig = qube_servo2_rig()
    (tmp_path / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    logs = []
    for seed in (3, 4):
        logs.append(tmp_path / f"run_{seed}.csv")
        write_log_csv(simulate(with_effect(run_configs(rig, seed, 2.0)["hanging"], "input_delay", 2)), logs[-1])
    kwargs = dict(rig=tmp_path / "rig.yaml", train=logs[:1], heldout=logs[1:], settings=FAST)
    alone = json.loads(report_json(diagnose(**kwargs, workers=1).to_json()))
    with LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=":0") as cluster:
        on_dask = json.loads(report_json(diagnose(**kwargs, scheduler=cluster.scheduler_address).to_json()))
    assert on_dask == alone
    assert alone["verdict"] == "input_delay"
