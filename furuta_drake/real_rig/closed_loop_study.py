"""Study: the closed loop, real against simulated. The real QUBE swing-ups were recorded under Quanser's swing-up
and balance controller (:mod:`furuta_drake.controllers.quanser_swingup`); this study checks the controller against
the logs (fed the logged angles and velocities, does it give back the logged voltage?), then runs the same
experiment in simulation on the nominal model and on the model the diagnosis corrected (same initial state, same
250 Hz sampling, the 4 V clip, 2048-count encoders, the velocity filter of the rig's server) and compares the
runs side by side.

Velocities for the check. The paper's zero-phase Butterworth reference (:func:`furuta_drake.real_rig.runs.
reference_velocity`) is one; the causal filtered derivative of the rig's server (:mod:`furuta_drake.observers.
filtered_derivative`), with its corner fitted on the train swing-up's balancing voltage
(:func:`fit_velocity_corner`), is the other, and the one the simulations use.

Figures of a swing-up run (:func:`closed_loop_figures`), read the same way from a real log and a simulation:
``catch_time`` (the last hand-over to the PD law, :func:`~furuta_drake.controllers.swingup.catch_time`),
``peak_arm_angle`` (max |phi| before it), and over the balancing window (``SETTLE`` after the catch to the end)
the RMS of the wrapped theta and of phi about zero (the controller's set point), the RMS voltage, the balancing
limit cycle: the strongest peak of the Welch spectrum of theta above ``LIMIT_CYCLE_MIN_HZ`` (the arm's slow drift
lies below it) and the amplitude of the sinusoid holding the spectrum's power within half an octave of it, and
the means of theta and phi (where the loop balances, which the RMS about zero includes).

The gap table (:func:`gap_table`) averages over the runs that balance quietly; the run that balances in a
saturated oscillation is compared on its own. Where the corrected model still misses, :func:`balancing_diagnosis`
runs the diagnosis on the balancing part of the runs, from the corrected model.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar
from scipy.signal import welch

from furuta_drake.config import SimulationConfig, quanser_swingup_config
from furuta_drake.controllers.quanser_swingup import QuanserSwingUpParameters, quanser_command
from furuta_drake.controllers.swingup import catch_time, wrap_angle
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.observers.filtered_derivative import FilteredDerivativeParameters, filtered_derivative
from furuta_drake.paper import reproduce
from furuta_drake.real_rig.runs import (
    OSCILLATING_SWINGUP,
    SWINGUPS,
    TRAIN_SWINGUP,
    RealRuns,
    balancing_samples,
    catch_index,
    log_result,
    reference_velocity,
    run_diagnosis,
    voltage_of,
    write_segment,
)
from furuta_drake.simulate import SimulationResult, simulate
from furuta_drake.yamlio import dump_yaml_dataclass

LIMIT_CYCLE_MIN_HZ = 3.0  # [Hz] the balancing limit cycle is looked for above this
FIGURES = (
    "catch_time",
    "peak_arm_angle",
    "theta_rms",
    "phi_rms",
    "voltage_rms",
    "limit_cycle_hz",
    "limit_cycle_amplitude",
    "theta_mean",
    "phi_mean",
)
CORNER_BOUNDS = (5.0, 400.0)  # [rad/s] the search interval of the velocity filter's corner
SPREAD_COUNTS = (-2, -1, 1, 2)  # [counts] the simulated catch time is also read from starts this far off


def fit_velocity_corner(log: RunLog, params: QuanserSwingUpParameters) -> float:
    """The corner wc [rad/s] of the server's filtered derivative that best gives back ``log``'s balancing voltage
    through the controller (least RMS error over the samples where the PD law runs, bounded search)."""
    angles = np.column_stack([log.theta, log.phi])
    upper = min(CORNER_BOUNDS[1], 1.99 / log.sample_period)

    def error(corner: float) -> float:
        voltage, mode, _ = quanser_command(
            params, np.column_stack([angles, filtered_derivative(angles, log.sample_period, corner)])
        )
        balance = mode == 1
        return float(np.sqrt(np.mean((voltage[balance] - log.input[balance]) ** 2)))

    return float(minimize_scalar(error, bounds=(CORNER_BOUNDS[0], upper), method="bounded", options={"xatol": 1e-3}).x)


def rest_direction(log: RunLog, params: QuanserSwingUpParameters) -> int:
    """The first kick's direction of a real run: the ``rest_direction`` whose command at the first sample (at
    rest) is nearest the logged voltage."""
    state = [log.theta[0], log.phi[0], 0.0, 0.0]
    errors = {
        s: abs(float(quanser_command(dataclasses.replace(params, rest_direction=s), state)[0]) - log.input[0])
        for s in (1, -1)
    }
    return min(errors, key=errors.get)


def controller_fit(log: RunLog, params: QuanserSwingUpParameters, corner: float) -> dict:
    """The controller fed ``log``'s angles with the reference velocities and with the server's filtered
    derivative, against the logged voltage [V]: ``voltage_rms`` of the log, ``voltage_rmse`` with the reference
    velocities, ``voltage_rmse_server_filter`` with the filtered derivative, and both errors per mode
    (``swing``, ``balance``)."""
    params = dataclasses.replace(params, rest_direction=rest_direction(log, params))
    angles = np.column_stack([log.theta, log.phi])
    sources = {
        "voltage_rmse": reference_velocity(log),
        "voltage_rmse_server_filter": filtered_derivative(angles, log.sample_period, corner),
    }
    out = {"voltage_rms": _rms(log.input), "samples": int(log.time.size)}
    for key, velocity in sources.items():
        voltage, mode, _ = quanser_command(params, np.column_stack([angles, velocity]))
        error = voltage - log.input
        out[key] = _rms(error)
        for name, mask in (("swing", mode == 0), ("balance", mode == 1)):
            out.setdefault(name, {"samples": int(mask.sum()), "voltage_rms": _rms(log.input[mask])})[key] = _rms(
                error[mask]
            )
    return out


def _rms(values: np.ndarray) -> float:
    return float(np.sqrt(np.mean(np.square(values)))) if np.size(values) else float("nan")


def run_config(
    model: SimulationConfig, log: RunLog, params: QuanserSwingUpParameters, corner: float
) -> SimulationConfig:
    """The real run's experiment on ``model``: its first sample's angles at rest, its length, its first kick's
    direction, the server's velocity filter at ``corner``."""
    return quanser_swingup_config(
        model,
        initial_state=[log.theta[0], log.phi[0], 0.0, 0.0],
        duration=float(log.time[-1] - log.time[0] + log.sample_period),
        params=dataclasses.replace(params, rest_direction=rest_direction(log, params)),
        velocity_filter=FilteredDerivativeParameters(corner=corner),
    )


