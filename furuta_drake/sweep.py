"""Parameter sweeps: a grid or a random sample over any config fields, one simulation per point, on Dask.

A sweep file (YAML, strict keys like every config of this package)::

    base_file: lund_balance.yaml      # a simulate config, relative to this file; or inline it under ``base:``
    mode: grid                        # grid: every combination of ``parameters``; random: ``samples`` draws
    parameters:                       # dotted paths into the simulate config -> values
      friction.arm.coulomb_pos: [0.0, 0.015, 0.03]
      encoder.counts_per_rev: [1024, 4096]
      initial_state[0]: [0.05, 0.2]   # an item of a list field
    seed: 1
    metrics: [velocity_mse, mean_theta_sq_rad2, theta_abs_max_rad]

In random mode, ``ranges`` maps each path to ``[low, high]`` (uniform; integers for integer fields) and
``samples`` says how many points to draw. Each point's simulation seed (``seed`` and ``encoder.seed`` of its
config, unless the sweep sets those paths itself) and, in random mode, its values come from
``numpy.random.SeedSequence(sweep seed, spawn_key=(point index, ...))``: a point's result depends on the sweep
seed and its index only, never on the number of workers, their scheduling, or (random mode) ``samples``.

A point whose simulation the monitor stops is a row with ``diverged = true``, its time and cause; the sweep
carries on. A point whose config is bad input (a non-physical value, a gain that does not stabilise the
upright) stops the sweep with a ConfigError naming the sweep file, the point and its values.

Simulations run on a ``dask.distributed`` cluster: a LocalCluster of single-threaded worker processes by
default, or an existing cluster's scheduler (whose workers must have this package installed).
"""

from __future__ import annotations

import dataclasses
import itertools
import logging
import math
import os
import re
import types
import typing
from collections.abc import Callable
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import matplotlib.pyplot as plt
import numpy as np
import yaml
from dask.distributed import Client, LocalCluster, as_completed

from furuta_drake.config import SimulationConfig, load_config
from furuta_drake.errors import ConfigError, SimulationDiverged
from furuta_drake.outputs import atomic_output_dir, prepare_output_dir
from furuta_drake.results import config_yaml_with_provenance, summary, table_cell, write_table_csv
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import convert_node, dump_yaml_dataclass, load_yaml_dataclass, loads_yaml_dataclass

VELOCITY_MSE = "velocity_mse"
METRICS = (
    VELOCITY_MSE,
    "mean_theta_sq_rad2",
    "std_theta_sq_rad2",
    "mean_phi_sq_rad2",
    "std_phi_sq_rad2",
    "theta_abs_max_rad",
    "phi_abs_max_rad",
    "torque_rms_Nm",
)
METRIC_LABELS = {
    "mean_theta_sq_rad2": r"mean $\theta^2$ [rad$^2$]",
    "std_theta_sq_rad2": r"std $\theta^2$ [rad$^2$]",
    "mean_phi_sq_rad2": r"mean $\phi^2$ [rad$^2$]",
    "std_phi_sq_rad2": r"std $\phi^2$ [rad$^2$]",
    "theta_abs_max_rad": r"max $|\theta|$ [rad]",
    "phi_abs_max_rad": r"max $|\phi|$ [rad]",
    "torque_rms_Nm": "torque RMS [N m]",
    "diverged": "diverged (1 = yes)",
}
SEED_PATHS = ("seed", "encoder.seed")
_SEGMENT = re.compile(r"^([A-Za-z_]\w*)(?:\[(\d+)\])?$")


