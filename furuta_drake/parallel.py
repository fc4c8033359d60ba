"""The task runner of the diagnosis (candidates' fits, Drake replays), ``design`` and ``tune``: tasks on all
cores, in worker processes or on an existing Dask cluster, with every task contained.

A candidate fitted to arbitrary real data can be one whose parameters make a prediction blow up, and a worker
process can die; both are ordinary outcomes of a diagnosis, not its end. A task that raises comes back as a
:class:`Failure` with a one-line reason; a task whose worker process died is run again alone in a fresh
process, and becomes a :class:`Failure` if that one dies too. Tasks are pure functions of their inputs, so the
results do not depend on the number of workers or on where a task ran. An interrupt (Ctrl-C) is not contained:
it ends the run.

Every task, and the diagnosis' own process, runs its BLAS on one thread (:func:`one_blas_thread`): the parallelism
is across tasks.

A :class:`TaskPool` keeps the worker processes for a whole diagnosis, shared by the threads that run its
selections at once (the main one and each fold's of ``--folds``): a batch of a few fits leaves a core idle that
another selection's fits fill.
"""

from __future__ import annotations

import os
import signal
import threading
from collections.abc import Callable
from concurrent.futures import CancelledError, ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from dataclasses import dataclass

import numpy as np
from threadpoolctl import ThreadpoolController


@dataclass(frozen=True)
class Failure:
    """A task that produced no result: ``reason`` says why, in one line."""

    reason: str


def one_line(err: BaseException) -> str:
    """``err`` as one line: its type and the first line of its message."""
    text = str(err).strip().splitlines()
    return f"{type(err).__name__}: {text[0]}" if text else type(err).__name__


_pools: ThreadpoolController | None = None  # this process' native thread pools, found when first limited


def one_blas_thread():
    """A context in which this process' BLAS libraries run on one thread. A diagnosis' linear algebra is small (a
    fit's Jacobian of a few columns, stacks of 4 x 4 normal matrices): a BLAS thread beside the caller's finishes
    nothing sooner, and between calls it spins, on the core another task's process needs."""
    global _pools
    if _pools is None:  # after the task's function is unpickled: the libraries its modules load are loaded
        _pools = ThreadpoolController()
    return _pools.limit(limits=1, user_api="blas")


def _contained(task):
    function, argument = task
    with np.errstate(all="ignore"), one_blas_thread():  # a diverging candidate is reported as failed, not as warnings
        try:
            return function(argument)
        except Exception as err:  # noqa: BLE001 - any error of one task is that task's outcome
            return Failure(one_line(err))


class Interrupted(Exception):
    """A task handed to a :class:`TaskPool` closed by an interrupt (its diagnosis is ending)."""


class TaskPool:
    """Worker processes kept from one batch of tasks to the next; thread-safe. Its workers are started when it
    opens, before any selection thread runs (a process forked while another thread holds a lock may hang on
    it); a pool broken by a dying worker is replaced at the next batch (those workers start beside the running
    threads: a rare path, taken only after a worker died)."""

    def __init__(self, workers: int | None = None):
        self.workers = workers or os.cpu_count() or 1
        self._lock = threading.Lock()
        self._executor: ProcessPoolExecutor | None = None
        self._closed = False

    def __enter__(self) -> TaskPool:
        if self.workers > 1:
            self.executor()
        return self

    def __exit__(self, kind, error, trace) -> None:
        with self._lock:
            self._closed = True
            executor, self._executor = self._executor, None
        if executor is not None:  # an interrupt does not wait for running tasks; an error does, so that the
            # pool's own threads are done before the interpreter exits
            executor.shutdown(wait=kind is None or issubclass(kind, Exception), cancel_futures=True)

    def executor(self) -> ProcessPoolExecutor:
        with self._lock:
            if self._closed:
                raise Interrupted("the diagnosis' worker pool is closed")
            if self._executor is None:
                self._executor = ProcessPoolExecutor(max_workers=self.workers, initializer=_exit_on_interrupt)
                for _ in range(self.workers):  # each submission to a pool without an idle worker starts one
                    self._executor.submit(int)
            return self._executor

    def ensure_open(self) -> None:
        """Raise :class:`Interrupted` once the pool is closed."""
        with self._lock:
            if self._closed:
                raise Interrupted("the diagnosis' worker pool is closed")

    def discard(self, executor: ProcessPoolExecutor) -> None:
        """Replace ``executor`` (broken) at the next :meth:`executor`."""
        with self._lock:
            if self._executor is executor:
                self._executor = None
        executor.shutdown(wait=False, cancel_futures=True)


def run_tasks(
    function: Callable,
    tasks: list,
    *,
    workers: int | None = None,
    scheduler: str | None = None,
    done: Callable | None = None,
    pool: TaskPool | None = None,
) -> list:
    """``[function(task) for task in tasks]``, each result or a :class:`Failure`, in task order.

    ``workers``: processes on this machine (default: all cores; 1: in this process); ``scheduler``: the address
    of an existing Dask scheduler whose workers run the tasks instead; ``pool``: the worker processes to run
    them in (its size replaces ``workers``). ``done(result)`` after each task."""
    calls = [(function, task) for task in tasks]
    if scheduler is not None:
        results = _on_dask(calls, scheduler)
    elif pool is not None and pool.workers > 1:
        return _in_processes(calls, pool, done)
    elif min(workers or os.cpu_count() or 1, len(tasks)) > 1:
        with TaskPool(min(workers or os.cpu_count() or 1, len(tasks))) as own:
            return _in_processes(calls, own, done)
    else:
        results = [_contained(call) for call in calls]
    for result in results:
        if done is not None:
            done(result)
    return results


def _exit_on_interrupt() -> None:
    """A worker's Ctrl-C: end at once and silently (the main process reports the interrupt)."""
    signal.signal(signal.SIGINT, lambda signum, frame: os._exit(130))


def _submitted(calls: list, pool: TaskPool):
    """(executor, futures) of ``calls`` handed to ``pool``, or (None, []) when it broke twice meanwhile."""
    for _ in range(2):
        executor = pool.executor()
        try:
            return executor, [executor.submit(_contained, call) for call in calls]
        except (BrokenProcessPool, RuntimeError):  # broken by another thread's task, or shut down for that
            pool.discard(executor)
    return None, []


def _in_processes(calls: list, pool: TaskPool, done: Callable | None) -> list:
    results: list = [None] * len(calls)
    finished = [False] * len(calls)
    executor, futures = _submitted(calls, pool)
    for i, future in enumerate(futures):
        try:
            results[i] = future.result()
        except (BrokenProcessPool, CancelledError):  # a worker died (the pool cancels what it had not begun)
            pool.discard(executor)
            break
        finished[i] = True
        if done is not None:
            done(results[i])
    for i in (i for i, ok in enumerate(finished) if not ok):  # the pool broke: each task again, alone
        pool.ensure_open()
        with ProcessPoolExecutor(max_workers=1, initializer=_exit_on_interrupt) as alone:
            try:
                results[i] = alone.submit(_contained, calls[i]).result()
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