def closed_loop_figures(result: SimulationResult, voltage: np.ndarray) -> dict:
    """The figures of a swing-up run (module docstring) from its tape (encoder angles, ``swingup_mode``) and its
    ``voltage`` [V]; NaN for what a run that never caught does not have."""
    figures = dict.fromkeys(FIGURES, float("nan"))
    theta, phi = result.measured[:, 0], result.measured[:, 1]
    k = catch_index(result)
    if k is None:
        figures["peak_arm_angle"] = float(np.max(np.abs(phi)))
        return figures
    figures["catch_time"] = float(catch_time(result))
    figures["peak_arm_angle"] = float(np.max(np.abs(phi[: k + 1])))
    window = balancing_samples(result)
    if window is None:
        return figures
    balance = wrap_angle(theta[window])
    period = float(result.time[1] - result.time[0])
    figures.update(
        theta_rms=_rms(balance),
        phi_rms=_rms(phi[window]),
        voltage_rms=_rms(voltage[window]),
        theta_mean=float(np.mean(balance)),
        phi_mean=float(np.mean(phi[window])),
    )
    frequency, amplitude = limit_cycle(balance, period)
    figures.update(limit_cycle_hz=frequency, limit_cycle_amplitude=amplitude)
    return figures


def spectrum(theta: np.ndarray, period: float) -> tuple[np.ndarray, np.ndarray]:
    """(frequency [Hz], power [rad^2/Hz]): the Welch spectrum of a balancing pendulum angle sampled at ``period``
    [s], 1 s segments, linear detrend."""
    return welch(theta, fs=1.0 / period, nperseg=min(theta.size, int(round(1.0 / period))), detrend="linear")


def balancing_spectrum(result: SimulationResult) -> tuple[np.ndarray, np.ndarray] | None:
    """:func:`spectrum` of a run's wrapped pendulum angle over its balancing window (None without one)."""
    window = balancing_samples(result)
    if window is None:
        return None
    return spectrum(wrap_angle(result.measured[window, 0]), float(result.time[1] - result.time[0]))


