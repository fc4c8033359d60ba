"""Coverage of the 95 % parameter intervals of one accepted effect, at the fit level, on the suite's true-world
realisations in Drake (benchmarks/diagnosis/suite.py): for each case a rig, an accepted effect A at the suite's level
and, in half of them, a small second effect below its detection limit (an input delay or an actuator lag of
``HIDDEN_SECONDS``). A is fitted alone on the case's train runs (the suite's balancing and hanging runs); its
bootstrap intervals are the *own* ones; the rival is the joint fit of A and the not-accepted candidate of
``RIVALS`` that leaves the least train cost, and its move d of each parameter widens [lo, hi] to
[min(lo, lo + d), max(hi, hi + d)]. Then both are inflated about the fitted value by each factor of
``INFLATIONS``; the table gives each method's coverage over the known parameters, with its binomial standard
error sqrt(p (1 - p) / n). As the report does, A is then fitted again on every train window from its fit
(:func:`~furuta_drake.diagnosis.selection.final_fit.every_window_tasks`, when the logs hold more windows than a fit
draws) and the refit's value and own interval are checked, the rival's move still measured from the fit on the drawn
windows; the tables are given for the refit (the report's) and for the drawn windows' fit.

``PYTHONPATH=. python benchmarks/diagnosis/interval_coverage_fits.py [--seeds 1 2] [--duration 3]``
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import benchmarks.diagnosis.independent as ind
from benchmarks.diagnosis.suite import run_configs, true_params, with_effect
from furuta_drake.diagnosis.gap.metric import make_windows
from furuta_drake.diagnosis.logs.load import RunLog, load_logs
from furuta_drake.diagnosis.selection.final_fit import every_window_tasks, refit
from furuta_drake.diagnosis.selection.fit import FitTask, fit_task, interval
from furuta_drake.diagnosis.selection.rival import inflated
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import CANDIDATES
from furuta_drake.rig import RIGS
from furuta_drake.rig_file import load_rig
from furuta_drake.simulate import simulate

ACCEPTED = ("torque_gain_error", "arm_viscous_friction", "arm_coulomb_friction", "inertia_mismatch")
CHECKED = {"arm_coulomb_friction": ("coulomb",)}  # the parameters checked (default: every one the truth states)
sim = ind.sim  # the independent simulator, as the suite that builds its cases imports it
HIDDEN_SECONDS = 0.0015  # a delay or a lag of 1.5 ms: below the detection limits of these logs
RIVALS = ("input_delay", "actuator_lag", "arm_viscous_friction", "torque_gain_error")
INFLATIONS = (1.0, 1.5, 2.0, 2.5, 3.0)
SETTINGS = DiagnosisSettings(interval_resamples=200, detection_limits=False)


def _with_hidden(config, hidden: str):
    if hidden == "input_delay":
        return dataclasses.replace(config, actuator=dataclasses.replace(config.actuator, delay=HIDDEN_SECONDS))
    if hidden == "actuator_lag":
        return dataclasses.replace(
            config, actuator=dataclasses.replace(config.actuator, lag_time_constant=HIDDEN_SECONDS)
        )
    return config


def case_rows(label: str, rig, logs: tuple, accepted: str, truth: dict, hidden: bool) -> list[dict]:
    """One row per known parameter (``truth``: name -> value) of ``accepted`` fitted alone on ``logs``: truth,
    fit and own interval (of the refit on every window, and of the fit on the drawn ones) and the rival's move."""
    nominal = Model.from_rig(rig)
    windows = make_windows(list(logs), rig)

    def fit(new: str, fixed: dict):
        return fit_task(FitTask(new, fixed, nominal, windows, None, logs, rig.counts_per_rev, SETTINGS))

    alone = fit(accepted, {})
    rival = min((fit(other, alone.effects) for other in RIVALS if other != accepted), key=lambda j: j.train_gap)
    every = every_window_tasks(alone, nominal, windows, None, logs, rig.counts_per_rev, SETTINGS)
    final = refit(alone, every, lambda function, tasks: [function(task) for task in tasks]) or alone
    effect, moved, refitted = alone.effects[accepted], rival.effects[accepted], final.effects[accepted]
    params = CANDIDATES[accepted].form(effect.form).params
    rows = []
    for i, param in enumerate(params):
        if param not in truth or param not in CHECKED.get(accepted, params):
            continue
        rows.append(
            {
                "case": label,
                "param": param,
                "true": truth[param],
                "fitted": refitted.values[i],
                "own": interval(final.samples[accepted][:, i]),
                "subset": {"fitted": effect.values[i], "own": interval(alone.samples[accepted][:, i])},
                "refitted": final is not alone,
                "shift": moved.values[i] - effect.values[i] if moved.form == effect.form else 0.0,
                "rival": rival.name,
                "hidden": hidden,
            }
        )
    return rows