@dataclass
class SweepConfig:
    """A sweep file. ``base`` is the simulate config every point starts from (absent keys: SimulationConfig's
    defaults, as in ``simulate --config``); ``base_file`` instead names a simulate config YAML (relative to the
    sweep file). ``metrics``: result columns, from :data:`METRICS`; ``velocity_mse`` gives, for every observer
    that ran, the mean squared error of its theta_dot and phi_dot estimates against the true velocities
    [rad^2/s^2]; the others are those of :func:`furuta_drake.results.summary`, over the whole run."""

    base: SimulationConfig = field(default_factory=SimulationConfig)
    base_file: str | None = None
    mode: Literal["grid", "random"] = "grid"
    parameters: dict[str, list[Any]] = field(default_factory=dict)  # grid: dotted path -> values
    ranges: dict[str, list[float]] = field(default_factory=dict)  # random: dotted path -> [low, high]
    samples: int = 0  # random: number of points
    seed: int = 0
    metrics: list[str] = field(
        default_factory=lambda: [VELOCITY_MSE, "mean_theta_sq_rad2", "mean_phi_sq_rad2", "theta_abs_max_rad"]
    )

    def validate(self, where: str = "") -> None:
        prefix = f"{where}." if where else ""
        if self.mode == "grid":
            if not self.parameters:
                raise ConfigError(f"{prefix}parameters: a grid sweep needs at least one dotted path with values")
            if self.ranges or self.samples:
                raise ConfigError(f"{prefix}ranges and samples belong to mode 'random', not 'grid'")
            for path, values in self.parameters.items():
                if not values:
                    raise ConfigError(f"{prefix}parameters.{path}: needs at least one value")
        else:
            if not self.ranges:
                raise ConfigError(f"{prefix}ranges: a random sweep needs at least one dotted path with [low, high]")
            if self.parameters:
                raise ConfigError(f"{prefix}parameters belong to mode 'grid'; a random sweep samples 'ranges'")
            if self.samples < 1:
                raise ConfigError(f"{prefix}samples must be >= 1 in a random sweep, got {self.samples}")
            for path, bounds in self.ranges.items():
                if len(bounds) != 2 or not bounds[0] <= bounds[1]:
                    raise ConfigError(f"{prefix}ranges.{path} must be [low, high] with low <= high, got {bounds}")
        if self.seed < 0:
            raise ConfigError(f"{prefix}seed must be a non-negative integer, got {self.seed}")
        for name in self.metrics:
            if name not in METRICS:
                raise ConfigError(f"{prefix}metrics: unknown metric {name!r} (known: {', '.join(METRICS)})")
        if self.base_file is not None and self.base != SimulationConfig():
            raise ConfigError(f"{prefix}base_file and base: give the base config one way, not both")


@dataclass(frozen=True)
class SweepPoint:
    """One simulation of a sweep: its index, seed, the swept values (dotted path -> value) and full config."""

    index: int
    seed: int
    values: dict[str, Any]
    config: SimulationConfig

    def describe(self) -> str:
        return f"point {self.index} ({', '.join(f'{p}={table_cell(v)}' for p, v in self.values.items())})"


@dataclass
class Sweep:
    """A checked sweep: its config (``base`` resolved, ``base_file`` inlined) and every point, in order."""

    config: SweepConfig
    points: list[SweepPoint]
    source: str


def load_sweep(path: str | Path) -> Sweep:
    """Read and check a sweep file; errors name the file, line and key (or the point and its values)."""
    path = Path(path)
    config = load_yaml_dataclass(path, SweepConfig)
    return _resolve(config, path.read_text(), str(path), path.parent)


def resolve_sweep(config: SweepConfig, source: str = "<SweepConfig>", base_dir: str | Path = ".") -> Sweep:
    """Check a sweep built in Python (through the same strict YAML conversion as a file) and list its points."""
    text = dump_yaml_dataclass(config)
    return _resolve(loads_yaml_dataclass(text, SweepConfig, source=source), text, source, Path(base_dir))


def _resolve(config: SweepConfig, text: str, source: str, base_dir: Path) -> Sweep:
    root = yaml.compose(text, Loader=yaml.SafeLoader)
    base = config.base
    if config.base_file is not None:
        try:
            base = load_config(base_dir / config.base_file)
        except ConfigError as err:
            raise ConfigError(f"{source}: base_file: {err}") from None
    if config.mode == "grid":
        axes = {
            path: _typed_values(base, path, key_node, values_node, source)
            for path, key_node, values_node in _entries(root, "parameters", source)
        }
        values = [dict(zip(axes, combination)) for combination in itertools.product(*axes.values())]
    else:
        samplers = {
            path: _sampler(base, path, key_node, config.ranges[path], source)
            for path, key_node, _ in _entries(root, "ranges", source)
        }
        values = []
        for index in range(config.samples):
            rng = np.random.default_rng(np.random.SeedSequence(config.seed, spawn_key=(index, 1)))
            values.append({path: sample(rng) for path, sample in samplers.items()})
    points = [_point(base, index, config.seed, point_values, source) for index, point_values in enumerate(values)]
    return Sweep(dataclasses.replace(config, base=base, base_file=None), points, source)