def limit_cycle(theta: np.ndarray, period: float) -> tuple[float, float]:
    """(frequency [Hz], amplitude [rad]) of the strongest oscillation of ``theta`` above ``LIMIT_CYCLE_MIN_HZ``:
    the Welch spectrum's peak (1 s segments, linear detrend) and the amplitude sqrt(2 P) of the power P within half
    an octave of it."""
    frequency, power = spectrum(theta, period)
    above = frequency >= LIMIT_CYCLE_MIN_HZ
    if not above.any():
        return float("nan"), float("nan")
    peak = frequency[above][np.argmax(power[above])]
    band = (frequency > peak / math.sqrt(2.0)) & (frequency < peak * math.sqrt(2.0))
    return float(peak), float(math.sqrt(2.0 * np.sum(power[band]) * (frequency[1] - frequency[0])))


@dataclass
class ClosedLoopStudy:
    """``rows``: real_closed_loop.csv (one row per log and source: real, then ``sim_{model}`` per model);
    ``controller_fit``: controller_fit.json; ``gap``: per figure, the mean over the runs of |sim - real| per model
    and the share each correction closed (:func:`gap_table`); ``runs``: {(source, log): (tape, voltage)};
    ``configs``: {(source, log): the simulate config of each simulated run}; ``corner``: the fitted velocity
    filter corner [rad/s]."""

    rows: list[dict]
    controller_fit: dict
    gap: list[dict]
    runs: dict = field(default_factory=dict)
    configs: dict = field(default_factory=dict)
    corner: float = float("nan")
    models: list[str] = field(default_factory=list)

    def add_model(
        self,
        runs: RealRuns,
        name: str,
        model: SimulationConfig,
        params: QuanserSwingUpParameters,
        spread: bool = True,
        progress=None,
    ) -> None:
        """Simulate every run on one more model (``sim_{name}`` rows) and recompute the gap table."""
        logs = list(dict.fromkeys(row["log"] for row in self.rows))
        rows, taped, configs = closed_loop_rows(
            runs, {name: model}, params, self.corner, logs, spread=spread, with_real=False, progress=progress
        )
        order = {log: k for k, log in enumerate(logs)}
        self.rows = sorted(self.rows + rows, key=lambda row: order[row["log"]])
        self.runs.update(taped)
        self.configs.update(configs)
        self.models.append(name)
        self.gap = gap_table(self.rows, self.models)


def fit_controller(runs: RealRuns, params: QuanserSwingUpParameters) -> tuple[float, dict]:
    """(corner, controller_fit.json): the velocity filter's corner fitted on the train swing-up, then the
    controller's fit (:func:`controller_fit`) on every swing-up."""
    corner = fit_velocity_corner(runs.logs[TRAIN_SWINGUP], params)
    return corner, {
        "velocity_filter_corner": corner,
        "logs": {
            name: {"part": runs.part(name), **controller_fit(runs.logs[name], params, corner)}
            for name in SWINGUPS
            if name in runs.logs
        },
    }


def closed_loop_rows(
    runs: RealRuns,
    models: dict[str, SimulationConfig],
    params: QuanserSwingUpParameters,
    corner: float,
    logs,
    *,
    spread: bool = True,
    with_real: bool = True,
    progress=None,
):
    """The rows of every run of ``logs`` (real first when ``with_real``, then simulated on each model), with the
    simulated catch time's range over starts ``SPREAD_COUNTS`` encoder counts off the logged pendulum angle
    (``catch_time_min``, ``catch_time_max``; the real run's own catch time for both, and for a simulation without
    ``spread``). Returns (rows, {(source, log): (tape, voltage)}, {(source, log): config})."""
    rows, taped, configs = [], {}, {}
    for name in logs:
        log = runs.logs[name]
        if with_real:
            real = log_result(log, params)
            taped[("real", name)] = (real, log.input)
            figures = closed_loop_figures(real, log.input)
            rows.append(
                {
                    "log": name,
                    "part": runs.part(name),
                    "source": "real",
                    **figures,
                    "catch_time_min": figures["catch_time"],
                    "catch_time_max": figures["catch_time"],
                }
            )
        for model_name, model in models.items():
            config = run_config(model, log, params, corner)
            result = simulate(config)
            source = f"sim_{model_name}"
            configs[(source, name)], taped[(source, name)] = config, (result, voltage_of(result, runs.rig))
            figures = closed_loop_figures(result, voltage_of(result, runs.rig))
            catches = [figures["catch_time"]]
            if spread:
                count = runs.rig.encoder_resolution
                for offset in SPREAD_COUNTS:
                    start = [config.initial_state[0] + offset * count, *config.initial_state[1:]]
                    catches.append(catch_time(simulate(dataclasses.replace(config, initial_state=start))))
            rows.append(
                {
                    "log": name,
                    "part": runs.part(name),
                    "source": source,
                    **figures,
                    "catch_time_min": float(np.min(catches)),
                    "catch_time_max": float(np.max(catches)),
                }
            )
            reproduce.report_progress(progress, f"closed loop: {name} on the {model_name} model")
    return rows, taped, configs


