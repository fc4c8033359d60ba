"""The diagnosis of a geared rig's drive: backlash and an elastic coupling, each at two sizes and two log rates,
beside an arm friction and an input delay on the same rig, logged as built rigs log them.

The truth is the package's Drake world of the shipped geared rig (``furuta_drake.rig.geared_rig``: a 30:1
gearmotor whose rotor weighs about half the arm side), its drive stated with the case's backlash or stiffness and
damping; the rig file the diagnosis reads states the same drive rigid (gear ratio and rotor inertia only), so the
drive's play or spring is what it has to find. Every log is open loop from the hanging pendulum under a step
command (a square wave of the motor's voltage whose level switches sign after a random dwell of DWELL_S), as a
microcontroller that logs its PWM command records it; the arm reverses at every step, where backlash and a spring
show. Two train and two held-out runs of DURATION_S per case, at 200 Hz and at 50 Hz.

Printed: per case the effect, its size, the rate, the verdict, the fitted value (95 % interval) against the
truth, the held-out reduction of the gap, and the detection limit of the drive's effects. The candidates are the
drive's two effects, their look-alikes (arm Coulomb friction, a dead zone, an actuator lag) and the input delay
(``CANDIDATES``; the whole vocabulary takes about ten times as long).

``--simulator independent`` records the same cases with the project's independent simulator instead
(:mod:`benchmarks.independent.simulator`: its own equations of the rotor and the arm, scipy's ``solve_ivp``), the drive
effects checked blind: its geared rig (``geared_like``, the same gear ratio, rotor, motor, bodies and encoders as the
rig file the diagnosis reads, which is the same file in both modes) with a
:class:`~benchmarks.independent.simulator.Backlash` or a :class:`~benchmarks.independent.simulator.Belt`, Karnopp
stick-slip on the arm for the friction case and an integer-sample FIFO for the delay, played the same step command (in
volts, logged as voltage). The truth's parameters map to the diagnosis' as follows, both simulators stating the drive on
the arm side (the rotor's angle psi the motor's over the gear ratio, its inertia J_r = J_m N^2 = ``rotor_share`` times
the arm's J, rotor included):

- backlash: ``Backlash.half_gap`` [rad, arm side, half the play] is ``drive_backlash.backlash``; the simulator's own
  tooth contact (the rotor ringing at 150 Hz against a held arm, damping ratio 0.3) stays as it is, unknown to the
  diagnosis;
- compliance: ``Belt.stiffness`` [N m/rad] and ``Belt.damping`` [N m s/rad] on the twist psi - phi are
  ``drive_compliance.stiffness`` and ``.damping``; the pair rings at sqrt(k / mu) / 2 pi, mu = J_r (a - J_r) / a with
  a = J + m r^2 (8 Hz and 30 Hz here, as in Drake);
- both drives' ``rotor_share`` is the rig's J_m N^2 / J (0.74), the rotor taken out of the arm's J;
- friction: the Karnopp law's Coulomb level [N m] (breakaway equal to it) is ``arm_coulomb_friction.coulomb``;
- delay: ``delay_samples`` = DELAY / period samples is ``input_delay.delay`` = DELAY [s].

A ``none`` case (no effect) checks that the rig file describes the rig the simulator integrates: its nominal gap is
at the encoder's floor.

Run from the repository root: ``PYTHONPATH=. nice -n 19 python benchmarks/diagnosis/drives.py --out DIR
[--simulator drake|independent] [--cases backlash_small ...] [--rates 200Hz 50Hz] [--workers 1]``. ``DIR`` keeps
the recorded cases and the reports; a case already diagnosed there is read back, not rerun. Writes
``DIR/results.json`` (one row per case and rate), ``DIR/table.md`` and ``DIR/config.json`` (argv, simulator, the
runs' command seeds, versions).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmarks.diagnosis import independent as di
from benchmarks.diagnosis.suite import _with_actuator, _with_arm_friction
from furuta_drake.config import SimulationConfig, open_loop_config
from furuta_drake.diagnosis.logs.writers import write_log
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.rig import RigParameters, geared_rig
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import dump_yaml_dataclass

sim = di.sim  # the independent simulator, as the blind suite's effect makers import it

RATES = {"200Hz": 0.005, "50Hz": 0.02}  # control and logging period [s]
VOLTS = 1.0  # the step command's level [V]: the arm swings through about a radian between reversals
DWELL_S = (0.25, 0.6)  # the command keeps its sign for a uniform random time in this range [s]
DURATION_S = 4.0
CANDIDATES = (  # the drive's effects, their look-alikes and the friction and delay cases' own
    "drive_backlash",
    "drive_compliance",
    "arm_coulomb_friction",
    "actuator_deadzone",
    "actuator_lag",
    "input_delay",
)
RUNS = {"train_1": 1, "train_2": 2, "heldout_1": 501, "heldout_2": 502}  # run -> command seed
SIMULATORS = ("drake", "independent")


@dataclass(frozen=True)
class DriveCase:
    """A case: its name, the effect the diagnosis should name, the truth's changes (``drive`` keys of the rig's
    drive, or a simulate config's ``effects``), and the truth's values of the effect's parameters."""

    name: str
    effect: str
    drive: dict
    truth: dict
    config: dict = dataclasses.field(default_factory=dict)


