"""A lab's QUBE-Servo 2 far from its rig file: open-loop +-7 V bang-bang trials of 4 s at 125 Hz with 2048-count
encoders, four or five large effects acting at once, from the project's independent simulator
(:mod:`benchmarks.independent.simulator`: its own equations and effect forms).

The effects, as a built or worn rig shows them: a drive gain well below 1 (0.7), viscous damping three times the
back-EMF's, a restoring torque (a cable of 0.3 m g l per radian), a sample of delay (8 ms) and, in the five-effect
cases, Coulomb friction on the arm (0.05 m g l, a tanh law). The command switches sign after a random dwell of
25-75 ms, so the pendulum spins through full turns and a misfit reaches several counts between samples: the
conditions under which a noise claimed for the misfit used to explain the whole gap.

Each case has six train and three held-out trials; ``diagnose`` runs blind on each folder. A case is right when
every true effect is in ``effects`` (a variant of its law counts: Stribeck or asymmetric friction for Coulomb
friction, whose torque at speed they share) and no sensor effect is (the encoder is exact, no noise is added); the null
case (no effect) must read ``none``. The table gives, per case: the verdict and effects, the share of the held-out
gap the predictions remove, the sensor's share, and each true parameter against its fit.

Run from the repository root: ``PYTHONPATH=. python benchmarks/diagnosis/lab_bang_bang.py --out runs/lab`` (``--only
WORD`` keeps the cases whose name holds a word). Writes ``OUT/results.json``, ``OUT/table.md`` and ``OUT/config.json``
(argv, seeds, versions); the reports go to ``OUT/reports/<case>/``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.diagnosis import independent as di
from benchmarks.independent import simulator as sim
from furuta_drake.effects.vocabulary import law_of

PERIOD = 0.008  # [s] 125 Hz
TRIAL_S = 4.0
VOLTS = 7.0
DWELL_S = (0.025, 0.075)
TRIALS = {"train": (100, 6), "heldout": (500, 3)}  # split -> (first command seed, trials)
SENSOR = {"encoder_quantization", "measurement_noise"}


def bang_bang(seed: int, samples: int) -> np.ndarray:
    """+-VOLTS switching sign after dwells drawn uniformly from DWELL_S [V], one value per sample."""
    rng = np.random.default_rng(seed)
    out, sign, switch = np.empty(samples), rng.choice([-1.0, 1.0]), rng.uniform(*DWELL_S)
    for k in range(samples):
        if k * PERIOD >= switch:
            sign, switch = -sign, switch + rng.uniform(*DWELL_S)
        out[k] = VOLTS * sign
    return out


def lab_world(friction: bool, seed: int) -> tuple[sim.World, list]:
    """The QUBE-like rig at 125 Hz with the lab's effects (module docstring) and their truths; ``seed`` only names
    the case (the trials' seeds differ by it)."""
    rig = dataclasses.replace(sim.qube_like(), sample_period=PERIOD)
    world, truth = sim.World(rig), []
    back_emf = rig.motor.torque_constant * rig.motor.backemf_constant / rig.motor.resistance
    makers = [
        (di.gain, (0.7,), {}),
        (di.arm_viscous, (3.0 * back_emf / rig.bodies.a,), {}),
        (di.spring, (0.3,), {}),
        (di.delay, (1,), {}),
    ]
    if friction:
        makers.append((di.arm_friction, ("tanh", 0.05), {"smoothing": 0.02}))
    for make, args, kwargs in makers:
        world, effect = make(world, *args, **kwargs)
        truth.append(effect)
    return world, truth


def cases() -> list[tuple[str, sim.World, list, int]]:
    """(name, world, truth, seed) of every case: four and five effects on two seeds, and the null rig."""
    out = []
    for seed in (1, 2):
        for friction in (False, True):
            world, truth = lab_world(friction, seed)
            out.append((f"qube125__{len(truth)}effects__s{seed}", world, truth, seed))
    null = sim.World(dataclasses.replace(sim.qube_like(), sample_period=PERIOD))
    out.append(("qube125__none__s1", null, [], 1))
    return out


def write_case(folder: Path, world: sim.World, seed: int) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    sim.write_rig_file(world.rig, folder / "rig.yaml")
    samples = int(round(TRIAL_S / PERIOD))
    for split, (first, count) in TRIALS.items():
        for k in range(count):
            command_seed = first + 1000 * seed + k
            log = sim.play(world, bang_bang(command_seed, samples), command_seed)
            sim.write_log(log, folder / f"{split}_{k}.csv")


def diagnose_case(folder: Path, report_dir: Path) -> tuple[dict, float]:
    from furuta_drake.diagnosis.pipeline import diagnose
    from furuta_drake.diagnosis.report.files import write_report

    start = time.perf_counter()
    diagnosis = diagnose(
        rig=folder / "rig.yaml",
        train=sorted(folder.glob("train_*.csv")),
        heldout=sorted(folder.glob("heldout_*.csv")),
        workers=2,
    )
    seconds = time.perf_counter() - start
    write_report(report_dir, diagnosis, force=True)
    return json.loads((report_dir / "report.json").read_text()), seconds


def named_as(effect: str, found) -> str | None:
    """The accepted effect that names ``effect``: itself, or a variant of its law (Stribeck or asymmetric friction
    for Coulomb friction: the same torque at speed, more parameters near zero speed); None when none does."""
    return next((name for name in found if name in law_of(effect)), None)


def fitted_value(report: dict, effect: str, param: str):
    """The accepted model's value of ``effect.param``, read from the effect that names it (None when none does)."""
    steps = [step for step in report.get("steps", []) if step["effect"] not in SENSOR]
    name = named_as(effect, [step["effect"] for step in steps])
    if name is None:
        return None
    params = steps[-1]["params"]
    return params.get(f"{name}.{param}", params.get(param))


def score(name: str, truth: list, report: dict, seconds: float) -> dict:
    names = {effect.name for effect in truth}
    found = set(report["effects"])
    named = all(named_as(effect, found) is not None for effect in names)
    right = report["verdict"] == "none" if not truth else named and not found & SENSOR
    return {
        "case": name,
        "truth": sorted(names) or ["none"],
        "verdict": report["verdict"],
        "effects": report["effects"],
        "right": right,
        "heldout_reduction": report["gap"]["heldout_reduction"],
        "sensor_share": report["gap"].get("sensor_share"),
        "nominal_heldout_gap": report["gap"]["nominal"]["heldout"],
        "fitted_vs_true": [
            {"effect": e.name, "param": p, "true": v, "fitted": fitted_value(report, e.name, p)}
            for e in truth
            for p, v in e.params.items()
        ],
        "seconds": seconds,
    }


def _number(value) -> str:
    return "-" if value is None else f"{value:.3g}"


def table(rows: list[dict]) -> str:
    lines = [
        "| case | verdict | effects | right | nominal gap | predictions remove | sensor | fitted / true |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        pairs = "; ".join(
            f"{c['effect']}.{c['param']} {_number(c['fitted'])}/{_number(c['true'])}" for c in r["fitted_vs_true"]
        )
        share = "-" if r["sensor_share"] is None else f"{r['sensor_share']:.0%}"
        lines.append(
            f"| {r['case']} | {r['verdict']} | {', '.join(r['effects']) or '-'} | {'yes' if r['right'] else 'NO'} | "
            f"{r['nominal_heldout_gap']:.2f} | {r['heldout_reduction']:.0%} | {share} | {pairs or '-'} |"
        )
    lines.append(f"\n{sum(r['right'] for r in rows)}/{len(rows)} right")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--only", nargs="+", help="the cases whose name contains one of these words")
    parser.add_argument("--rescore", action="store_true", help="score the reports already in OUT/reports again")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    chosen = [c for c in cases() if not args.only or any(word in c[0] for word in args.only)]
    (args.out / "config.json").write_text(
        json.dumps(
            {"argv": sys.argv[1:] if argv is None else argv, "trials": TRIALS, "versions": di.versions()}, indent=2
        )
        + "\n"
    )
    before = {}
    if args.rescore:
        before = {row["case"]: row["seconds"] for row in json.loads((args.out / "results.json").read_text())["rows"]}
    rows = []
    for name, world, truth, seed in chosen:
        if args.rescore:
            if name not in before:
                continue
            report, seconds = json.loads((args.out / "reports" / name / "report.json").read_text()), before[name]
        else:
            folder = args.out / "cases" / name
            write_case(folder, world, seed)
            report, seconds = diagnose_case(folder, args.out / "reports" / name)
        rows.append(score(name, truth, report, seconds))
        print(f"{name}: {rows[-1]['verdict']} {rows[-1]['effects']} ({seconds:.0f} s)", flush=True)
        (args.out / "results.json").write_text(json.dumps({"rows": rows}, indent=2) + "\n")
        (args.out / "table.md").write_text(table(rows))
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
