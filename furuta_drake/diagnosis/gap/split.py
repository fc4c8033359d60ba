"""Which data train and which are held out (stage 2 of the diagnosis): the automatic split of logs into blocks
when no held-out logs are given, and the folds of ``--folds``."""

from __future__ import annotations

import dataclasses

import numpy as np

from furuta_drake.diagnosis.gap.metric import window_samples
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.rig import RigParameters

HOLDOUT_FRACTION = 0.3
HOLDOUT_BLOCKS = 10
MIN_BLOCK_S = 1.0  # [s]: three or more gap windows per block
MIN_BLOCKS = 3


def _cut(log: RunLog, edges: list[int], held: set[int]) -> tuple[list[RunLog], list[RunLog]]:
    """``log`` cut at sample ``edges`` into blocks: (train blocks, held-out blocks ``held``), each named with its
    times."""
    train, heldout = [], []
    for k, (first, last) in enumerate(zip(edges[:-1], edges[1:])):
        part = dataclasses.replace(
            log,
            name=f"{log.name} (t = {log.time[first]:.2f}-{log.time[last - 1]:.2f} s)",
            time=log.time[first:last],
            theta=log.theta[first:last],
            phi=log.phi[first:last],
            input=log.input[first:last],
        )
        (heldout if k in held else train).append(part)
    return train, heldout


def _blocks(log: RunLog) -> int:
    return min(HOLDOUT_BLOCKS, int(log.time.size * log.sample_period / MIN_BLOCK_S))


def _held_out_blocks(blocks: int) -> set[int]:
    """Which of ``blocks`` equal blocks are held out: HOLDOUT_FRACTION of them, spread evenly (1, 4, 8 of 10)."""
    held = max(1, round(HOLDOUT_FRACTION * blocks))
    return {int(round((i + 0.5) * blocks / held - 0.5)) for i in range(held)}


def _whole_runs(logs: list[RunLog], folds: int | None = None, fold: int = 0):
    """The runs of files split by --run-column with at least MIN_BLOCKS runs, held out whole: (train runs,
    held-out runs, the other logs). Without ``folds`` HOLDOUT_FRACTION of each file's runs, spread over it; with
    them the runs k with k mod folds == fold."""
    files: dict[str, list[RunLog]] = {}
    for log in logs:
        if log.run is not None:
            files.setdefault(log.path, []).append(log)
    train, heldout, rest = [], [], []
    for log in logs:
        runs = files.get(log.path, [])
        if len(runs) < max(MIN_BLOCKS, folds or 0):
            rest.append(log)
            continue
        k = runs.index(log)
        held = k % folds == fold if folds else k in _held_out_blocks(len(runs))
        (heldout if held else train).append(log)
    return train, heldout, rest


def split_heldout(logs: list[RunLog]) -> tuple[list[RunLog], list[RunLog], str]:
    """Without --heldout: every log is cut into up to HOLDOUT_BLOCKS equal blocks of at least MIN_BLOCK_S and
    HOLDOUT_FRACTION of the blocks, spread over the run, are held out, so train and held-out data both see every
    phase of it (the tail of a swing-up log is only balancing). A log too short for MIN_BLOCKS blocks holds
    out its last HOLDOUT_FRACTION. The runs of a file split by --run-column are held out whole instead
    (HOLDOUT_FRACTION of them, spread over the file), when it has at least MIN_BLOCKS runs."""
    train, heldout, logs = _whole_runs(logs)
    for log in logs:
        blocks = _blocks(log)
        if blocks < MIN_BLOCKS:
            edges, held = [0, int(log.time.size * (1.0 - HOLDOUT_FRACTION)), log.time.size], {1}
        else:
            edges, held = np.linspace(0, log.time.size, blocks + 1).astype(int).tolist(), _held_out_blocks(blocks)
        parts = _cut(log, edges, held)
        train, heldout = train + parts[0], heldout + parts[1]
    return (
        train,
        heldout,
        (
            f"no --heldout logs: each train log was cut into up to {HOLDOUT_BLOCKS} equal blocks of at least "
            f"{MIN_BLOCK_S:g} s and {HOLDOUT_FRACTION:.0%} of them, spread over the run, were held out and never used "
            f"for fitting (a log shorter than {MIN_BLOCKS} blocks held out its last {HOLDOUT_FRACTION:.0%}; a "
            f"file of runs, whole runs): " + ", ".join(log.name for log in heldout)
        ),
    )


def fold_split(logs: list[RunLog], folds: int, fold: int, rig: RigParameters) -> tuple[list[RunLog], list[RunLog]]:
    """Split ``fold`` of ``folds``: every log cut into max(folds, up to HOLDOUT_BLOCKS) equal blocks, the blocks
    b with b mod folds == fold held out (each fold holds out other blocks, spread over every log); a log too
    short for ``folds`` blocks of one gap window each trains in every fold. The runs of a file split by
    --run-column are the blocks instead, held out whole."""
    train, heldout, logs = _whole_runs(logs, folds, fold)
    for log in logs:
        blocks = max(folds, _blocks(log))
        if (
            log.time.size // blocks
            <= sum(window_samples(log.sample_period, rig)) + window_samples(log.sample_period, rig)[1]
        ):
            train.append(log)
            continue
        edges = np.linspace(0, log.time.size, blocks + 1).astype(int).tolist()
        parts = _cut(log, edges, {b for b in range(blocks) if b % folds == fold})
        train, heldout = train + parts[0], heldout + parts[1]
    return train, heldout