def _entries(root, key: str, source: str) -> list[tuple[str, Any, Any]]:
    """(dotted path, key node, value node) of the mapping under ``key`` of the sweep file, in file order."""
    for key_node, value_node in root.value:
        if key_node.value == key:
            seen = set()
            for path_node, _ in value_node.value:
                if path_node.value in seen:
                    raise ConfigError(f"{_at(source, path_node)} {key}.{path_node.value}: duplicate path")
                seen.add(path_node.value)
            return [(k.value, k, v) for k, v in value_node.value]
    return []


def _at(source: str, node) -> str:
    return f"{source}:{node.start_mark.line + 1}:"


def _segments(path: str, where: str) -> list[tuple[str, int | None]]:
    """``"controller.lqr.state_weights[0]"`` -> [("controller", None), ("lqr", None), ("state_weights", 0)]."""
    segments = []
    for part in path.split("."):
        match = _SEGMENT.match(part)
        if match is None:
            raise ConfigError(
                f"{where} {path!r} is not a dotted path (fields separated by '.', an optional [index] for a list item)"
            )
        segments.append((match[1], None if match[2] is None else int(match[2])))
    return segments


def _leaf_type(segments: list[tuple[str, int | None]], where: str):
    """The type a dotted path names in the SimulationConfig tree; ConfigError naming an unknown key."""
    tp = SimulationConfig
    for name, index in segments:
        tp = _without_none(tp)
        if not dataclasses.is_dataclass(tp):
            raise ConfigError(f"{where} {name!r} is not a field: its parent is a value ({tp}), not a section")
        hints = typing.get_type_hints(tp)
        known = [f.name for f in dataclasses.fields(tp)]
        if name not in known:
            raise ConfigError(f"{where} unknown key {name!r} in {tp.__name__} (known keys: {', '.join(sorted(known))})")
        tp = hints[name]
        if index is not None:
            tp = _without_none(tp)
            if typing.get_origin(tp) not in (list, tuple):
                raise ConfigError(f"{where} {name!r} is not a list: it has no item [{index}]")
            tp = typing.get_args(tp)[0]
    return tp


def _without_none(tp):
    """X for ``X | None``; other types unchanged."""
    if typing.get_origin(tp) in (typing.Union, types.UnionType):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1:
            return args[0]
    return tp


def _set(obj, segments: list[tuple[str, int | None]], value, done: str = ""):
    """A copy of the dataclass tree ``obj`` with the field at ``segments`` set to ``value``."""
    if not segments:
        return value
    if obj is None:
        raise ConfigError(f"{done} is null in the base config: give it a value there to sweep its fields")
    (name, index), rest = segments[0], segments[1:]
    where = f"{done}.{name}" if done else name
    child = getattr(obj, name)
    if index is None:
        return dataclasses.replace(obj, **{name: _set(child, rest, value, where)})
    if child is None or index >= len(child):
        size = 0 if child is None else len(child)
        raise ConfigError(f"{where}[{index}]: index out of range, the base config's {where} has {size} items")
    items = list(child)
    items[index] = _set(items[index], rest, value, f"{where}[{index}]")
    return dataclasses.replace(obj, **{name: type(child)(items)})


def _typed_values(base: SimulationConfig, path: str, key_node, values_node, source: str) -> list:
    """The grid values of ``path``, converted to its field's type by the strict YAML loader."""
    where = f"{_at(source, key_node)} parameters.{path}:"
    segments = _segments(path, where)
    tp = _leaf_type(segments, where)
    values = [convert_node(node, tp, source, f"parameters.{path}[{i}]") for i, node in enumerate(values_node.value)]
    try:
        _set(base, segments, values[0])
    except ConfigError as err:
        raise ConfigError(f"{where} {err}") from None
    return values