def _compliance(frequency: float, ratio: float) -> dict:
    """A drive spring ringing at ``frequency`` [Hz] (pendulum locked) with the damping ratio ``ratio``:
    k = mu (2 pi f)^2, c = 2 zeta sqrt(k mu), mu the reduced inertia of the geared rig's rotor and arm side."""
    rig = geared_rig()
    rotor = rig.drive.reflected_inertia
    arm_side = rig.arm_inertia_total - rotor
    mu = rotor * arm_side / (rotor + arm_side)
    k = mu * (2.0 * math.pi * frequency) ** 2
    return {"stiffness": k, "damping": 2.0 * ratio * math.sqrt(k * mu)}


SOFT, STIFF = _compliance(8.0, 0.1), _compliance(30.0, 0.1)  # a belt ringing at 8 Hz and at 30 Hz
FRICTION = 0.01  # [N m] Coulomb friction on the arm (Dahl's, presliding 1 mrad)
DELAY = 0.02  # [s]
CASES = {
    c.name: c
    for c in [
        DriveCase("backlash_small", "drive_backlash", {"backlash": 0.01}, {"backlash": 0.01}),
        DriveCase("backlash_large", "drive_backlash", {"backlash": 0.03}, {"backlash": 0.03}),
        DriveCase("compliance_soft", "drive_compliance", SOFT, {"stiffness": SOFT["stiffness"]}),
        DriveCase("compliance_stiff", "drive_compliance", STIFF, {"stiffness": STIFF["stiffness"]}),
        DriveCase("arm_friction", "arm_coulomb_friction", {}, {"coulomb": FRICTION}, {"coulomb": FRICTION}),
        DriveCase("delay", "input_delay", {}, {"delay": DELAY}, {"delay": DELAY}),
        DriveCase("none", "none", {}, {}),
    ]
}


def lab_rig(period: float) -> RigParameters:
    """The geared rig as its rig file states it: a rigid drive (gear ratio and rotor inertia), the lab's period."""
    return geared_rig().replace(sample_period=period)


def step_command(rig: RigParameters, seed: int, duration: float) -> np.ndarray:
    """The torque-equivalent command [N m] per control period: +-VOLTS through the motor, switching sign after
    dwells drawn uniformly from DWELL_S (the same function of time at every period)."""
    rng = np.random.default_rng(seed)
    switches = np.cumsum(rng.uniform(*DWELL_S, size=int(duration / DWELL_S[0]) + 2))
    level = VOLTS * rig.motor.torque_constant / rig.motor.resistance * rng.choice([-1.0, 1.0])
    times = np.arange(int(round(duration / rig.sample_period))) * rig.sample_period
    return level * (-1.0) ** np.searchsorted(switches, times, side="right")


