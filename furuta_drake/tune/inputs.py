"""A diagnosis as ``tune`` reads it: ``fitted_rig.yaml`` (the rig file with the accepted effects) and
``report.json`` (which effects were accepted, their fitted parameters and 95 % intervals, the torque beyond the
vocabulary if one was kept).

The accepted model's row of the ranking is the one (status ``ok``, the latest step) whose effects are the accepted
ones; its ``params_ci`` give each parameter's interval (keys ``effect.param`` when the row holds several effects).
The central values are ``fitted_rig.yaml``'s: the rig file a lab continues from. Effects the rig file stated before
the diagnosis are part of the model and have no interval. Anything missing or malformed is a
:class:`~furuta_drake.errors.ConfigError` naming the file and the key.
"""

from __future__ import annotations

import dataclasses
import hashlib
import json
import math
from dataclasses import dataclass
from pathlib import Path

from furuta_drake.effects.vocabulary import CANDIDATES, DRIVE_KEYS, POSITIVE, SIGNED, Effect, drive_effects, rig_effects
from furuta_drake.errors import ConfigError
from furuta_drake.rig import RigParameters
from furuta_drake.rig_file import load_rig

FILES = ("fitted_rig.yaml", "report.json")


@dataclass(frozen=True)
class TuneInputs:
    """What ``tune`` reads from a diagnosis directory.

    ``rig``: the fitted rig file (with the accepted effects); ``nominal``: the same rig file without any effect or
    torque beyond the vocabulary (what a lab designs on today); ``accepted``: the effects the diagnosis accepted
    (name -> :class:`Effect`, as the fitted rig file states them); ``intervals``: (effect, parameter) -> its 95 %
    interval; ``torque``: the report's ``unmodelled_torque`` section (empty when none was kept); ``notes``: on
    intervals moved into their parameter's physical range; ``sha256``: of each file read."""

    directory: Path
    rig: RigParameters
    nominal: RigParameters
    accepted: dict[str, Effect]
    intervals: dict[tuple[str, str], tuple[float, float]]
    verdict: str
    torque: dict
    notes: list[str]
    sha256: dict[str, str]


def read_diagnosis(directory: str | Path) -> TuneInputs:
    """Read and check a diagnosis output directory (module docstring)."""
    directory = Path(directory)
    if not directory.is_dir():
        what = "no such directory" if not directory.exists() else "not a directory"
        raise ConfigError(f"{directory}: {what} (--diagnosis expects the --out directory of furuta-drake diagnose)")
    for name in FILES:
        if not (directory / name).is_file():
            raise ConfigError(f"{directory / name}: missing; --diagnosis expects the --out directory of diagnose")
    rig_path, report_path = directory / "fitted_rig.yaml", directory / "report.json"
    rig = load_rig(rig_path)
    text = report_path.read_bytes()
    try:
        report = json.loads(text)
    except (json.JSONDecodeError, UnicodeDecodeError) as err:
        raise ConfigError(f"{report_path}: not valid JSON ({err})") from None
    if not isinstance(report, dict):
        raise ConfigError(f"{report_path}: expected a JSON object")
    for key in ("verdict", "effects", "ranking"):
        if key not in report:
            raise ConfigError(f"{report_path}: no '{key}' key (written by another version of diagnose?)")
    effects = report["effects"]
    if not isinstance(effects, list) or not all(isinstance(name, str) and name in CANDIDATES for name in effects):
        raise ConfigError(f"{report_path}: effects must be a list of the vocabulary's effect names, got {effects!r}")
    stated = {**rig_effects(rig), **drive_effects(rig)}
    for name in effects:
        if name not in stated:
            raise ConfigError(f"{rig_path}: effects.{name}: missing, but {report_path} accepted it")
    accepted = {name: stated[name] for name in effects}
    intervals, notes = _intervals(report, report_path, accepted) if accepted else ({}, [])
    torque = report.get("unmodelled_torque") or {}
    if not isinstance(torque, dict):
        raise ConfigError(f"{report_path}: unmodelled_torque must be an object, got {torque!r}")
    nominal = rig.replace(effects=None, unmodelled_torque=None)
    return TuneInputs(
        directory,
        rig,
        nominal,
        accepted,
        intervals,
        str(report["verdict"]),
        torque,
        notes,
        {name: hashlib.sha256((directory / name).read_bytes()).hexdigest() for name in FILES},
    )