def _sampler(base: SimulationConfig, path: str, key_node, bounds: list[float], source: str):
    """A function drawing a value of ``path`` uniformly in [low, high] (integers for an integer field)."""
    where = f"{_at(source, key_node)} ranges.{path}:"
    segments = _segments(path, where)
    tp = _without_none(_leaf_type(segments, where))
    low, high = bounds
    try:
        _set(base, segments, low)
    except ConfigError as err:
        raise ConfigError(f"{where} {err}") from None
    if tp is float:
        return lambda rng: float(rng.uniform(low, high))
    if tp is int:
        if not (low.is_integer() and high.is_integer()):
            raise ConfigError(f"{where} {path} is an integer field: give integer bounds, got [{low}, {high}]")
        return lambda rng: int(rng.integers(int(low), int(high), endpoint=True))
    raise ConfigError(f"{where} random mode draws numbers, but {path} is of type {tp}; sweep it on a grid")


def _point(base: SimulationConfig, index: int, sweep_seed: int, values: dict, source: str) -> SweepPoint:
    seed = int(np.random.SeedSequence(sweep_seed, spawn_key=(index, 0)).generate_state(1)[0])
    config = base
    for path in SEED_PATHS:
        if path not in values:
            config = _set(config, _segments(path, ""), seed)
    for path, value in values.items():
        config = _set(config, _segments(path, ""), value)
    point = SweepPoint(index, seed, values, config)
    try:
        config.validate()
    except ConfigError as err:
        raise ConfigError(f"{source}: {point.describe()}: {err}") from None
    return point


def run_point(point: SweepPoint) -> dict:
    """Simulate one point (on a Dask worker): its metrics, or the time and cause of its divergence.

    A ConfigError the diagram raises (e.g. a gain that does not stabilise the upright) names the point."""
    try:
        result = simulate(point.config)
    except SimulationDiverged as err:
        return {"metrics": {}, "diverged": True, "diverged_time": err.time, "cause": err.cause}
    except ConfigError as err:
        raise ConfigError(f"{point.describe()}: {err}") from None
    metrics = {}
    for key, value in summary(result, point.config).items():
        if isinstance(value, dict):
            metrics.update({f"{key}_{part}": v for part, v in value.items()})
        elif isinstance(value, float):
            metrics[key] = value
    return {"metrics": metrics, "diverged": False, "diverged_time": None, "cause": ""}


@contextmanager
def dask_client(scheduler: str | None = None, workers: int | None = None, tasks: int | None = None):
    """A Dask client: of the cluster whose scheduler is at ``scheduler``, or of a LocalCluster of ``workers``
    single-threaded processes (default: one per core, at most one per task), closed on exit."""
    if scheduler is not None:
        if workers is not None:
            raise ConfigError(
                "workers (--workers) sizes a local cluster; with a scheduler (--scheduler) the "
                "cluster's own workers run the sweep"
            )
        try:
            client = Client(scheduler, timeout=10)
        except (OSError, ValueError) as err:
            raise ConfigError(f"cannot connect to the Dask scheduler at {scheduler!r}: {err}") from None
        with client:
            yield client
        return
    if workers is not None and workers < 1:
        raise ConfigError(f"workers (--workers) must be >= 1, got {workers}")
    cores = os.cpu_count() or 1
    count = workers or max(1, min(cores, tasks or cores))
    with (
        LocalCluster(
            n_workers=count, threads_per_worker=1, processes=True, dashboard_address=":0", silence_logs=logging.CRITICAL
        ) as cluster,
        Client(cluster) as client,
    ):
        yield client


def map_on_dask(
    client: Client, function: Callable, items: list, progress: Callable[[int, int], None] | None = None
) -> list:
    """``[function(item) for item in items]`` computed on ``client``'s workers, in the order of ``items``;
    ``progress(done, total)`` after each completion. The first exception a call raises cancels the others and
    propagates."""
    futures = client.map(function, items, pure=False)
    position = {future.key: i for i, future in enumerate(futures)}
    results = [None] * len(items)
    try:
        for done, future in enumerate(as_completed(futures), start=1):
            results[position[future.key]] = future.result()
            if progress is not None:
                progress(done, len(items))
    finally:
        client.cancel(futures)
    return results


