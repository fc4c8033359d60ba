"""Result files of a simulation: the log CSV of ``furuta-drake diagnose`` (``docs/diagnose.md``), the summary and the
config.

Everything written here is deterministic (fixed float formatting, sorted keys, no wall-clock figures), so
the same config and seed give byte-identical files.
"""

from __future__ import annotations

import csv
import dataclasses
import json
import math
from pathlib import Path

import numpy as np

from furuta_drake.config import SimulationConfig, dump_config
from furuta_drake.outputs import versions
from furuta_drake.yamlio import to_plain

LOG_COLUMNS = ["time", "torque", "theta", "phi", "theta_true", "phi_true", "theta_dot_true", "phi_dot_true"]


def write_log_csv(result, path: str | Path) -> None:
    """The diagnosis' log format: ``time, torque, theta, phi`` (encoder angles, torque command), then the true
    angles and velocities the simulation knows (extra columns, ignored by ``diagnose``)."""
    table = np.column_stack([result.time, result.torque, result.measured, result.state])
    np.savetxt(path, table, delimiter=",", header=",".join(LOG_COLUMNS), comments="", fmt="%.9g")


def config_yaml_with_provenance(config: SimulationConfig) -> str:
    """The resolved config, loadable by ``simulate --config``, headed by the versions as YAML comments."""
    header = "".join(f"# {name} {version}\n" for name, version in versions().items())
    return header + dump_config(config)


def summary(result, config: SimulationConfig) -> dict:
    """Figures of a run: control accuracy (paper Table I statistics), extremes, the LQR gain."""
    theta, phi = result.state[:, 0], result.state[:, 1]
    out = {
        "duration_s": float(result.time[-1] - result.time[0] + config.control_period),
        "samples": int(result.time.size),
        "seed": config.seed,
        "theta_abs_max_rad": float(np.max(np.abs(theta))),
        "phi_abs_max_rad": float(np.max(np.abs(phi))),
        "mean_theta_sq_rad2": float(np.mean(theta**2)),
        "std_theta_sq_rad2": float(np.std(theta**2)),
        "mean_phi_sq_rad2": float(np.mean(phi**2)),
        "std_phi_sq_rad2": float(np.std(phi**2)),
        "torque_rms_Nm": float(np.sqrt(np.mean(result.torque**2))),
        "final_state": [float(v) for v in result.state[-1]],
        "lqr_gain": None if result.lqr_gain is None else [float(v) for v in np.ravel(result.lqr_gain)],
        "diverged": False,
    }
    for name, estimate in result.estimates.items():
        err = estimate[:, 2:] - result.state[:, 2:]
        out[f"{name}_velocity_mse"] = {
            "theta_dot": float(np.mean(err[:, 0] ** 2)),
            "phi_dot": float(np.mean(err[:, 1] ** 2)),
        }
    return out


def write_table_csv(rows: list[dict], path: str | Path) -> None:
    """Deterministic CSV of rows with the same keys: floats to 12 significant digits, booleans true/false,
    lists as JSON, None empty."""
    with open(path, "w", newline="") as file:
        writer = csv.writer(file, lineterminator="\n")
        writer.writerow(list(rows[0]))
        writer.writerows([table_cell(value) for value in row.values()] for row in rows)


def table_cell(value) -> str:
    """One CSV cell of :func:`write_table_csv`."""
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, float):
        return f"{value:.12g}"
    if isinstance(value, (list, tuple, dict)) or dataclasses.is_dataclass(value):
        return json.dumps(to_plain(value))
    return str(value)


def write_json(path: str | Path, data: dict) -> None:
    """Deterministic JSON: sorted keys, floats rounded to 12 significant digits, NaN as null."""
    Path(path).write_text(json.dumps(_rounded(data), indent=2, sort_keys=True) + "\n")


def _rounded(value):
    if isinstance(value, dict):
        return {k: _rounded(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_rounded(v) for v in value]
    if isinstance(value, float):
        return None if not math.isfinite(value) else float(f"{value:.12g}")
    return value
