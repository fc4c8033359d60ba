"""Would a log's velocity columns (the controller's own estimates) help the diagnosis's window start states?

Each window's start state is first read from the angles by a Savitzky-Golay smoother and then refined per model by
Levenberg-Marquardt steps on the window's residuals (:mod:`furuta_drake.diagnosis.gap.metric`). A logged velocity could
only replace the smoother's first guess. This measures what it would change, on the low-rate benchmark's
recordings (:mod:`benchmarks.diagnosis.low_rate`: open loop from hanging, +-7 V bang-bang, 2048 counts; two 8 s
runs to fit, one held out) at 125 Hz and 1 kHz, both rigs, with the window start velocities taken from:

- ``smoothed``: the Savitzky-Golay derivative (what the diagnosis uses);
- ``true``: the simulator's state (the best any log could hold);
- ``filtered W``: a controller's estimate, the backward difference of the encoder angle through a first-order
  low-pass of cutoff W rad/s (50 rad/s is the QUBE courseware's; its lag is 1 / W);
- garbage: the 300 rad/s estimate at twice its scale (a units slip), or 20 ms late.

Printed per rig, rate and source: the RMS error of the start velocities against the truth before and after the
refinement [rad/s], the gap of the nominal model on the null case (the nominal model is the truth there, so every
count above 0 is start-state error), and on the arm-Coulomb-friction case (level 2) the fitted Coulomb level's
error against the injected one and the fit's held-out reduction. Sources that give the same refined states, gaps,
parameters and reductions as ``smoothed`` leave the diagnosis unchanged.

Run from the repository root: ``PYTHONPATH=. nice -n 10 python benchmarks/diagnosis/log_velocities.py [--rigs
qube_servo2 lund] [--rates 125Hz 1kHz]``.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np
from scipy.signal import lfilter

from benchmarks.diagnosis.low_rate import RATES, lab_rig, run_config
from benchmarks.diagnosis.suite import CaseSpec, true_params
from furuta_drake.diagnosis.gap.metric import Windows, evaluate_gap, make_windows
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.diagnosis.selection.fit import FitTask, fit_task
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects.surrogate import Model
from furuta_drake.rig import RIGS
from furuta_drake.simulate import simulate

SEEDS = {"train": (1, 2), "heldout": (501,)}  # command seeds of the runs
DURATION_S = 8.0


def filtered_difference(angle: np.ndarray, period: float, cutoff: float) -> np.ndarray:
    """A controller's velocity estimate [rad/s]: the backward difference through a first-order low-pass of
    ``cutoff`` [rad/s] (its pole exact at the sample ``period``)."""
    difference = np.concatenate([[0.0], np.diff(angle) / period])
    pole = np.exp(-cutoff * period)
    return lfilter([1.0 - pole], [1.0, -pole], difference)


def sources(state: np.ndarray, measured: np.ndarray, period: float) -> dict[str, np.ndarray]:
    """Per source, the (n, 2) velocities [theta_dot, phi_dot] a log could hold."""
    out = {"true": state[:, 2:4]}
    for cutoff in (50.0, 300.0):
        out[f"filtered {cutoff:.0f}"] = np.column_stack(
            [filtered_difference(measured[:, i], period, cutoff) for i in (0, 1)]
        )
    fast = out["filtered 300"]
    lag = max(1, int(round(0.02 / period)))
    out["x2 scale"] = 2.0 * fast
    out["20 ms late"] = np.vstack([np.repeat(fast[:1], lag, axis=0), fast[:-lag]])
    return out


def recorded(rig_name: str, effects: tuple[str, ...], period: float, seeds: tuple[int, ...]):
    """The runs of the case as logs, with their per-source velocities and true velocities."""
    rig = lab_rig(rig_name, period)
    logs, velocities = [], []
    for seed in seeds:
        result = simulate(run_config(rig, CaseSpec(rig_name, effects, 2, 1), seed, DURATION_S))
        measured = result.measured
        logs.append(
            RunLog(f"run_{seed}", "", result.time, measured[:, 0], measured[:, 1], "torque", result.torque, period)
        )
        velocities.append(sources(result.state, measured, period))
    return rig, logs, velocities


def with_starts(windows: Windows, velocities: list[dict], source: str) -> Windows:
    """``windows`` with their start velocities read from ``source`` (``smoothed``: as cut)."""
    if source == "smoothed":
        return windows
    states = [np.vstack([x[:2], v[source][s].T]) for x, v, s in zip(windows.initial_states, velocities, windows.starts)]
    return dataclasses.replace(windows, initial_states=states)


def velocity_error(states: list[np.ndarray], velocities: list[dict], windows: Windows) -> float:
    errors = [(x[2:4] - v["true"][s].T).ravel() for x, v, s in zip(states, velocities, windows.starts)]
    return float(np.sqrt(np.mean(np.concatenate(errors) ** 2)))


def null_row(rig_name: str, period: float, source: str, case) -> dict:
    rig, logs, velocities = case
    windows = with_starts(make_windows(logs, rig), velocities, source)
    gap = evaluate_gap(Model.from_rig(rig), windows, rig.counts_per_rev)
    return {
        "start_error": velocity_error(windows.initial_states, velocities, windows),
        "refined_error": velocity_error(gap.initial_states, velocities, windows),
        "null_gap": gap.gap,
    }


def friction_row(rig_name: str, source: str, train, heldout) -> dict:
    rig, logs, velocities = train
    _, held_logs, held_velocities = heldout
    windows = with_starts(make_windows(logs, rig), velocities, source)
    held = with_starts(make_windows(held_logs, rig), held_velocities, source)
    nominal = Model.from_rig(rig)
    task = FitTask("arm_coulomb_friction", {}, nominal, windows, held, tuple(logs), rig.counts_per_rev, SETTINGS)
    fit = fit_task(task)
    truth = true_params(RIGS[rig_name](), "arm_coulomb_friction", 2)["coulomb"]
    before = evaluate_gap(nominal, held, rig.counts_per_rev).gap
    return {
        "coulomb_error": fit.effects["arm_coulomb_friction"].values[0] / truth - 1.0,
        "reduction": 1.0 - fit.heldout.gap / before,
    }


SETTINGS = DiagnosisSettings(interval_resamples=20)  # the fit as the diagnosis runs it; few interval resamples


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rigs", nargs="+", default=["qube_servo2", "lund"], choices=list(RIGS))
    parser.add_argument("--rates", nargs="+", default=["125Hz", "1kHz"], choices=list(RATES))
    args = parser.parse_args(argv)
    print(
        f"{'rig':<12} {'rate':<6} {'start velocities':<16} {'start err':>9} {'refined':>8} {'null gap':>8} "
        f"{'Fc error':>8} {'reduction':>9}"
    )
    names = ["smoothed", "true", "filtered 50", "filtered 300", "x2 scale", "20 ms late"]
    for rig_name in args.rigs:
        for rate in args.rates:
            period = RATES[rate]
            null = recorded(rig_name, (), period, SEEDS["train"])
            train = recorded(rig_name, ("arm_coulomb_friction",), period, SEEDS["train"])
            heldout = recorded(rig_name, ("arm_coulomb_friction",), period, SEEDS["heldout"])
            for source in names:
                row = {**null_row(rig_name, period, source, null), **friction_row(rig_name, source, train, heldout)}
                print(
                    f"{rig_name:<12} {rate:<6} {source:<16} {row['start_error']:>9.3f} {row['refined_error']:>8.3f} "
                    f"{row['null_gap']:>8.4f} {row['coulomb_error']:>+8.1%} {row['reduction']:>9.1%}",
                    flush=True,
                )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