def true_config(case: DriveCase, rig: RigParameters, seed: int, duration: float) -> SimulationConfig:
    """The truth's run: the rig with the case's drive (or effect), open loop from hanging under the step command."""
    truth = rig.replace(drive=dataclasses.replace(rig.drive, **case.drive)) if case.drive else rig
    config = open_loop_config(truth, step_command(rig, seed, duration), duration=duration, seed=seed)
    if "coulomb" in case.config:
        level = case.config["coulomb"]
        friction = JointFrictionParameters(model="dahl", coulomb_pos=level, coulomb_neg=level, sigma0=level / 1e-3)
        config = _with_arm_friction(config, friction)
    if "delay" in case.config:
        config = _with_actuator(config, delay=case.config["delay"])
    return config


def independent_world(case: DriveCase, period: float) -> sim.World:
    """The case's truth in the independent simulator: its geared rig at ``period`` with the case's drive or effect,
    the parameters mapped as the module docstring states."""
    rig = dataclasses.replace(sim.geared_like(), sample_period=period)
    world, share = sim.World(rig), rig.rotor_share
    if "backlash" in case.drive:
        world, _ = di.backlash(world, case.drive["backlash"], share)
    if "stiffness" in case.drive:
        world = dataclasses.replace(world, belt=sim.Belt(case.drive["stiffness"], case.drive["damping"], share))
    if "coulomb" in case.config:
        world, _ = di.arm_friction(world, "karnopp", case.config["coulomb"] / rig.bodies.d)
    if "delay" in case.config:
        samples = round(case.config["delay"] / period)
        if not math.isclose(samples * period, case.config["delay"]):
            raise ValueError(
                f"the independent simulator delays by whole samples: {case.config['delay']} s at {period} s"
            )
        world, _ = di.delay(world, samples)
    return world


def record_case(
    case: DriveCase, folder: Path, period: float, duration: float = DURATION_S, simulator: str = "drake"
) -> None:
    """The case's rig file (the drive rigid) and four runs by ``simulator``, each a CSV of time, theta, phi and the
    command only (torque from Drake, voltage from the independent simulator)."""
    rig = lab_rig(period)
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    world = independent_world(case, period) if simulator == "independent" else None
    for run, seed in RUNS.items():
        if world is not None:
            volts = step_command(rig, seed, duration) * rig.motor.resistance / rig.motor.torque_constant
            sim.write_log(sim.play(world, volts, seed), folder / f"{run}.csv")
            continue
        result = simulate(true_config(case, rig, seed, duration))
        columns = {"time": result.time, "theta": result.measured[:, 0], "phi": result.measured[:, 1]}
        write_log(folder / f"{run}.csv", {**columns, "torque": result.torque})


def diagnose_case(folder: Path, out: Path, workers: int, candidates=CANDIDATES) -> tuple[dict, float]:
    """The report of the case in ``folder`` (diagnosed blind) and its wall time [s], read back when already there."""
    from furuta_drake.diagnosis.pipeline import diagnose
    from furuta_drake.diagnosis.report.files import write_report

    start = time.perf_counter()
    if not (out / "report.json").exists():
        diagnosis = diagnose(
            rig=folder / "rig.yaml",
            train=sorted(folder.glob("train_*.csv")),
            heldout=sorted(folder.glob("heldout_*.csv")),
            candidates=list(candidates),
            workers=workers,
        )
        write_report(out, diagnosis, force=True)
    return json.loads((out / "report.json").read_text()), time.perf_counter() - start


def _entry(report: dict, effect: str) -> dict:
    """The ranking entry of the accepted model, else the case's effect's own entry."""
    accepted = "+".join(name for name in report.get("effects", []) if name not in ("measurement_noise",))
    for name in (accepted, effect):
        entry = next((e for e in report.get("ranking", []) if e["effect"] == name), None)
        if entry is not None:
            return entry
    return {}


