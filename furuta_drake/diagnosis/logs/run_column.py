"""Many runs in one log file (``diagnose --run-column NAME``): the file's rows grouped into runs by the values of
one column, each run a log of its own with its own time base (``docs/diagnose.md``)."""

from __future__ import annotations

import numpy as np

from furuta_drake.diagnosis.logs.readers import Where

Run = tuple[str, int, int]  # (run label, first row, end row) of the grouped table


def run_label(value: float) -> str:
    """How a run value names its run: ``7`` for an integer value, else the float's shortest repr."""
    return str(int(value)) if float(value).is_integer() else repr(float(value))


def split_runs(run_values: np.ndarray, data: np.ndarray, where: Where) -> tuple[np.ndarray, list[Run], Where]:
    """The rows of ``data`` grouped by ``run_values``: (the table with each run's rows contiguous, the runs in
    the order they first appear, the location of a row of that table in the file).

    A file whose runs are already contiguous (the usual trial table) is returned as it is; otherwise the rows are
    reordered once, keeping each run's rows in file order."""
    starts = _starts(run_values)
    if np.unique(run_values[starts]).size != starts.size:
        _, first_row, inverse = np.unique(run_values, return_index=True, return_inverse=True)
        rank = np.argsort(np.argsort(first_row))  # each value's rank by first appearance
        order = np.argsort(rank[inverse], kind="stable")
        data, run_values = data[order], run_values[order]
        where = _reordered(where, order)
        starts = _starts(run_values)
    ends = np.append(starts[1:], run_values.size)
    return data, [(run_label(run_values[a]), int(a), int(b)) for a, b in zip(starts, ends)], where


def _starts(run_values: np.ndarray) -> np.ndarray:
    return np.concatenate([[0], np.flatnonzero(run_values[1:] != run_values[:-1]) + 1])


def _reordered(where: Where, order: np.ndarray) -> Where:
    return lambda row: where(int(order[row]))


__all__ = ["split_runs", "run_label", "Run"]
