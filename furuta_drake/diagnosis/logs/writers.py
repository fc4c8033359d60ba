"""Write a run log's columns as CSV, Parquet or MCAP (by extension), in the layouts
:mod:`~furuta_drake.diagnosis.logs.readers` reads: for converting a lab's logs and for tests of the readers."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np


def write_log(path: str | Path, columns: dict[str, np.ndarray], topic: str = "/furuta/log", time: str = "time") -> Path:
    """Write ``columns`` (name -> one value per sample) to ``path``.

    Parameters
    ----------
    path
        ``.parquet``: one float column per name; ``.mcap``: one JSON message per sample on channel ``topic``
        whose fields are the columns, logged at ``columns[time]`` [s] (as nanoseconds) when there is such a
        column, else at the sample index in milliseconds; anything else: CSV with a header line.
    columns
        equal-length numeric arrays; floats are written so that they read back exactly.
    topic
        the MCAP channel's topic.
    time
        the column that gives an MCAP message's log time.
    """
    path = Path(path)
    arrays = {name: np.asarray(values, dtype=float) for name, values in columns.items()}
    suffix = path.suffix.lower()
    if suffix == ".parquet":
        import pyarrow as pa
        import pyarrow.parquet as pq

        pq.write_table(pa.table(arrays), path)
    elif suffix == ".mcap":
        _write_mcap(path, arrays, topic, time)
    else:
        table = np.column_stack(list(arrays.values()))
        lines = [",".join(arrays)] + [",".join(repr(float(v)) for v in row) for row in table]
        path.write_text("\n".join(lines) + "\n")
    return path


def _write_mcap(path: Path, arrays: dict[str, np.ndarray], topic: str, time: str) -> None:
    from mcap.writer import Writer

    n = len(next(iter(arrays.values())))
    log_times = (
        np.round(arrays[time] * 1e9).astype(np.int64) if time in arrays else np.arange(n, dtype=np.int64) * 1_000_000
    )
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start()
        schema = writer.register_schema(
            name="furuta_log",
            encoding="jsonschema",
            data=json.dumps({"type": "object", "properties": {name: {"type": "number"} for name in arrays}}).encode(),
        )
        channel = writer.register_channel(topic=topic, message_encoding="json", schema_id=schema)
        for k in range(n):
            data = json.dumps({name: float(values[k]) for name, values in arrays.items()}).encode()
            writer.add_message(
                channel, log_time=int(log_times[k]), data=data, publish_time=int(log_times[k]), sequence=k
            )
        writer.finish()


__all__ = ["write_log"]
