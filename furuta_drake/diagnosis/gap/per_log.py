"""The held-out prediction error of each log and signal, with the rig file's model and with the accepted effects:
the per-log rows of ``report.json``'s ``gap.heldout_rms_per_log`` (the report's before/after picture)."""

from __future__ import annotations

import numpy as np

from furuta_drake.diagnosis.logs.load import WindowResiduals

SIGNALS = ("theta", "phi")


def rms_by_log(windows: list[WindowResiduals]) -> dict[str, dict[str, float]]:
    """{log: {signal: RMS residual over the log's windows [counts]}} (sensor noise included), logs in order."""
    squares: dict[str, list[np.ndarray]] = {}
    for window in windows:
        squares.setdefault(window.log_name, []).append(np.square(np.asarray(window.residual, float)))
    return {
        log: dict(zip(SIGNALS, np.sqrt(np.concatenate(parts).mean(axis=0)).tolist())) for log, parts in squares.items()
    }


def heldout_rms_per_log(before: list[WindowResiduals], after: list[WindowResiduals] | None) -> list[dict]:
    """One row per held-out log: ``{"log", "nominal": {theta, phi}, "with_effects": {theta, phi}}`` [counts RMS];
    without accepted effects both are the nominal model's."""
    nominal = rms_by_log(before)
    corrected = rms_by_log(after) if after else nominal
    return [{"log": log, "nominal": nominal[log], "with_effects": corrected[log]} for log in nominal]
