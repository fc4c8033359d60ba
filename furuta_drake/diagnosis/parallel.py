"""The diagnosis' task runner: candidates' fits and Drake replays on all cores, in worker processes or on an
existing Dask cluster, with every task contained.

A candidate fitted to arbitrary real data can be one whose parameters make a prediction blow up, and a worker
process can die; both are ordinary outcomes of a diagnosis, not its end. A task that raises comes back as a
:class:`Failure` with a one-line reason; a task whose worker process died is run again alone in a fresh
process, and becomes a :class:`Failure` if that one dies too. Tasks are pure functions of their inputs, so the
results do not depend on the number of workers or on where a task ran. An interrupt (Ctrl-C) is not contained:
it ends the run.
"""

from __future__ import annotations

import os
import signal
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Failure:
    """A task that produced no result: ``reason`` says why, in one line."""

    reason: str


def one_line(err: BaseException) -> str:
    """``err`` as one line: its type and the first line of its message."""
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0]}" if text else type(err).__name__


def _contained(task):
    function, argument = task
    with np.errstate(all="ignore"):  # a diverging candidate is reported as failed, not as warnings
        try:
            return function(argument)
        except Exception as err:  # noqa: BLE001 - any error of one task is that task's outcome
            return Failure(one_line(err))


def run_tasks(
    function: Callable,
    tasks: list,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    done: Callable | None = None,
) -> list:
    """``[function(task) for task in tasks]``, each result or a :class:`Failure`, in task order.

    ``workers``: processes on this machine (default: all cores; 1: in this process); ``scheduler``: the address
    of an existing Dask scheduler whose workers run the tasks instead. ``done(result)`` after each task."""
    calls = [(function, task) for task in tasks]
    if scheduler is not None:
        results = _on_dask(calls, scheduler)
    elif min(workers or os.cpu_count() or 1, len(tasks)) > 1:
        return _in_processes(calls, min(workers or os.cpu_count() or 1, len(tasks)), done)
    else:
        results = [_contained(call) for call in calls]
    for result in results:
        if done is not None:
            done(result)
    return results


def _exit_on_interrupt() -> None:
    """A worker's Ctrl-C: end at once and silently (the main process reports the interrupt)."""
    signal.signal(signal.SIGINT, lambda signum, frame: os._exit(130))


def _in_processes(calls: list, workers: int, done: Callable | None) -> list:
    results: list = [None] * len(calls)
    finished = [False] * len(calls)
    with ProcessPoolExecutor(max_workers=workers, initializer=_exit_on_interrupt) as pool:
        futures = [pool.submit(_contained, call) for call in calls]
        for i, future in enumerate(futures):
            try:
                results[i] = future.result()
            except BrokenProcessPool:
                break
            finished[i] = True
            if done is not None:
                done(results[i])
    for i in (i for i, ok in enumerate(finished) if not ok):  # the pool broke: each task again, alone
        with ProcessPoolExecutor(max_workers=1, initializer=_exit_on_interrupt) as pool:
            try:
                results[i] = pool.submit(_contained, calls[i]).result()
            except BrokenProcessPool:
                results[i] = Failure("its worker process died (killed, or crashed in native code)")
        if done is not None:
            done(results[i])
    return results


def _on_dask(calls: list, scheduler: str) -> list:
    from distributed import as_completed
    from distributed.scheduler import KilledWorker

    from furuta_drake.sweep import dask_client

    with dask_client(scheduler) as client:
        futures = client.map(_contained, calls, pure=False)
        position = {future.key: i for i, future in enumerate(futures)}
        results: list = [None] * len(calls)
        try:
            for future in as_completed(futures):
                try:
                    results[position[future.key]] = future.result()
                except KilledWorker:
                    results[position[future.key]] = Failure("its Dask worker died (killed, or crashed)")
        finally:
            client.cancel(futures)
    return results
