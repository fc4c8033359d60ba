"""Blind check of a geared rig's drive effects on the logs built rigs record: a play's size and a belt's stiffness,
on heavy-rotor and light-rotor gearmotors, at 1 kHz and 200 Hz.

The truth is the independent simulator's geared rig (:func:`benchmarks.independent.simulator.geared_like`: a
30:1 gearmotor, its own equations of the rotor and the arm, scipy's ``solve_ivp``), its rotor's reflected inertia
``SHARES`` of the arm side's (rotor included): 0.74 as built, the rotor most of the arm side, and 0.2, a small motor.
Each case's rig file states that gearmotor as a datasheet gives it (ratio and rotor inertia) with a rigid drive;
its four logs are the blind suite's (:mod:`benchmarks.diagnosis.independent`: balancing under the nominal LQR and
hanging under a multisine, train and held-out, 8 s). The cases (``CASES``) at each share and rate:

- ``none``: the rig file is the rig;
- a play of 0.005 and of 0.03 rad either way (:class:`~benchmarks.independent.simulator.Backlash`, its teeth's own
  contact, unknown to the diagnosis);
- a belt ringing at 30 Hz and at 60 Hz against the locked pendulum (:class:`~benchmarks.independent.simulator.Belt`,
  damping ratio 0.1; k = mu (2 pi f)^2, mu = J_r (a - J_r) / a, a = J + m r^2); the nominal LQR loses the pendulum
  over a belt ringing at 12 Hz on either rotor and at 20 Hz on the light one, so softer belts have no balancing log;
- a play of 0.015 rad beside a belt ringing at 40 Hz;
- the controls: Coulomb friction on the arm (10 mN m, smoothed by tanh(v / 0.02 rad/s): Karnopp's stick-slip
  chatters beyond the simulator's switch budget on an arm free in a play), and a delay of 5 ms (whole samples),
  neither of which may be blamed on the drive.

Every case is diagnosed on the drive's effects, their look-alikes and the controls' effects
(:data:`benchmarks.diagnosis.drives.CANDIDATES`), or with ``--whole-vocabulary`` on every effect, as a user with
this rig file would (several times as long), one worker per case on a Dask cluster (``--workers``, ``--scheduler``;
:mod:`benchmarks.diagnosis.shards`). Scored per case: a play named with its
half-width within 15 % of the truth and its 95 % interval covering it; a belt named with its stiffness within 10 %;
both named where both are there; no drive effect named in a control; ``none`` for the rig file's own rig. A drive
effect beyond the report's own detection limit (a play under it, a belt stiffer than it) is out of these logs' sight
and need not be named.

Writes ``OUT/drive_table.md`` and ``OUT/drive_results.json`` (one row per case: truth, effects, the accepted
model's play and stiffness with their intervals, the checks), beside the blind suite's own ``results.json``,
``table.md``, ``verdicts.json`` and ``config.json``; the cases' logs under ``OUT/suite`` (or ``--suite``).

Run from the repository root: ``PYTHONPATH=. python benchmarks/diagnosis/geared.py --out runs/geared``
(``--quick``: the heavy rotor at 1 kHz alone; ``--only WORD ...``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import sys

import numpy as np

from benchmarks.diagnosis import independent as di
from benchmarks.diagnosis.drives import CANDIDATES, FRICTION
from benchmarks.diagnosis.shards import suite_parser, worker_count
from furuta_drake.sweep import dask_client

sim = di.sim
SHARES = {"heavy": 0.74, "light": 0.2}  # the rotor's reflected inertia over the arm side's, rotor included
RATES = {"1kHz": 0.001, "200Hz": 0.005}  # control and logging period [s]
DELAY_S = 0.005
BELT_DAMPING_RATIO = 0.1
PLAY_TOLERANCE, BELT_TOLERANCE = 0.15, 0.10  # the check's relative errors of the half-width and the stiffness
DRIVE_EFFECTS = ("drive_backlash", "drive_compliance")


def geared_rig(share: float, period: float) -> sim.Rig:
    """The simulator's geared rig with its rotor's reflected inertia ``share`` of the arm side's (the arm itself as
    built) at ``period``."""
    rig = sim.geared_like()
    arm = rig.bodies.arm_inertia - rig.rotor_inertia * rig.gear_ratio**2
    rotor = share * arm / (1.0 - share)
    bodies = dataclasses.replace(rig.bodies, arm_inertia=arm + rotor)
    return dataclasses.replace(rig, bodies=bodies, rotor_inertia=rotor / rig.gear_ratio**2, sample_period=period)


def belt_for(rig: sim.Rig, frequency: float) -> dict:
    """The stiffness [N m/rad] and damping [N m s/rad] of a belt on ``rig`` ringing at ``frequency`` [Hz]."""
    bodies = rig.bodies
    rotor = rig.rotor_share * bodies.arm_inertia
    whole = bodies.arm_inertia + bodies.pendulum_mass * bodies.arm_length**2
    mu = rotor * (whole - rotor) / whole
    stiffness = mu * (2.0 * math.pi * frequency) ** 2
    return {"stiffness": stiffness, "damping": 2.0 * BELT_DAMPING_RATIO * math.sqrt(stiffness * mu)}


def play(world: sim.World, half_width: float):
    return dataclasses.replace(world, backlash=sim.Backlash(half_width, world.rig.rotor_share)), di.Effect(
        "drive_backlash", "tooth_contact", {"backlash": half_width}, {"rotor_share": world.rig.rotor_share}
    )


def belt(world: sim.World, frequency: float):
    values = belt_for(world.rig, frequency)
    return dataclasses.replace(world, belt=sim.Belt(**values, rotor_share=world.rig.rotor_share)), di.Effect(
        "drive_compliance", "belt", values, {"frequency_hz": frequency}
    )


def friction(world: sim.World):
    return di.arm_friction(world, "tanh", FRICTION / world.rig.bodies.d, smoothing=0.02)


def delay(world: sim.World):
    return di.delay(world, round(DELAY_S / world.rig.sample_period))


CASES = {  # name -> the effects made on the rig's world in turn
    "none": (),
    "play_small": ((play, 0.005),),
    "play_large": ((play, 0.03),),
    "belt_slow": ((belt, 30.0),),
    "belt_fast": ((belt, 60.0),),
    "play_belt": ((play, 0.015), (belt, 40.0)),
    "friction": ((friction,),),
    "delay": ((delay,),),
}


def all_cases() -> list[di.Case]:
    """Every case at every share and rate, seeded apart."""
    cases = []
    for share_name, share in SHARES.items():
        for rate, period in RATES.items():
            for name, makers in CASES.items():
                world, truth = sim.World(geared_rig(share, period)), []
                for make, *args in makers:
                    world, effect = make(world, *args)
                    truth.append(effect)
                seed = len(cases) + 1
                cases.append(di.Case(f"{share_name}_{rate}_{name}", "geared", world, tuple(truth), seed))
    return cases


def _accepted(report: dict) -> tuple[dict, dict]:
    """The accepted model's parameters and 95 % intervals, keyed 'effect.parameter'."""
    effects = list(report["effects"])
    entry = next((e for e in report["ranking"] if e["effect"] == "+".join(effects)), {})
    if len(effects) == 1:
        prefix = f"{effects[0]}."
        return (
            {prefix + k: v for k, v in entry.get("params", {}).items()},
            {prefix + k: v for k, v in entry.get("params_ci", {}).items()},
        )
    return entry.get("params", {}), entry.get("params_ci", {})


