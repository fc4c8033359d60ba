"""The diagnosis on logs recorded as a lab with a slow controller records them: 125 Hz, 2048-count encoders, no
velocities, a random bang-bang command, against the same cases recorded at 1 kHz.

Each case of the project's simulator suite (:mod:`benchmarks.diagnosis.suite`: the Drake world with one hidden
effect realised by the true-world blocks, at the suite's two sizes, and the null case) is recorded open loop from
the hanging pendulum under a bang-bang command of +-7 V through the QUBE-Servo 2's motor (+-0.7 of the torque
limit for the Lund rig, which has no motor) that switches sign after a random dwell of 25-75 ms, so the pendulum
swings through full turns. Two train and two held-out runs of 8 s per case; the same command (a function of time)
and the same effect at both rates, only the control and logging period differ (an effect sized in control periods,
the input delay, scales with it). Each case is diagnosed blind with one worker and scored with the suite's rule
(:func:`~benchmarks.diagnosis.suite.verdict_is_right`).

Printed: per case the verdict at 1 kHz and at 125 Hz and whether each is right, then the rate of right verdicts at
each rate. Target: the 125 Hz rate within 10 points of the 1 kHz rate and no false alarm on the null case.

Run from the repository root (the whole suite is ~60 cases x 2 rates; on a shared machine take a subset):
``PYTHONPATH=. nice -n 10 python benchmarks/diagnosis/low_rate.py --out DIR [--rigs lund qube_servo2]
[--effects none arm_viscous_friction ...] [--levels 1 2] [--rates 1kHz 125Hz]``. ``DIR`` keeps the recorded cases
and the reports; a case already diagnosed there is read back, not rerun.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path

import numpy as np

from benchmarks.diagnosis.suite import SUITE_RIGS, VOCABULARY, CaseSpec, verdict_is_right, with_effect
from furuta_drake.config import SimulationConfig, open_loop_config
from furuta_drake.diagnosis.logs.writers import write_log
from furuta_drake.rig import RIGS, RigParameters
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import dump_yaml_dataclass

RATES = {"1kHz": 0.001, "125Hz": 0.008}  # control and logging period [s]
COUNTS = 2048  # encoder counts per revolution at both rates
VOLTS, AMPLIFIER_VOLTS = 7.0, 10.0  # the bang-bang level and the amplifier's range [V]
DWELL_S = (0.025, 0.075)  # the command keeps its sign for a uniform random time in this range [s]
DURATION_S = 8.0
RUNS = {"train_1": 1, "train_2": 2, "heldout_1": 501, "heldout_2": 502}  # run -> command seed


def lab_rig(name: str, period: float) -> RigParameters:
    """The shipped rig as the lab's rig file states it: its bodies, a 2048-count encoder, the lab's period."""
    return RIGS[name]().replace(sample_period=period, counts_per_rev=COUNTS)


def bang_bang(rig: RigParameters, seed: int, duration: float, period: float) -> np.ndarray:
    """The torque command [N m] per control period: +-7 V through the motor (+-0.7 torque limit without one),
    switching sign after dwells drawn uniformly from DWELL_S; the same function of time at every period."""
    rng = np.random.default_rng(seed)
    switches = np.cumsum(rng.uniform(*DWELL_S, size=int(duration / DWELL_S[0]) + 2))
    sign = rng.choice([-1.0, 1.0])
    level = (
        VOLTS * rig.motor.torque_constant / rig.motor.resistance
        if rig.motor is not None
        else VOLTS / AMPLIFIER_VOLTS * rig.torque_limit
    )
    times = np.arange(int(round(duration / period))) * period
    return sign * level * (-1.0) ** np.searchsorted(switches, times, side="right")


def run_config(rig: RigParameters, case: CaseSpec, seed: int, duration: float) -> SimulationConfig:
    """An open-loop run from the hanging pendulum under the bang-bang command, with the case's effects."""
    config = open_loop_config(rig, bang_bang(rig, seed, duration, rig.sample_period), duration=duration, seed=seed)
    for effect in case.effects:
        config = with_effect(config, effect, case.level)
    return config


def record_case(case: CaseSpec, folder: Path, period: float, duration: float = DURATION_S) -> None:
    """The case's rig file and four runs, each a CSV of time, theta, phi (encoder angles) and torque only."""
    rig = lab_rig(case.rig, period)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    for run, seed in RUNS.items():
        result = simulate(run_config(rig, case, case.seed * 1000 + seed, duration))
        columns = {"time": result.time, "theta": result.measured[:, 0], "phi": result.measured[:, 1]}
        write_log(folder / f"{run}.csv", {**columns, "torque": result.torque})


def diagnose_case(folder: Path, out: Path) -> dict:
    """The report of the case in ``folder`` (diagnosed blind, one worker), read back when already there."""
    from furuta_drake.cli import main

    if not (out / "report.json").exists():
        runs = sorted(folder.glob("*.csv"))
        train = [str(p) for p in runs if p.name.startswith("train")]
        heldout = [str(p) for p in runs if p.name.startswith("heldout")]
        args = ["diagnose", "--rig", str(folder / "rig.yaml"), "--train", *train, "--heldout", *heldout]
        code = main(args + ["--out", str(out), "--workers", "1", "--force"])
        if code != 0:
            return {"verdict": f"exit {code}", "effects": []}
    return json.loads((out / "report.json").read_text())


def cases(rigs: list[str], effects: list[str], levels: list[int]) -> list[CaseSpec]:
    chosen = []
    for rig in rigs:
        for effect in effects:
            if effect == "none":
                chosen += [CaseSpec(rig, (), 0, 1), CaseSpec(rig, (), 0, 101)]
            else:
                chosen += [CaseSpec(rig, (effect,), level, 1) for level in levels]
    return chosen


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--rigs", nargs="+", default=list(SUITE_RIGS), choices=list(SUITE_RIGS))
    parser.add_argument("--effects", nargs="+", default=["none", *VOCABULARY])
    parser.add_argument("--levels", nargs="+", type=int, default=[1, 2])
    parser.add_argument("--rates", nargs="+", default=list(RATES), choices=list(RATES))
    args = parser.parse_args(argv)
    rows = []
    for case in cases(args.rigs, args.effects, args.levels):
        row = {"case": case.name, "expected": case.expected_verdict}
        answer = {"expected_verdict": case.expected_verdict}
        for rate in args.rates:
            folder = args.out / rate / "cases" / case.name
            start = time.perf_counter()
            if not (folder / "heldout_2.csv").exists():
                record_case(case, folder, RATES[rate])
            report = diagnose_case(folder, args.out / rate / "reports" / case.name)
            row[rate] = (report["verdict"], bool(verdict_is_right(answer, report)), time.perf_counter() - start)
        rows.append(row)
        print(
            f"{row['case']:<48} "
            + "  ".join(
                f"{rate} {row[rate][0]:<22} {'right' if row[rate][1] else 'WRONG'} ({row[rate][2]:.0f} s)"
                for rate in args.rates
            ),
            flush=True,
        )
    for rate in args.rates:
        right = sum(row[rate][1] for row in rows)
        false_alarms = sum(row["expected"] == "none" and row[rate][0] != "none" for row in rows)
        print(
            f"{rate}: {right}/{len(rows)} right ({right / len(rows):.0%}); false alarms on the null case: "
            f"{false_alarms}"
        )
    (args.out / "low_rate.json").write_text(json.dumps(rows, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