def row_for(case: DriveCase, rate: str, report: dict, seconds: float) -> dict:
    """The table's row of a case: verdict, the fitted main parameter (its 95 % interval) of the case's effect
    against the truth, the held-out reduction, and the drive effects' detection limits."""
    entry = _entry(report, case.effect)
    names = entry.get("effect", "").split("+")
    prefix = f"{case.effect}." if len(names) > 1 else ""
    param, truth = next(iter(case.truth.items()), (None, None))
    fitted = entry.get("params", {}).get(prefix + param) if case.effect in names else None
    interval = entry.get("params_ci", {}).get(prefix + param) if case.effect in names else None
    limits = {limit["effect"]: limit["value"] for limit in report.get("detection_limits", [])}
    return {
        "case": case.name,
        "effect": case.effect,
        "size": "-" if param is None else f"{param} {truth:.3g}",
        "rate": rate,
        "verdict": report.get("verdict"),
        "effects": "+".join(report.get("effects", [])) or "-",
        "fitted": fitted,
        "interval": interval,
        "truth": truth,
        "within": None if truth is None else bool(interval and interval[0] <= truth <= interval[1]),
        "nominal_gap": ((report.get("gap") or {}).get("nominal") or {}).get("heldout"),
        "reduction": (report.get("gap") or {}).get("heldout_reduction"),
        "limit_backlash": limits.get("drive_backlash"),
        "limit_stiffness": limits.get("drive_compliance"),
        "seconds": seconds,
    }


def _g(value, digits: int = 3) -> str:
    return "-" if value is None else f"{value:.{digits}g}"


def table(rows: list[dict]) -> str:
    head = (
        "| case | size | rate | verdict (accepted) | fitted (95 % interval) | truth in interval | nominal gap [counts] "
        "| held-out reduction | limit: backlash [rad] | limit: stiffness [N m/rad] |"
    )
    lines = [head, "|" + "---|" * 10]
    for r in rows:
        fitted = _g(r["fitted"]) + (f" ({_g(r['interval'][0])} to {_g(r['interval'][1])})" if r["interval"] else "")
        reduction = "-" if r["reduction"] is None else f"{100 * r['reduction']:.0f} %"
        within = "-" if r["within"] is None else ("yes" if r["within"] else "no")
        lines.append(
            f"| {r['case']} | {r['size']} | {r['rate']} | {r['verdict']} ({r['effects']}) | {fitted} | {within} | "
            f"{_g(r['nominal_gap'])} | {reduction} | {_g(r['limit_backlash'])} | {_g(r['limit_stiffness'])} |"
        )
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--simulator", choices=SIMULATORS, default="drake", help="the truth's simulator")
    parser.add_argument("--cases", nargs="+", default=list(CASES), choices=list(CASES))
    parser.add_argument("--rates", nargs="+", default=list(RATES), choices=list(RATES))
    parser.add_argument("--workers", type=int, default=1)
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    config = {
        "argv": sys.argv[1:] if argv is None else argv,
        "simulator": args.simulator,
        "command_seeds": RUNS,
        "candidates": list(CANDIDATES),
        "versions": di.versions(),
    }
    (args.out / "config.json").write_text(json.dumps(config, indent=2) + "\n")
    rows = []
    for name in args.cases:
        for rate in args.rates:
            case, folder = CASES[name], args.out / "cases" / f"{name}_{rate}"
            if not (folder / "heldout_2.csv").exists():
                record_case(case, folder, RATES[rate], simulator=args.simulator)
            report, seconds = diagnose_case(folder, args.out / "reports" / f"{name}_{rate}", args.workers)
            rows.append(row_for(case, rate, report, seconds))
            print(f"  {name} {rate}: {rows[-1]['verdict']} in {seconds:.0f} s", flush=True)
            (args.out / "results.json").write_text(json.dumps({"rows": rows}, indent=2) + "\n")
            (args.out / "table.md").write_text(table(rows) + "\n")
    print(table(rows))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
