"""Are the detection limits a diagnosis states true? An effect simulated at twice its stated limit should be
detected in at least 9 of 10 seeds, one at half its limit in at most 3 of 10.

For a rig: logs with no effect (the validation suite's balancing and hanging runs, train and held-out) are
diagnosed, and its report states a detection limit for every effect. Then, for each effect asked for, the same
runs are simulated with the effect at 0.5x and 2x that limit, with ten seeds each (other excitations and encoder
noise), and diagnosed: detected means the effect is among the report's accepted ``effects``. The effects are
realised with the project's true-world blocks in the limit's own form (Dahl friction with the limit's presliding,
a first-order lag, a subtracting dead zone...). An input delay is left out: the simulated world resolves delays
to half a control period, coarser than a limit's halving.

Run from the repository root:
``PYTHONPATH=. python benchmarks/diagnosis/detection_limits.py --out runs/limits --rig qube_servo2``.
Writes ``OUT/results.json`` (the limits, every run's verdict and the counts) and ``OUT/config.json``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

from benchmarks.diagnosis.suite import run_configs
from furuta_drake.config import SimulationConfig
from furuta_drake.diagnosis.pipeline import diagnose
from furuta_drake.effects.vocabulary import PRESLIDING_STARTS
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.outputs import versions
from furuta_drake.results import write_log_csv
from furuta_drake.rig import RIGS, RigParameters
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import dump_yaml_dataclass

EFFECTS = (
    "arm_coulomb_friction",
    "arm_viscous_friction",
    "actuator_lag",
    "torque_gain_error",
    "arm_spring",
    "inertia_mismatch",
)


def realise(config: SimulationConfig, effect: str, value: float) -> SimulationConfig:
    """``config`` whose world has ``effect`` with its main parameter at ``value`` (the detection limit's
    parameter and form)."""
    friction, actuator, rig = config.friction, config.actuator, config.rig
    if effect == "arm_coulomb_friction":
        return dataclasses.replace(
            config,
            friction=dataclasses.replace(
                friction, arm=JointFrictionParameters.dahl(value, value, sigma0=value / PRESLIDING_STARTS[0])
            ),
        )
    if effect == "arm_viscous_friction":
        return dataclasses.replace(
            config, friction=dataclasses.replace(friction, arm=JointFrictionParameters(model="static", viscous=value))
        )
    if effect == "pendulum_friction":
        return dataclasses.replace(
            config, friction=dataclasses.replace(friction, pendulum=JointFrictionParameters.coulomb(value))
        )
    if effect == "actuator_lag":
        return dataclasses.replace(config, actuator=dataclasses.replace(actuator, lag_time_constant=value))
    if effect == "torque_gain_error":
        return dataclasses.replace(config, actuator=dataclasses.replace(actuator, gain=value))
    if effect == "actuator_deadzone":
        return dataclasses.replace(config, actuator=dataclasses.replace(actuator, deadzone=value))
    if effect == "arm_spring":
        return dataclasses.replace(
            config, disturbance=dataclasses.replace(config.disturbance, arm_spring_stiffness=value)
        )
    if effect == "inertia_mismatch":  # the arm's lumped inertia a = J_arm + m r^2 scaled by value
        total = value * rig.arm_inertia_total
        return dataclasses.replace(config, rig=rig.replace(arm_inertia=total - rig.pendulum_mass * rig.arm_length**2))
    raise ValueError(f"no realisation of {effect}")


def scaled(effect: str, limit: float, factor: float) -> float:
    """``factor`` times the limit's size: of the value itself, or of its distance from 1 for a gain or a scale."""
    return 1.0 + factor * (limit - 1.0) if effect in ("torque_gain_error", "inertia_mismatch") else factor * limit


def write_case(
    rig: RigParameters, folder: Path, seed: int, duration: float, effect: str | None = None, value: float | None = None
) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    for split, offset in (("train", 0), ("heldout", 500)):
        for run, config in run_configs(rig, seed + offset, duration).items():
            if effect is not None:
                config = realise(config, effect, value)
            write_log_csv(simulate(config), folder / f"{split}_{run}.csv")


def diagnosed(folder: Path, workers: int | None):
    return diagnose(
        rig=folder / "rig.yaml",
        train=sorted(folder.glob("train_*.csv")),
        heldout=sorted(folder.glob("heldout_*.csv")),
        workers=workers,
    )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--rig", choices=sorted(RIGS), default="qube_servo2")
    parser.add_argument("--effects", nargs="+", default=list(EFFECTS))
    parser.add_argument("--seeds", type=int, default=10)
    parser.add_argument("--duration", type=float, default=4.0, help="length of every log [s]")
    parser.add_argument("--workers", type=int)
    args = parser.parse_args(argv)
    rig = RIGS[args.rig]()
    args.out.mkdir(parents=True, exist_ok=True)
    write_case(rig, args.out / "clean", 1, args.duration)
    clean = diagnosed(args.out / "clean", args.workers)
    limits = {limit.effect: limit for limit in clean.detection_limits}
    print(
        f"clean logs: verdict {clean.verdict}; limits: "
        + ", ".join(
            f"{name} {limits[name].param} {limits[name].value:.3g} {limits[name].unit}"
            for name in args.effects
            if limits.get(name) and limits[name].value is not None
        )
    )
    rows, counts = [], {}
    for effect in args.effects:
        limit = limits.get(effect)
        if limit is None or limit.value is None:
            print(f"{effect}: no finite limit, skipped")
            continue
        for factor in (0.5, 2.0):
            value = scaled(effect, limit.value, factor)
            detected = 0
            for seed in range(2, 2 + args.seeds):
                folder = args.out / "cases" / f"{effect}_x{factor:g}_s{seed}"
                start = time.perf_counter()
                write_case(rig, folder, seed, args.duration, effect, value)
                diagnosis = diagnosed(folder, args.workers)
                found = effect in diagnosis.effects
                detected += found
                rows.append(
                    {
                        "effect": effect,
                        "factor": factor,
                        "value": value,
                        "seed": seed,
                        "verdict": diagnosis.verdict,
                        "effects": diagnosis.effects,
                        "detected": found,
                        "seconds": time.perf_counter() - start,
                    }
                )
            counts[f"{effect} x{factor:g}"] = detected
            target = "target >= 9" if factor > 1 else "target <= 3"
            print(
                f"{effect:<22} {factor:g} x limit = {value:.4g} {limit.unit}: detected {detected}/{args.seeds} "
                f"({target})",
                flush=True,
            )
    (args.out / "results.json").write_text(
        json.dumps(
            {
                "rig": args.rig,
                "clean_verdict": clean.verdict,
                "limits": {name: dataclasses.asdict(limit) for name, limit in limits.items()},
                "detected": counts,
                "rows": rows,
            },
            indent=2,
        )
        + "\n"
    )
    (args.out / "config.json").write_text(
        json.dumps({"argv": sys.argv[1:] if argv is None else argv, "versions": versions()}, indent=2) + "\n"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
