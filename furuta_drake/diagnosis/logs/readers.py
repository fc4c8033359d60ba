"""Read the columns of one run log from CSV, Parquet or MCAP; :mod:`furuta_drake.diagnosis.logs.load` checks them.

The reader is picked by the file's extension: ``.parquet`` (pyarrow; one run per file, numeric columns),
``.mcap`` (the ``mcap`` package; one run per file, the messages of one channel, JSON-encoded, each message one
row whose fields are the columns) and anything else as CSV (header line, comma-separated numbers). A reader
produces the names it has and, for the columns asked for, a rows x columns float array with each row's location
for errors (``file:line`` for CSV, ``file: row k`` for Parquet, ``file: topic 't': message k`` for MCAP). Every
format-level problem is a :class:`~furuta_drake.errors.LogError` naming the file.

MCAP time: a mapped ``time`` field is read like any column; when ``time`` is not mapped the rows' time is each
message's ``log_time`` (nanoseconds, converted to seconds).
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

from furuta_drake.errors import LogError, read_input_text

LOG_TIME = "log_time"  # an MCAP message's log time, the time column when --columns maps no time field

Where = Callable[[int], str]  # the location of a data row, for errors


def open_log(path: Path, topic: str | None = None):
    """The reader for ``path`` by its extension; ``topic`` selects an MCAP channel (other formats ignore it)."""
    suffix = path.suffix.lower()
    if suffix == ".parquet":
        return ParquetColumns(path)
    if suffix == ".mcap":
        return McapColumns(path, topic)
    return CsvColumns(path)


class CsvColumns:
    """A CSV log: header line of column names, then one row of comma-separated numbers per sample."""

    default_time = "time"

    def __init__(self, path: Path):
        self.path = path
        lines = read_input_text(path, "a CSV log", LogError).splitlines()
        while lines and not lines[-1].strip():
            lines.pop()
        if not lines:
            raise LogError(f"{path}:1: empty file, expected a header line 'time,theta,phi,torque' (or voltage)")
        self.lines = lines
        self.names = tuple(name.strip() for name in lines[0].lstrip("\ufeff").split(","))
        self.header_where = f"{path}:1"
        seen = set()
        for index, name in enumerate(self.names):
            if name in seen:
                raise LogError(f"{path}:1: column {index + 1}: duplicate column name {name!r}")
            seen.add(name)

    def read(self, columns: dict[str, str]) -> tuple[np.ndarray, Where]:
        """The file's ``columns`` (name -> label for errors) as floats, rows x columns, and each row's line."""
        path, header = self.path, self.names
        body = self.lines[1:]
        line_numbers = np.arange(2, len(self.lines) + 1)
        keep = np.array([bool(line.strip()) for line in body], bool)
        body = [line for line, k in zip(body, keep) if k]
        line_numbers = line_numbers[keep]
        if not body:
            raise LogError(f"{path}:1: header only, no data rows")
        expected_commas = len(header) - 1
        if sum(line.count(",") for line in body) != expected_commas * len(body):
            for line, number in zip(body, line_numbers):
                if line.count(",") != expected_commas:
                    raise LogError(f"{path}:{number}: {line.count(',') + 1} fields, the header has {len(header)}")
        indices = [header.index(name) for name in columns]
        try:
            data = np.loadtxt(body, delimiter=",", usecols=indices, dtype=float, ndmin=2)
        except ValueError as err:
            for line, number in zip(body, line_numbers):
                fields = line.split(",")
                for label, index in zip(columns.values(), indices):
                    try:
                        float(fields[index])
                    except ValueError:
                        raise LogError(
                            f"{path}:{number}: column {label}: {fields[index].strip()!r} is not a number"
                        ) from None
            raise LogError(f"{path}: cannot read the numbers ({err})") from None
        return data, lambda row: f"{path}:{int(line_numbers[row])}"


class ParquetColumns:
    """A Parquet file holding one run: one numeric column per signal, one row per sample."""

    default_time = "time"

    def __init__(self, path: Path):
        import pyarrow
        import pyarrow.parquet as pq

        _check_file(path, "a Parquet file")
        self.path = path
        self.header_where = str(path)
        try:
            self.names = tuple(pq.read_schema(path).names)
        except (pyarrow.ArrowException, OSError) as err:
            raise LogError(f"{path}: not a Parquet file ({_first_line(err)})") from None

    def read(self, columns: dict[str, str]) -> tuple[np.ndarray, Where]:
        import pyarrow
        import pyarrow.compute as pc
        import pyarrow.parquet as pq

        try:
            table = pq.read_table(self.path, columns=list(columns))
        except (pyarrow.ArrowException, OSError) as err:
            raise LogError(f"{self.path}: cannot read the columns ({_first_line(err)})") from None
        if table.num_rows == 0:
            raise LogError(f"{self.path}: no rows")
        data = np.empty((table.num_rows, len(columns)))
        for j, (name, label) in enumerate(columns.items()):
            column = table.column(name)
            if not (pyarrow.types.is_integer(column.type) or pyarrow.types.is_floating(column.type)):
                raise LogError(f"{self.path}: column {label} holds {column.type}, expected numbers")
            if column.null_count:
                row = int(pc.index(pc.is_null(column), True).as_py())
                raise LogError(f"{self.path}: row {row + 1}: column {label} is empty (null)")
            data[:, j] = column.to_numpy().astype(float)
        return data, lambda row: f"{self.path}: row {row + 1}"


class McapColumns:
    """An MCAP file holding one run: the JSON-encoded messages of one channel, one message per sample."""

    default_time = LOG_TIME

    def __init__(self, path: Path, topic: str | None):
        from mcap.reader import make_reader

        _check_file(path, "an MCAP file")
        self.path = path
        try:
            with open(path, "rb") as stream:
                reader = make_reader(stream)
                summary = reader.get_summary()
                channels = list(summary.channels.values()) if summary is not None else []
                if not channels:
                    channels = {channel.id: channel for _, channel, _ in reader.iter_messages()}.values()
                channel = self._channel(list(channels), topic)
                messages = [message for _, _, message in reader.iter_messages(topics=[channel.topic])]
        except LogError:
            raise
        except Exception as err:  # the mcap package raises many types on a file that is not MCAP
            raise LogError(f"{path}: not a readable MCAP file ({type(err).__name__}: {_first_line(err)})") from None
        self.header_where = f"{path}: topic {channel.topic!r}"
        if channel.message_encoding != "json":
            raise LogError(
                f"{self.header_where}: messages are {channel.message_encoding!r}-encoded; furuta-drake "
                f"reads JSON-encoded messages (one field per column)"
            )
        if not messages:
            raise LogError(f"{self.header_where}: no messages")
        self.rows = []
        for k, message in enumerate(messages):
            try:
                fields = json.loads(message.data)
            except (ValueError, UnicodeDecodeError) as err:
                raise LogError(f"{self.header_where}: message {k + 1}: not JSON ({err})") from None
            if not isinstance(fields, dict):
                raise LogError(
                    f"{self.header_where}: message {k + 1}: a JSON {type(fields).__name__}, expected an "
                    f"object whose fields are the columns"
                )
            self.rows.append(fields)
        self.log_times = np.array([message.log_time for message in messages], dtype=np.int64)
        self.names = tuple(dict.fromkeys(name for fields in self.rows for name in fields)) + (LOG_TIME,)

    def _channel(self, channels: list, topic: str | None):
        topics = sorted(channel.topic for channel in channels)
        if topic is None:
            if len(channels) != 1:
                raise LogError(
                    f"{self.path}: {len(channels)} channels ({', '.join(topics) or 'none'}): name the "
                    f"run's with --topic"
                )
            return channels[0]
        matching = [channel for channel in channels if channel.topic == topic]
        if not matching:
            raise LogError(
                f"{self.path}: no channel with topic {topic!r} (--topic); the file has: "
                f"{', '.join(topics) or 'no channel'}"
            )
        return matching[0]

    def read(self, columns: dict[str, str]) -> tuple[np.ndarray, Where]:
        data = np.empty((len(self.rows), len(columns)))
        for j, (name, label) in enumerate(columns.items()):
            if name == LOG_TIME and not any(LOG_TIME in fields for fields in self.rows[:1]):
                data[:, j] = self.log_times / 1e9
                continue
            for k, fields in enumerate(self.rows):
                value = fields.get(name)
                if isinstance(value, bool) or not isinstance(value, (int, float)):
                    what = "has no field" if name not in fields else f"has {value!r} in field"
                    raise LogError(f"{self.header_where}: message {k + 1} {what} {label}, expected a number")
                data[k, j] = value
        return data, lambda row: f"{self.header_where}: message {row + 1}"


def _check_file(path: Path, expected: str) -> None:
    if path.is_dir():
        raise LogError(f"{path}: is a directory, expected {expected}")
    if not path.is_file():
        raise LogError(f"{path}: no such file")


def _first_line(err: Exception) -> str:
    text = str(err).strip()
    return text.splitlines()[0] if text else type(err).__name__


__all__ = ["open_log", "CsvColumns", "ParquetColumns", "McapColumns", "LOG_TIME"]
