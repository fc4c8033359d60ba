"""``tune`` on the real QUBE-Servo 2 (data/qube-servo2-real): what the tuned design predicts for the balancing limit
cycle, beside the one measured on the rig.

The real runs balance under Quanser's PD law (:mod:`furuta_drake.controllers.quanser_swingup`), not under the LQR,
so the rig cannot check the tuned design itself; what can be set side by side:

1. **measured**: the limit cycle of each real swing-up's balancing part (from 1 s after its catch to its end,
   :func:`furuta_drake.real_rig.runs.balancing_samples`), read as ``tune`` reads its predictions
   (:func:`furuta_drake.tune.limit_cycle.balancing_figures`, on the last half of that part);
2. **Quanser's PD on the corrected model**: each real run's experiment simulated on the model the diagnosis
   corrected (:func:`furuta_drake.real_rig.closed_loop_study.closed_loop_rows`), read the same way: how well the
   corrected model predicts the rig's limit cycle and theta's RMS under the controller that ran on it, on the quiet
   model and with the rig's disturbance the diagnosis read (``disturbance`` of its report, a seeded draw per run);
3. **nominal and tuned LQR on the corrected model**: ``tune.json``'s predictions;
4. **the swing-up's catch time**: measured on each real run (Quanser's PD), Quanser's PD on the corrected model, and
   ``tune``'s prediction for each design's LQR behind the same Quanser swing-up (``tune --swingup``), from the
   train swing-up's start (its first angles at rest, its first kick's direction, the server's velocity filter),
   over 10 s.

The diagnosis is the one the real-rig study runs (the train swing-up and the hanging chirp as train logs, the two
swing-ups of other days held out; the command's default settings), written to ``OUT/diagnosis`` once; ``tune`` is
run on it with its defaults and that swing-up (``OUT/swingup.yaml``) into ``OUT/tune``. Writes
``OUT/results.json`` and prints the table.

Run from the repository root: ``PYTHONPATH=. python benchmarks/tune/real.py --out runs/tune_real``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
from pathlib import Path

import numpy as np

from furuta_drake.config import dump_config
from furuta_drake.controllers.quanser_swingup import QuanserSwingUpParameters
from furuta_drake.controllers.swingup import catch_time
from furuta_drake.data import QUBE_REAL_DIR, QUBE_REAL_RIG
from furuta_drake.diagnosis.pipeline import diagnose
from furuta_drake.diagnosis.report.files import write_report
from furuta_drake.effects.corrected import rig_config
from furuta_drake.errors import FurutaError
from furuta_drake.outputs import versions
from furuta_drake.real_rig.closed_loop_study import closed_loop_rows, fit_velocity_corner, run_config
from furuta_drake.real_rig.runs import (
    CHIRP,
    HELDOUT_SWINGUPS,
    SWINGUPS,
    TRAIN_SWINGUP,
    balancing_samples,
    load_real_runs,
    log_result,
)
from furuta_drake.rig_file import load_rig
from furuta_drake.tune.limit_cycle import balancing_figures
from furuta_drake.tune.output import write_tune
from furuta_drake.tune.pipeline import TuneSettings, tune
from furuta_drake.tune.swingup import read_swingup

FIGURES = ("theta_rms", "limit_cycle_amplitude", "limit_cycle_frequency")
SWINGUP_S = 10.0  # [s] the predicted swing-ups
TUNED_KEYS = ("lqr_gain", "lqr_gain_volts", "observer", "family_member")


def balancing(result, period: float) -> dict:
    """The balancing figures of a swing-up tape (real or simulated) over its balancing part, theta about the
    upright it balances at (a swing-up may end a whole turn away)."""
    window = balancing_samples(result)
    if window is None:
        return dict.fromkeys(FIGURES)
    theta = result.measured[window, 0]
    theta = theta - 2.0 * math.pi * np.round(theta / (2.0 * math.pi))
    return balancing_figures(theta, result.measured[window, 1], result.torque[window], period)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--workers", type=int, default=1, help="processes of the diagnosis and of tune")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    diagnosis = args.out / "diagnosis"
    if not (diagnosis / "report.json").is_file():
        train = [QUBE_REAL_DIR / TRAIN_SWINGUP, QUBE_REAL_DIR / CHIRP]
        heldout = [QUBE_REAL_DIR / name for name in HELDOUT_SWINGUPS]
        result = diagnose(rig=QUBE_REAL_RIG, train=train, heldout=heldout, workers=args.workers)
        write_report(diagnosis, result, force=True)
    runs = load_real_runs(SWINGUPS)
    params = QuanserSwingUpParameters()
    corner = fit_velocity_corner(runs.logs[TRAIN_SWINGUP], params)
    fitted_rig = load_rig(diagnosis / "fitted_rig.yaml")
    disturbed = rig_config(fitted_rig)  # the corrected model pushed by the disturbance the diagnosis read
    corrected = disturbed.with_arm_torque(None)
    swingup = args.out / "swingup.yaml"
    start = dataclasses.replace(run_config(corrected, runs.logs[TRAIN_SWINGUP], params, corner), duration=SWINGUP_S)
    swingup.write_text(dump_config(start))
    tuned = args.out / "tune"
    if not (tuned / "tune.json").is_file():
        settings = TuneSettings(workers=args.workers, swingup=read_swingup(swingup))
        try:
            write_tune(tuned, tune(diagnosis, settings), force=True)
        except FurutaError as err:
            print(f"tune refused: {err}")
            return 1
    document = json.loads((tuned / "tune.json").read_text())
    _, taped, _ = closed_loop_rows(
        runs,
        {"corrected": corrected, "disturbed": disturbed},
        params,
        corner,
        list(SWINGUPS),
        spread=False,
        with_real=False,
    )
    rows = []
    for name in SWINGUPS:
        log = runs.logs[name]
        measured, simulated = log_result(log, params), taped[("sim_corrected", name)][0]
        rows.append(
            {
                "log": name,
                "part": runs.part(name),
                "measured": balancing(measured, log.sample_period),
                "quanser_pd_corrected": balancing(simulated, log.sample_period),
                "quanser_pd_disturbed": balancing(taped[("sim_disturbed", name)][0], log.sample_period),
                "catch_time_s": {"measured": _catch(measured), "quanser_pd_corrected": _catch(simulated)},
            }
        )
    out = {
        "disturbance": json.loads((diagnosis / "report.json").read_text()).get("disturbance"),
        "rows": rows,
        "predicted": {name: document["designs"][name]["predicted"] for name in ("nominal", "tuned")},
        "margins": {
            name: {key: document["designs"][name][key] for key in ("margins", "worst_corner")}
            for name in ("nominal", "tuned")
        },
        "swingup": document["swingup"],
        "diagnosis": document["diagnosis"],
        "tuned_design": {
            key: document["designs"]["tuned"][key]
            for key in ("lqr_gain", "lqr_gain_volts", "observer", "family_member")
        },
        "versions": versions(),
    }
    (args.out / "results.json").write_text(json.dumps(out, indent=2) + "\n")
    print(table(out))
    return 0


def _catch(result) -> float | None:
    caught = catch_time(result)
    return caught if math.isfinite(caught) else None


def _mrad(value) -> str:
    return "-" if value is None else f"{1e3 * value:.3g}"


def table(out: dict) -> str:
    disturbance = out["disturbance"] or {}
    lines = [
        f"The rig's disturbance read by the diagnosis: {_mnm(disturbance.get('arm_torque_rms'))} mN m RMS "
        f"(95 % interval {' to '.join(_mnm(v) for v in disturbance.get('ci') or [None, None])}), 90 % of its power "
        f"below {disturbance.get('bandwidth_hz', float('nan')):.3g} Hz.",
        "",
        "| run | part | measured amplitude [mrad] | frequency [Hz] | Quanser's PD on the corrected model [mrad] "
        "| [Hz] | catch measured [s] | catch of Quanser's PD on the corrected model [s] "
        "| theta RMS measured [mrad] | predicted, quiet | predicted, with the disturbance | ratio |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for row in out["rows"]:
        m, q, caught = row["measured"], row["quanser_pd_corrected"], row["catch_time_s"]
        pushed = row["quanser_pd_disturbed"]
        ratio = pushed["theta_rms"] / m["theta_rms"] if m["theta_rms"] and pushed["theta_rms"] is not None else math.nan
        lines.append(
            f"| {row['log']} | {row['part']} | {_mrad(m['limit_cycle_amplitude'])} | "
            f"{m['limit_cycle_frequency'] or float('nan'):.3g} | {_mrad(q['limit_cycle_amplitude'])} | "
            f"{q['limit_cycle_frequency'] or float('nan'):.3g} | {_seconds(caught['measured'])} | "
            f"{_seconds(caught['quanser_pd_corrected'])} | {_mrad(m['theta_rms'])} | {_mrad(q['theta_rms'])} | "
            f"{_mrad(pushed['theta_rms'])} | {ratio:.2f} |"
        )
    for name, predicted in out["predicted"].items():
        if "fell" in predicted:
            lines.append(f"\n{name} LQR on the corrected model: falls ({predicted['fell']})")
            continue
        lines.append(
            f"\n{name} LQR on the corrected model: limit cycle {_mrad(predicted['limit_cycle_amplitude'])} mrad at "
            f"{predicted['limit_cycle_frequency']:.3g} Hz, theta RMS {_mrad(predicted['theta_rms'])} mrad"
        )
    for name, margins in out["margins"].items():
        worst = margins["worst_corner"]
        lines.append(
            f"\n{name} LQR margins: {margins['margins']['gain_db']:.3g} dB, {_ms(margins['margins']['delay_s'])} ms at "
            f"the fit; {worst['gain_db']:.3g} dB, {_ms(worst['delay_s'])} ms at the worst corner"
        )
    if out["swingup"] is not None:
        for name, design in out["swingup"]["designs"].items():
            span = design["catch_time_over_intervals"]
            lines.append(
                f"\n{name} LQR behind Quanser's swing-up (train start): catch at "
                f"{_seconds(design['at_fit']['catch_time_s'])} s on the corrected model; over the intervals "
                + (f"{span[0]:.3g} to {span[1]:.3g} s" if span else "not caught at every extreme")
            )
    return "\n".join(lines) + "\n"


def _mnm(value) -> str:
    return "-" if value is None else f"{1e3 * value:.3g}"


def _seconds(value) -> str:
    return "-" if value is None else f"{value:.3g}"


def _ms(value) -> str:
    return "-" if value is None else f"{1e3 * value:.3g}"


if __name__ == "__main__":
    sys.exit(main())
