"""How a lab's log names and scales the columns furuta-drake reads: :class:`LogFormat`.

The log columns are ``time`` [s], ``theta`` and ``phi`` (angles) and one input, ``torque`` [N m] or ``voltage``
[V]. A lab's file may call them otherwise (Quanser names the arm ``theta`` and the pendulum ``alpha``) and give
the angles in degrees or encoder counts; ``diagnose --columns time=t,theta=alpha,phi=theta,voltage=vm
--angle-unit deg`` says so, and :class:`LogFormat` carries it to the readers and the checks.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

from furuta_drake.errors import ConfigError
from furuta_drake.rig import encoder_resolution

COLUMN_NAMES = ("time", "theta", "phi", "torque", "voltage")  # the names a mapping may use, in this order
ANGLE_UNITS = ("rad", "deg", "counts")


@dataclass(frozen=True)
class LogFormat:
    """Column mapping, angle unit and MCAP topic of the logs of one diagnosis.

    Parameters
    ----------
    columns
        furuta-drake's column name -> the file's column (or MCAP message field) name; a name not mapped is read
        under its own name.
    angle_unit
        ``"rad"``, ``"deg"`` or ``"counts"`` (encoder counts, converted with the rig's ``counts_per_rev``); both
        angles are in this unit.
    topic
        the MCAP channel to read (None: the file's only channel); other formats ignore it.
    run_column
        the file's column (or MCAP field) whose values split a file into runs, each a log of its own (None: one
        run per file).
    """

    columns: dict[str, str] = field(default_factory=dict)
    angle_unit: str = "rad"
    topic: str | None = None
    run_column: str | None = None

    def __post_init__(self) -> None:
        unknown = [name for name in self.columns if name not in COLUMN_NAMES]
        if unknown:
            raise ConfigError(
                f"--columns: unknown column name {unknown[0]!r} (furuta-drake's names: "
                f"{', '.join(COLUMN_NAMES)}; write NAME=FILE_COLUMN)"
            )
        targets: dict[str, str] = {}
        for name, column in self.columns.items():
            if not column:
                raise ConfigError(f"--columns: {name}= names no file column")
            if column in targets:
                raise ConfigError(
                    f"--columns: the file's column {column!r} is mapped to both {targets[column]!r} and {name!r}"
                )
            targets[column] = name
        shadowed = [name for name in COLUMN_NAMES if name not in self.columns and name in targets]
        if shadowed:
            raise ConfigError(
                f"--columns: the file's column {shadowed[0]!r} is read as {targets[shadowed[0]]!r}, "
                f"so {shadowed[0]!r} needs a column of its own ({shadowed[0]}=...)"
            )
        if self.run_column is not None and (
            not self.run_column
            or self.run_column in targets
            or (self.run_column in COLUMN_NAMES and self.run_column not in self.columns)
        ):
            raise ConfigError(
                f"--run-column: {self.run_column!r} is read as a signal column; name the file's run (trial) column"
            )
        if self.angle_unit not in ANGLE_UNITS:
            raise ConfigError(f"--angle-unit: unknown unit {self.angle_unit!r} (rad, deg or counts)")

    @classmethod
    def parse(
        cls,
        columns: str | None = None,
        angle_unit: str | None = None,
        topic: str | None = None,
        run_column: str | None = None,
    ) -> LogFormat:
        """The format the command line's ``--columns NAME=COLUMN,...``, ``--angle-unit``, ``--topic`` and
        ``--run-column`` give (None: the default); ConfigError naming the flag when one is malformed."""
        mapping: dict[str, str] = {}
        for item in (columns or "").split(",") if columns is not None else []:
            name, sep, column = (part.strip() for part in item.partition("="))
            if not sep:
                raise ConfigError(f"--columns: {item.strip()!r} is not NAME=FILE_COLUMN (e.g. theta=alpha)")
            if name in mapping:
                raise ConfigError(f"--columns: {name!r} is mapped twice ({mapping[name]!r} and {column!r})")
            mapping[name] = column
        return cls(columns=mapping, angle_unit=angle_unit or "rad", topic=topic, run_column=run_column)

    def column(self, name: str) -> str:
        """The file's column read as furuta-drake's ``name``."""
        return self.columns.get(name, name)

    def label(self, name: str) -> str:
        """How an error names the column read as ``name``: ``'alpha' (theta)`` when mapped, else ``'theta'``."""
        column = self.column(name)
        return f"{column!r}" if column == name else f"{column!r} ({name})"

    def radians_per_unit(self, counts_per_rev: int) -> float:
        """The factor from the logged angle unit to radians [rad per unit]."""
        return {"rad": 1.0, "deg": math.pi / 180.0, "counts": encoder_resolution(counts_per_rev)}[self.angle_unit]

    def describe(self) -> str:
        """The format in force as command-line flags ("" for the default)."""
        flags = []
        if self.columns:
            flags.append("--columns " + ",".join(f"{k}={v}" for k, v in self.columns.items()))
        if self.angle_unit != "rad":
            flags.append(f"--angle-unit {self.angle_unit}")
        if self.topic is not None:
            flags.append(f"--topic {self.topic}")
        if self.run_column is not None:
            flags.append(f"--run-column {self.run_column}")
        return " ".join(flags)

    def record(self) -> dict:
        """The format as ``config.yaml`` records it."""
        return {
            "columns": {name: self.column(name) for name in COLUMN_NAMES},
            "angle_unit": self.angle_unit,
            "topic": self.topic,
            "run_column": self.run_column,
        }


__all__ = ["LogFormat", "COLUMN_NAMES", "ANGLE_UNITS"]