def hidden(truth: dict, report: dict) -> set[str]:
    """The true drive effects the report's own detection limits put out of these logs' sight: a play under the
    play's limit, a belt stiffer than the stiffness limit (a limit the report states only for an effect it did not
    accept)."""
    limits = {limit["effect"]: limit["value"] for limit in report.get("detection_limits", [])}
    out = set()
    if "drive_backlash" in truth and truth["drive_backlash"]["backlash"] < limits.get("drive_backlash", 0.0):
        out.add("drive_backlash")
    if "drive_compliance" in truth and truth["drive_compliance"]["stiffness"] > limits.get("drive_compliance", np.inf):
        out.add("drive_compliance")
    return out


def drive_row(answer: dict, report: dict) -> dict:
    """The case's drive checks (module docstring) from its answer and its report; an effect beyond the report's
    detection limit (:func:`hidden`) need not be named."""
    truth = {e["name"]: e["params"] for e in answer["effects"]}
    named = set(report["effects"])
    params, intervals = _accepted(report)
    unseen = hidden(truth, report)
    row = {
        "case": answer["case"],
        "truth": truth,
        "verdict": report["verdict"],
        "effects": sorted(named),
        "hidden": sorted(unseen),
    }
    checks = []
    if "drive_backlash" in truth and "drive_backlash" not in unseen:
        true, fitted = truth["drive_backlash"]["backlash"], params.get("drive_backlash.backlash")
        interval = intervals.get("drive_backlash.backlash")
        row.update(play=fitted, play_interval=interval, play_truth=true)
        checks.append(
            fitted is not None
            and abs(fitted / true - 1.0) <= PLAY_TOLERANCE
            and bool(interval and interval[0] <= true <= interval[1])
        )
    if "drive_compliance" in truth and "drive_compliance" not in unseen:
        true, fitted = truth["drive_compliance"]["stiffness"], params.get("drive_compliance.stiffness")
        row.update(
            stiffness=fitted, stiffness_interval=intervals.get("drive_compliance.stiffness"), stiffness_truth=true
        )
        checks.append(fitted is not None and abs(fitted / true - 1.0) <= BELT_TOLERANCE)
    blamed = (named & set(DRIVE_EFFECTS)) - set(truth)
    row["blamed_on_drive"] = sorted(blamed)
    checks.append(not blamed)
    seen = set(truth) - unseen
    checks.append(report["verdict"] == "none" if not seen else seen <= named)
    row["right"] = all(checks)
    row["heldout_reduction"] = report["gap"]["heldout_reduction"]
    row["balance_fell"] = answer["balance_fell"]
    return row