def study(
    runs: RealRuns,
    models: dict[str, SimulationConfig],
    params: QuanserSwingUpParameters | None = None,
    logs=SWINGUPS,
    spread: bool = True,
    progress=None,
) -> ClosedLoopStudy:
    """The controller's fit on every swing-up, then each run of ``logs`` real and simulated on every model of
    ``models`` (e.g. {'nominal': config, 'fitted': config}; 'nominal' is the reference of the gap table)."""
    params = params or QuanserSwingUpParameters()
    corner, fit = fit_controller(runs, params)
    rows, taped, configs = closed_loop_rows(
        runs, models, params, corner, [name for name in logs if name in runs.logs], spread=spread, progress=progress
    )
    return ClosedLoopStudy(rows, fit, gap_table(rows, list(models)), taped, configs, corner, list(models))


def gap_table(rows: list[dict], models: list[str]) -> list[dict]:
    """Per figure, over the runs that balance quietly (every part but 'oscillating'): the real mean, each model's
    mean |sim - real| (``gap_{model}``, over the runs where both are finite, counted in ``runs_{model}``), and for
    every model but 'nominal' ``closed_{model}``, 1 - gap_model / gap_nominal: the share of the nominal model's gap
    that model closed."""
    table = []
    logs = list(dict.fromkeys(row["log"] for row in rows if row["part"] != "oscillating"))
    by = {(row["source"], row["log"]): row for row in rows}
    for figure in FIGURES:
        entry = {"figure": figure, "real": float(np.nanmean([by[("real", log)][figure] for log in logs]))}
        for model in models:
            gaps = [abs(by[(f"sim_{model}", log)][figure] - by[("real", log)][figure]) for log in logs]
            gaps = [g for g in gaps if math.isfinite(g)]
            entry[f"gap_{model}"] = float(np.mean(gaps)) if gaps else float("nan")
            entry[f"runs_{model}"] = len(gaps)
        for model in models:
            if model != "nominal" and "nominal" in models:
                nominal = entry["gap_nominal"]
                entry[f"closed_{model}"] = 1.0 - entry[f"gap_{model}"] / nominal if nominal > 0 else float("nan")
        table.append(entry)
    return table


def balancing_diagnosis(runs: RealRuns, corrected_rig, folder: Path, small: bool = False, progress=None):
    """The diagnosis of the part the corrected model leaves open, the balancing: every swing-up from its catch to
    its end, written into ``folder`` with the corrected rig file (the diagnosis starts from the corrected model),
    fitted on the swing-ups that balance quietly and judged on the one that balances in a saturated
    oscillation. Returns (Diagnosis, train paths, held-out paths)."""
    folder.mkdir(parents=True, exist_ok=True)
    rig_path = folder / "corrected_rig.yaml"
    rig_path.write_text(dump_yaml_dataclass(corrected_rig))
    paths = {}
    for name in SWINGUPS:
        log = runs.logs[name]
        catch = catch_index(log_result(log))
        paths[name] = write_segment(folder / f"balance_{name}", log, slice(catch, None), runs.rig)
    train = [paths[name] for name in SWINGUPS if name != OSCILLATING_SWINGUP]
    heldout = [paths[OSCILLATING_SWINGUP]]
    return run_diagnosis(rig_path, train, heldout, small, progress), train, heldout


__all__ = [
    "LIMIT_CYCLE_MIN_HZ",
    "FIGURES",
    "SPREAD_COUNTS",
    "fit_velocity_corner",
    "rest_direction",
    "controller_fit",
    "run_config",
    "closed_loop_figures",
    "spectrum",
    "balancing_spectrum",
    "limit_cycle",
    "ClosedLoopStudy",
    "fit_controller",
    "closed_loop_rows",
    "study",
    "gap_table",
    "balancing_diagnosis",
]
