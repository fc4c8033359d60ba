"""The diagnosis' process pool: candidates' fits and Drake replays run on all cores."""

from __future__ import annotations

import os
from concurrent.futures import ProcessPoolExecutor
from typing import Callable, Iterable, Iterator


def map_in_processes(function: Callable, tasks: list, workers: int | None = None,
                     done: Callable | None = None) -> Iterator:
    """``function`` over ``tasks`` in ``workers`` processes (default: all cores; 1: in this process), results
    in task order; ``done(result)`` after each one."""
    workers = workers or os.cpu_count() or 1
    if workers == 1 or len(tasks) <= 1:
        yield from _reported(map(function, tasks), done)
        return
    with ProcessPoolExecutor(max_workers=min(workers, len(tasks))) as pool:
        yield from _reported(pool.map(function, tasks), done)


def _reported(results: Iterable, done: Callable | None) -> Iterator:
    for result in results:
        if done is not None:
            done(result)
        yield result
