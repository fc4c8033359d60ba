"""A finished diagnosis as the experiment design reads it: its report, the rig file and the logs it was run on.

The output directory of ``furuta-drake diagnose`` holds ``report.json`` (the ranking of every model tried, the
accepted steps, the confusable pairs and the detection limits) and ``config.yaml`` (the rig file and the logs
with their sha256). The design needs the rig file the diagnosis started from (the nominal model every hypothesis
is built on) and the logs (their input column, the held-out windows the new log will join): both are read from
the paths ``config.yaml`` records (relative ones from the working directory), in the log format it records, and
must be unchanged since. Anything missing or from a report without the
keys the design reads is a :class:`~furuta_drake.errors.ConfigError` naming the file and the key.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import yaml

from furuta_drake.diagnosis.logs.format import LogFormat
from furuta_drake.diagnosis.logs.load import RunLog, load_logs
from furuta_drake.errors import ConfigError, FurutaError
from furuta_drake.rig import RigParameters
from furuta_drake.rig_file import load_rig

# The keys of report.json the design reads, each with the keys its entries need.
REPORT_KEYS = {
    "verdict": None,
    "effects": None,
    "ranking": ("effect", "params", "step", "status", "heldout_reduction", "reduction_over_previous"),
    "steps": ("effect",),
    "detection_limits": ("effect", "param", "value"),
}


@dataclass(frozen=True)
class DiagnosisRecord:
    """What the design reads from a diagnosis directory."""

    directory: Path
    report: dict  # report.json
    report_sha256: str
    rig: RigParameters
    rig_path: Path
    train: list[RunLog]  # the logs given as --train
    heldout: list[RunLog]  # the logs given as --heldout (empty: the diagnosis held out blocks of the train logs)
    inputs: dict  # config.yaml's rig, train and held-out entries (path, sha256)

    @property
    def input_kind(self) -> str:
        """The input column of the logs: ``voltage`` when they were voltage logs, else ``torque``."""
        kinds = {log.input_kind for log in self.train + self.heldout}
        return "voltage" if kinds == {"voltage"} else "torque"


def read_diagnosis(directory: str | Path) -> DiagnosisRecord:
    """Read and check a diagnosis output directory (module docstring)."""
    directory = Path(directory)
    if not directory.is_dir():
        raise ConfigError(
            f"{directory}: no such diagnosis directory (--diagnosis expects the --out directory "
            f"of furuta-drake diagnose)"
            if not directory.exists()
            else f"{directory}: is not a directory (--diagnosis expects the --out directory of furuta-drake diagnose)"
        )
    report_path, config_path = directory / "report.json", directory / "config.yaml"
    for path in (report_path, config_path):
        if not path.is_file():
            raise ConfigError(f"{path}: missing; --diagnosis expects the --out directory of furuta-drake diagnose")
    text = report_path.read_bytes()
    try:
        report = json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ConfigError(f"{report_path}: not valid JSON ({err})") from None
    _check_report(report, report_path)
    try:
        config = yaml.safe_load(config_path.read_text())
    except yaml.YAMLError as err:
        raise ConfigError(f"{config_path}: not valid YAML ({err})") from None
    inputs = _inputs(config, config_path)
    rig_path = _checked_input(inputs["rig"], config_path, "rig")
    rig = load_rig(rig_path)
    train = [_checked_input(entry, config_path, f"train[{i}]") for i, entry in enumerate(inputs["train"])]
    heldout = [_checked_input(entry, config_path, f"heldout[{i}]") for i, entry in enumerate(inputs["heldout"])]
    recorded = ((config.get("options") or {}).get("log_format")) or {}
    try:
        log_format = LogFormat(
            columns=dict(recorded.get("columns") or {}),
            angle_unit=recorded.get("angle_unit") or "rad",
            topic=recorded.get("topic"),
        )
        logs = load_logs(train + heldout, rig, rig_path, log_format)
    except FurutaError as err:
        raise ConfigError(f"{config_path}: a log it records no longer loads: {err}") from None
    return DiagnosisRecord(
        directory,
        report,
        hashlib.sha256(text).hexdigest(),
        rig,
        rig_path,
        logs[: len(train)],
        logs[len(train) :],
        inputs,
    )


def _check_report(report, path: Path) -> None:
    if not isinstance(report, dict):
        raise ConfigError(f"{path}: expected a JSON object")
    for key, entry_keys in REPORT_KEYS.items():
        if key not in report:
            raise ConfigError(
                f"{path}: no '{key}' key: written by another version of furuta-drake diagnose; run the diagnosis again"
            )
        for i, entry in enumerate(report[key] if entry_keys else []):
            missing = [k for k in entry_keys if k not in entry]
            if missing:
                raise ConfigError(
                    f"{path}: {key}[{i}] has no '{missing[0]}': written by another version of "
                    f"furuta-drake diagnose; run the diagnosis again"
                )


def _inputs(config, path: Path) -> dict:
    if not isinstance(config, dict):
        raise ConfigError(f"{path}: expected a mapping with the diagnosis' rig and logs")
    for key in ("rig", "train", "heldout"):
        if key not in config:
            raise ConfigError(f"{path}: no '{key}' key: written by another version of furuta-drake diagnose")
    return {"rig": config["rig"], "train": list(config["train"]), "heldout": list(config["heldout"] or [])}


def _checked_input(entry, config_path: Path, key: str) -> Path:
    """The path of an input ``config.yaml`` records, checked to exist and to have its recorded sha256."""
    if not isinstance(entry, dict) or "path" not in entry or "sha256" not in entry:
        raise ConfigError(f"{config_path}: {key} must have 'path' and 'sha256'")
    path = Path(entry["path"])
    if not path.is_file():
        raise ConfigError(
            f"{config_path}: {key} {path} is missing (the design reads the diagnosis' inputs where it recorded them)"
        )
    if hashlib.sha256(path.read_bytes()).hexdigest() != entry["sha256"]:
        raise ConfigError(
            f"{config_path}: {key} {path} changed since the diagnosis (its sha256 differs); run the diagnosis again"
        )
    return path