def _g(value, digits: int = 3) -> str:
    return "-" if value is None else f"{value:.{digits}g}"


def _fitted(row: dict, key: str) -> str:
    if key not in row:
        return "-"
    interval = row.get(f"{key}_interval")
    span = f" ({_g(interval[0])} to {_g(interval[1])})" if interval else ""
    return f"{_g(row[key])}{span} / {_g(row[f'{key}_truth'])}"


def drive_table(rows: list[dict]) -> str:
    lines = [
        "| case | effects named | play [rad] fitted (95 %) / truth | stiffness [N m/rad] fitted (95 %) / truth "
        "| out of sight | blamed on the drive | held-out reduction | right |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        reduction = "-" if r["heldout_reduction"] is None else f"{100 * r['heldout_reduction']:.0f} %"
        lines.append(
            f"| {r['case']} | {', '.join(r['effects']) or 'none'} | {_fitted(r, 'play')} | "
            f"{_fitted(r, 'stiffness')} | {', '.join(r['hidden']) or '-'} | {', '.join(r['blamed_on_drive']) or '-'} | "
            f"{reduction} | "
            f"{'yes' if r['right'] else 'NO'} |"
        )
    right = sum(r["right"] for r in rows)
    return "\n".join(lines) + f"\n\nright: {right}/{len(rows)}\n"


def select(cases: list[di.Case], quick: bool, only: list[str] | None) -> list[di.Case]:
    if quick:
        return [c for c in cases if c.name.startswith("heavy_1kHz_")]
    if only:
        return [c for c in cases if any(word in c.name for word in only)]
    return cases


def main(argv: list[str] | None = None) -> int:
    parser = suite_parser(__doc__.splitlines()[0], "the heavy rotor at 1 kHz alone")
    parser.add_argument("--whole-vocabulary", action="store_true", help="every effect a candidate")
    args = parser.parse_args(argv)
    candidates = None if args.whole_vocabulary else list(CANDIDATES)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    cases = select(all_cases(), args.quick, args.only)
    with dask_client(args.scheduler, args.workers, len(cases)) as client:
        suite = args.suite or out / "suite"
        if args.suite is None:
            print(f"simulating {len(cases)} cases ({args.duration:g} s logs) into {suite}", flush=True)
            answers = di.generate(cases, suite, args.duration, client)
        else:
            names = {case.name for case in cases}
            answers = [a for a in json.loads((suite / "answers.json").read_text()) if a["case"] in names]
        config = {
            "argv": sys.argv[1:] if argv is None else argv,
            "suite": str(suite),
            "duration_s": args.duration,
            "workers": worker_count(client),
            "run_seeds": di.SEEDS,
            "cases": {c.name: c.seed for c in cases},
            "shares": SHARES,
            "candidates": candidates or "the whole vocabulary",
            "versions": di.versions(),
        }
        (out / "config.json").write_text(json.dumps(config, indent=2) + "\n")
        if args.generate_only:
            return 0
        di.diagnose_all(answers, suite, out, client, candidates)
    rows = [
        drive_row(answer, json.loads((out / "reports" / answer["case"] / "report.json").read_text()))
        for answer in answers
        if (out / "reports" / answer["case"] / "report.json").exists()
    ]
    (out / "drive_results.json").write_text(json.dumps({"rows": rows}, indent=2) + "\n")
    (out / "drive_table.md").write_text(drive_table(rows))
    print(drive_table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