def run_sweep(
    sweep: Sweep | SweepConfig,
    out_dir: str | Path,
    *,
    force: bool = False,
    scheduler: str | None = None,
    workers: int | None = None,
    progress: Callable[[int, int], None] | None = None,
) -> list[dict]:
    """Run every point of ``sweep`` on Dask and write ``out_dir`` atomically: ``results.csv`` (one row per point
    in index order: ``point``, ``point_seed``, the swept values, the metrics, ``diverged``, ``diverged_time``
    [s], ``cause``), ``sweep.yaml`` (the resolved sweep, loadable again) and one plot of the metrics against
    each swept parameter. Returns the rows."""
    if isinstance(sweep, SweepConfig):
        sweep = resolve_sweep(sweep)
    prepare_output_dir(out_dir, force)
    with dask_client(scheduler, workers, len(sweep.points)) as client:
        try:
            outcomes = map_on_dask(client, run_point, sweep.points, progress)
        except ConfigError as err:
            raise ConfigError(f"{sweep.source}: {err}") from None
    metric_columns = _metric_columns(sweep.config.metrics, outcomes)
    rows = [
        {
            "point": point.index,
            "point_seed": point.seed,
            **point.values,
            **{name: outcome["metrics"].get(name) for name in metric_columns},
            "diverged": outcome["diverged"],
            "diverged_time": outcome["diverged_time"],
            "cause": outcome["cause"],
        }
        for point, outcome in zip(sweep.points, outcomes)
    ]
    with atomic_output_dir(out_dir, force) as out:
        write_table_csv(rows, out / "results.csv")
        (out / "sweep.yaml").write_text(config_yaml_with_provenance(sweep.config))
        for parameter in sweep.points[0].values:
            plot_metrics_vs_parameter(
                rows,
                parameter,
                metric_columns,
                out / f"metrics_vs_{re.sub(r'[^A-Za-z0-9]+', '_', parameter).strip('_')}.png",
            )
    return rows


def _metric_columns(metrics: list[str], outcomes: list[dict]) -> list[str]:
    """The metric columns in the order of ``metrics``; ``velocity_mse`` expands to the theta_dot and phi_dot
    errors of every observer that ran in some point, sorted by observer name."""
    suffix = "_velocity_mse_theta_dot"
    observers = sorted(
        {key[: -len(suffix)] for outcome in outcomes for key in outcome["metrics"] if key.endswith(suffix)}
    )
    columns = []
    for name in metrics:
        if name == VELOCITY_MSE:
            columns += [
                f"{observer}_velocity_mse_{part}" for observer in observers for part in ("theta_dot", "phi_dot")
            ]
        else:
            columns.append(name)
    return columns


def _metric_label(name: str) -> str:
    observer_error = re.fullmatch(r"(\w+)_velocity_mse_(theta|phi)_dot", name)
    if observer_error:
        return rf"{observer_error[1].upper()} $\dot\{observer_error[2]}$ MSE [rad$^2$/s$^2$]"
    return METRIC_LABELS[name]


def plot_metrics_vs_parameter(
    rows: list[dict], parameter: str, metric_columns: list[str], path: str | Path | None = None
):
    """Each metric (and the diverged flag) against one swept parameter, one marker per point; a parameter
    whose values are not all numbers is shown by category. Returns the Figure (saved and closed with a path)."""
    names = [*metric_columns, "diverged"]
    fig, axes = plt.subplots(len(names), 1, figsize=(7, 1.9 * len(names) + 0.8), sharex=True, squeeze=False)
    raw = [row[parameter] for row in rows]
    if all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in raw):
        x = np.array(raw, dtype=float)
    else:
        categories = list(dict.fromkeys(table_cell(v) for v in raw))
        x = np.array([categories.index(table_cell(v)) for v in raw], dtype=float)
        axes[-1, 0].set_xticks(range(len(categories)), categories, rotation=20, fontsize=8)
    for ax, name in zip(axes[:, 0], names):
        y = np.array([math.nan if row[name] is None else float(row[name]) for row in rows])
        ax.plot(x, y, "o", ms=4, color="tab:red" if name == "diverged" else "tab:blue")
        finite = y[np.isfinite(y)]
        if name != "diverged" and finite.size and finite.min() > 0 and finite.max() > 100 * finite.min():
            ax.set_yscale("log")
        ax.set_ylabel(_metric_label(name), fontsize=8)
        ax.grid(alpha=0.3)
    axes[-1, 0].set_xlabel(parameter)
    fig.tight_layout()
    if path is None:
        return fig
    fig.savefig(path, dpi=100)
    plt.close(fig)
    return fig