def suite_cases(rigs, seeds, duration: float):
    """(label, rig, train logs, accepted effect, its truth, hidden?) of the Drake suite's cases."""
    for rig_name in rigs:
        rig = RIGS[rig_name]()
        for seed in seeds:
            for accepted in ACCEPTED:
                for hidden in ("", "input_delay", "actuator_lag"):
                    logs = []
                    for name, config in run_configs(rig, seed, duration).items():
                        result = simulate(_with_hidden(with_effect(config, accepted, 1), hidden))
                        measured = result.measured[:, :2].T
                        period = rig.sample_period
                        logs.append(RunLog(f"{name}.csv", "", result.time, *measured, "torque", result.torque, period))
                    label = f"drake/{rig_name}/{accepted}/{hidden or 'alone'}/s{seed}"
                    yield label, rig, tuple(logs), accepted, true_params(rig, accepted, 1), bool(hidden)


def independent_cases(seeds, duration: float):
    """The same from the independent simulator (benchmarks/independent/simulator.py; its logs already hold the
    one-sample computation delay of a digital controller): each clear effect alone and beside a hidden one-sample
    delay or a 2 ms filter lag, read back through the package's log reader."""
    clear = {
        "torque_gain_error": [("lund", (ind.gain, 0.8)), ("qube", (ind.gain, 1.15))],
        "arm_viscous_friction": [("lund", (ind.arm_viscous, 1.5)), ("qube", (ind.arm_viscous, 0.5))],
        "arm_coulomb_friction": [("lund", (ind.arm_friction, "karnopp", 0.06, {"breakaway": 1.25}))],
        "inertia_mismatch": [("qube", (ind.inertia, {"pendulum_mass": 1.1, "arm_inertia": 1.2}))],
    }
    hidden = {"": (), "delay": ((ind.delay, 1),), "lag": ((ind.lag, "filter", 0.002),)}
    for seed in seeds:
        for accepted, makers in clear.items():
            for rig_name, maker in makers:
                for hidden_name, extra in hidden.items():
                    case = ind.make_case(rig_name, maker, *extra, seed=seed + 10, hidden=len(extra))
                    with tempfile.TemporaryDirectory() as folder:
                        paths = []
                        sim.write_rig_file(case.world.rig, Path(folder) / "rig.yaml")
                        for run in (sim.balance_run(duration, 11 + seed), sim.hanging_run(duration, 12 + seed)):
                            paths.append(Path(folder) / f"{run.kind}.csv")
                            sim.write_log(sim.simulate(case.world, run), paths[-1])
                        rig = load_rig(Path(folder) / "rig.yaml")
                        logs = tuple(load_logs(paths, rig))
                    label = f"independent/{case.name}"
                    yield label, rig, logs, accepted, case.effects[0].params, bool(hidden_name)


def covered(row: dict, inflation: float, with_rival: bool) -> bool:
    low, high = row["own"]
    if with_rival:
        low, high = min(low, low + row["shift"]), max(high, high + row["shift"])
    low, high = inflated(row["fitted"], low, high, row["param"], inflation)
    return low <= row["true"] <= high


def summary(rows: list[dict]) -> None:
    print("| method | inflation | all | no hidden effect | hidden second effect |")
    print("|---|---:|---|---|---|")
    for with_rival in (False, True):
        for k in INFLATIONS:
            cells = []
            for group in (rows, [r for r in rows if not r["hidden"]], [r for r in rows if r["hidden"]]):
                n = len(group)
                p = sum(covered(r, k, with_rival) for r in group) / max(n, 1)
                cells.append(f"{p:.0%} ± {np.sqrt(p * (1 - p) / max(n, 1)):.0%} (n={n})")
            print(f"| {'own + rival shift' if with_rival else 'own'} | {k} | " + " | ".join(cells) + " |")


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1])
    parser.add_argument("--duration", type=float, default=3.0)
    parser.add_argument("--rigs", nargs="+", default=["lund", "qube_servo2"], choices=list(RIGS))
    parser.add_argument("--simulator", choices=("drake", "independent", "both"), default="both")
    args = parser.parse_args(argv)
    sources = []
    if args.simulator in ("drake", "both"):
        sources.append(suite_cases(args.rigs, args.seeds, args.duration))
    if args.simulator in ("independent", "both"):
        sources.append(independent_cases(args.seeds, args.duration))
    print("| case | parameter | true | fitted | 95 % own | drawn windows' fit, own | rival's move | seconds |")
    print("|---|---|---:|---:|---|---|---|---:|")
    rows, start = [], time.time()
    for source in sources:
        for case in source:
            for r in case_rows(*case):
                rows.append(r)
                sub = r["subset"]
                print(
                    f"| {r['case']} | {r['param']} | {r['true']:.4g} | {r['fitted']:.4g} | "
                    f"[{r['own'][0]:.4g}, {r['own'][1]:.4g}] | "
                    + (f"{sub['fitted']:.4g} [{sub['own'][0]:.4g}, {sub['own'][1]:.4g}]" if r["refitted"] else "same")
                    + f" | {r['shift']:+.3g} ({r['rival']}) | "
                    f"{time.time() - start:.0f} |",
                    flush=True,
                )
    print(f"\nThe report's fit (refitted on every train window in {sum(r['refitted'] for r in rows)} of {len(rows)}):")
    summary(rows)
    print("\nThe fit on the drawn fit windows:")
    summary([{**r, **r["subset"]} for r in rows])
    return 0


if __name__ == "__main__":
    sys.exit(main())