def accepted_row(report: dict, path: Path, names) -> tuple[int, dict]:
    """(index, entry) of the ranking row of the accepted model: status ok, its effects ``names``, latest step."""
    ranking = report["ranking"]
    if not isinstance(ranking, list):
        raise ConfigError(f"{path}: ranking must be a list")
    rows = [
        (i, entry)
        for i, entry in enumerate(ranking)
        if isinstance(entry, dict)
        and entry.get("status", "ok") == "ok"
        and isinstance(entry.get("effect"), str)
        and set(entry["effect"].split("+")) == set(names)
    ]
    if not rows:
        raise ConfigError(f"{path}: ranking has no row of the accepted effects {'+'.join(names)}")
    return max(rows, key=lambda row: row[1].get("step", 0) or 0)


def _intervals(report: dict, path: Path, accepted: dict[str, Effect]) -> tuple[dict, list[str]]:
    """Every form parameter of the accepted effects -> its 95 % interval from the accepted row's ``params_ci``
    (a parameter the row lists ``at_bound`` has none: it is held at its fit), and notes on the ends moved into the
    parameter's physical range (:func:`physical_interval`) and on the parameters held."""
    index, row = accepted_row(report, path, list(accepted))
    intervals = row.get("params_ci")
    if not isinstance(intervals, dict):
        raise ConfigError(f"{path}: ranking[{index}].params_ci: missing (the 95 % intervals of the accepted model)")
    several = len(row["effect"].split("+")) > 1
    out, notes = {}, []
    for name, effect in accepted.items():
        for param, value in zip(CANDIDATES[name].form(effect.form).params, effect.values):
            key = f"{name}.{param}" if several else param
            where = f"{path}: ranking[{index}].params_ci.{key}"
            interval = intervals.get(key)
            if interval is None and key in (row.get("at_bound") or {}):
                # fitted at an end of its search range: the diagnosis gives no interval, the fit is held
                out[(name, param)] = (float(value), float(value))
                notes.append(
                    f"{name}.{param}: fitted at the {row['at_bound'][key]} end of its search range, so it "
                    "has no interval; it is held at its fit over the intervals"
                )
                continue
            if interval is None:
                raise ConfigError(f"{where}: missing")
            if (
                not isinstance(interval, list)
                or len(interval) != 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in interval)
                or not all(math.isfinite(v) for v in interval)
                or interval[0] > interval[1]
            ):
                raise ConfigError(f"{where} must be [low, high], two finite numbers with low <= high, got {interval!r}")
            out[(name, param)], note = physical_interval(param, value, (float(interval[0]), float(interval[1])))
            if note:
                notes.append(f"{name}.{param}: {note}")
    return out, notes


def physical_interval(param: str, value: float, interval: tuple[float, float]) -> tuple[tuple[float, float], str]:
    """``interval`` of ``param`` (fitted at ``value``) within the parameter's physical range, and a note when an
    end was moved: a lower end at or below zero of a positive parameter (a fit at the end of its search range)
    is taken a decade below the fitted value, a negative end of a non-negative one at zero."""
    low, high = interval
    if param in SIGNED:
        return (low, high), ""
    if param in POSITIVE and low <= 0.0:
        moved = (value / 10.0, max(high, value))
        return moved, f"the interval reaches {low:g}; its lower end is taken a decade below the fit, {moved[0]:.3g}"
    if low < 0.0:
        return (0.0, max(high, 0.0)), f"the interval reaches {low:g}; its lower end is taken at 0"
    return (low, high), ""


def corner_rig(inputs: TuneInputs, corner: dict[tuple[str, str], float]) -> RigParameters:
    """The fitted rig file with the accepted effects' parameters of ``corner`` ((effect, parameter) -> value) in
    place of the fitted ones."""
    effects, drive = dict(inputs.rig.effects or {}), inputs.rig.drive
    for name, effect in inputs.accepted.items():
        params = CANDIDATES[name].form(effect.form).params
        entry = {param: corner.get((name, param), value) for param, value in zip(params, effect.values)}
        if name in DRIVE_KEYS:  # the drive section's keys
            drive = dataclasses.replace(drive, **entry)
            continue
        if len(CANDIDATES[name].forms) > 1:
            entry["form"] = effect.form
        effects[name] = entry
    return inputs.rig.replace(effects=effects, drive=drive)
