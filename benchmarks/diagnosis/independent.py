"""Blind validation of ``furuta-drake diagnose`` on logs from an independent simulator
(benchmarks/independent/simulator.py: numpy/scipy, its own equations of motion, effects in forms the package does not
model).

The suite: every vocabulary effect in each of its forms at one realistic size (a few near the limit of
detectability), two ``none`` cases, two effects outside the vocabulary (cogging, gear backlash: ``unexplained``
expected) and eight combinations of two or three effects, on a Lund-like rig (torque logs, 1 kHz) and a
QUBE-like rig (voltage logs, 500 Hz). Each case folder holds the nominal ``rig.yaml`` and four 8 s logs
(train/held-out x balancing/hanging); the answers go to ``OUT/suite/answers.json``, apart from the folders.
``diagnose`` is then run on each folder blind and scored: a single effect by the verdict, several by every true
effect being in ``effects``, ``none`` by ``none``, an effect outside the vocabulary by ``unexplained`` (beside a
listed effect: Coulomb friction next to cogging, the listed effect named among the effects kept beside the torque
beyond the vocabulary, never displaced by it).

The cases are written and diagnosed on a Dask cluster, one case per task (:mod:`benchmarks.diagnosis.shards`; each
case diagnosed with one worker process): ``--scheduler ADDRESS`` for an existing cluster (its workers must import
this repository and see ``OUT``), else a local cluster of ``--workers`` single-threaded processes (default one per
core). A line per case is printed as it finishes; a case that raises is a wrong row naming the error. The run ends
with the sum of the case times over the wall time: its speed-up over one worker, which grows with the workers until
each has one case left (:mod:`benchmarks.diagnosis.shards`).

Writes, as the cases finish, ``OUT/results.json`` (one row per case: truth, verdict, effects, confusable pairs,
fitted parameters of the accepted model next to the truth, or of the true effect fitted alone where it was not
accepted, the best candidate, held-out reduction, seconds), ``OUT/table.md``, ``OUT/verdicts.json`` (the verdict
table every suite writes, to compare two runs: ``python benchmarks/diagnosis/shards.py OLD/verdicts.json
NEW/verdicts.json``) and ``OUT/config.json`` (argv, seeds, workers, versions); the reports go to
``OUT/reports/<case>/``. Each case also states its effect's size in the
train logs, in encoder counts: the RMS of the true angles minus the nominal rig's prediction over 100 ms windows
restarted from the true state (balancing / hanging), and the sensor error RMS (0.29 for a rounding encoder).

Run from the repository root: ``PYTHONPATH=. python benchmarks/diagnosis/independent.py --out runs/indep``
(``--quick``: 6 cases; ``--only WORD ...``: the cases whose name holds a word; ``--suite DIR``: reuse logs).
"""

from __future__ import annotations

import dataclasses
import json
import math
import platform
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from benchmarks.diagnosis.shards import (
    Outcome,
    shard,
    speed_up_line,
    suite_parser,
    verdict_rows,
    worker_count,
    write_verdicts,
)
from benchmarks.independent import simulator as sim
from furuta_drake.rig import encoder_resolution
from furuta_drake.sweep import dask_client

OUTSIDE = {"cogging_torque", "gear_backlash"}
SEEDS = {"train": 11, "heldout": 23}  # base seeds of the train and held-out runs (a case adds its own offset)


@dataclass(frozen=True)
class Effect:
    """One true effect of a case: its vocabulary name (or an outside name), the form realising it, and the
    parameters in the vocabulary's names and SI units (torque-equivalent N m on a voltage rig) beside the form's
    own parameters."""

    name: str
    form: str
    params: dict
    form_params: dict


@dataclass(frozen=True)
class Case:
    """A suite case: the rig, the true world and its effects."""

    name: str
    rig: str
    world: sim.World
    effects: tuple[Effect, ...]
    seed: int
    hidden: tuple[str, ...] = ()  # true effects below their detection limit: naming them is right, not needed

    @property
    def expected(self) -> str:
        """``none``, ``unexplained`` or the '+'-joined sorted vocabulary names (the hidden effects left out)."""
        needed = [e for e in self.effects if e.name not in self.hidden]
        if not needed:
            return "none"
        if any(e.name in OUTSIDE for e in needed):
            return "unexplained"
        return "+".join(sorted(e.name for e in needed))


# --- effects: each returns the world with the effect and its truth ---------------------------------------------


def _mgl(world: sim.World) -> float:
    return world.rig.bodies.d


def _to_command(world: sim.World, torque: float) -> float:
    """A torque [N m] in the rig's command units."""
    return torque / world.rig.torque_per_command


def arm_friction(
    world,
    form: str,
    level: float,
    neg_level: float | None = None,
    smoothing: float = 0.02,
    breakaway: float = 1.0,
    static: float = 0.0,
    stribeck_velocity: float = 0.0,
):
    """Arm dry friction at ``level`` m g l (``neg_level`` for negative velocities: asymmetric), in ``form``; a
    Karnopp law breaks away at ``breakaway`` times the larger of the two levels (a stuck arm must hold at least the
    torque either side slides at)."""
    mgl = _mgl(world)
    pos, neg = level * mgl, (level if neg_level is None else neg_level) * mgl
    friction = sim.ArmFriction(
        form,
        pos,
        neg,
        smoothing=smoothing,
        breakaway=breakaway * max(pos, neg),
        static=static * mgl,
        stribeck_velocity=stribeck_velocity,
    )
    own = {
        "karnopp": {"breakaway": breakaway * max(pos, neg)},
        "tanh": {"v_eps": smoothing},
        "sign_band": {"dead_band": smoothing},
        "stribeck": {"v_eps": smoothing},
    }[form]
    if static:
        effect = Effect(
            "arm_stribeck", form, {"coulomb": pos, "static": static * mgl, "stribeck_velocity": stribeck_velocity}, own
        )
    elif neg_level is not None:
        effect = Effect("friction_asymmetry", form, {"coulomb_pos": pos, "coulomb_neg": neg}, own)
    else:
        effect = Effect("arm_coulomb_friction", form, {"coulomb": pos}, own)
    return dataclasses.replace(world, arm_friction=friction), effect


def arm_viscous(world, rate: float):
    """Viscous arm friction whose decay rate on the arm's inertia a is ``rate`` [1/s]."""
    viscous = rate * world.rig.bodies.a
    return dataclasses.replace(world, arm_viscous=viscous), Effect(
        "arm_viscous_friction", "linear", {"viscous": viscous}, {"decay_rate": rate}
    )


def pendulum_friction(world, coulomb: float, rate: float):
    """Pendulum friction: tanh-smoothed Coulomb at ``coulomb`` m g l and viscous at decay rate ``rate`` [1/s]."""
    level, viscous = coulomb * _mgl(world), rate * world.rig.bodies.b
    return dataclasses.replace(world, pendulum_coulomb=level, pendulum_viscous=viscous), Effect(
        "pendulum_friction",
        "tanh_coulomb+viscous",
        {"coulomb": level, "viscous": viscous},
        {"v_eps": world.pendulum_smoothing},
    )


def coarse_encoder(world, counts: int):
    return dataclasses.replace(world, counts_per_rev=counts), Effect(
        "encoder_quantization", "round", {"counts_per_rev": float(counts)}, {"nominal": world.rig.counts_per_rev}
    )


def noise(world, counts: float):
    """Gaussian noise of ``counts`` encoder counts on both angles."""
    std = counts * encoder_resolution(world.rig.counts_per_rev)
    return dataclasses.replace(world, noise_std=std), Effect(
        "measurement_noise", "gaussian", {"noise_std": std}, {"counts": counts}
    )


def delay(world, samples: int):
    return dataclasses.replace(world, delay_samples=samples), Effect(
        "input_delay", "fifo", {"delay": samples * world.rig.sample_period}, {"samples": samples}
    )


def jittering_delay(world, samples: int, jitter: int):
    """A delay of ``samples`` plus a uniform 0..``jitter`` samples more, drawn each sample; truth: its mean, and the
    spread of the continuous uniform delay whose expected command over each sample is the same, (jitter + 1)
    samples wide (beside the discrete draw's own std)."""
    period = world.rig.sample_period
    mean = (samples + 0.5 * jitter) * period
    spread = (jitter + 1) * period / math.sqrt(12.0)
    discrete = math.sqrt(((jitter + 1) ** 2 - 1) / 12.0) * period  # std of a discrete uniform
    return dataclasses.replace(world, delay_samples=samples, delay_jitter_samples=jitter), Effect(
        "input_delay",
        "jitter",
        {"delay": mean, "delay_spread": spread},
        {"samples": samples, "jitter": jitter, "discrete_std_s": discrete},
    )


def correlated_noise(world, counts: float, time: float):
    """Noise of ``counts`` encoder counts, low-pass with correlation time ``time`` [s]."""
    std = counts * encoder_resolution(world.rig.counts_per_rev)
    return dataclasses.replace(world, noise_std=std, noise_correlation_time=time), Effect(
        "measurement_noise", "correlated", {"noise_std": std, "correlation_time": time}, {"counts": counts}
    )


def gain(world, value: float):
    return dataclasses.replace(world, gain=value), Effect("torque_gain_error", "scale", {"gain": value}, {})


def deadzone(world, form: str, width: float):
    """Dead zone of ``width`` m g l (torque-equivalent) in ``form`` (subtract or threshold)."""
    torque = width * _mgl(world)
    return dataclasses.replace(world, deadzone=_to_command(world, torque), deadzone_form=form), Effect(
        "actuator_deadzone", form, {"deadzone": torque}, {}
    )


def lag(world, form: str, seconds: float):
    """Actuator lag of time constant ``seconds``: ``inductance`` (a motor rig's armature, L = R T; on a torque rig
    the back-EMF-compensated equivalent, a continuous first-order lag) or ``filter`` (discrete first order)."""
    if form == "filter":
        return dataclasses.replace(world, filter_time_constant=seconds), Effect(
            "actuator_lag", "discrete_filter", {"time_constant": seconds}, {}
        )
    if world.rig.motor is None:
        return dataclasses.replace(world, lag_time_constant=seconds), Effect(
            "actuator_lag", "armature_equivalent", {"time_constant": seconds}, {}
        )
    inductance = seconds * world.rig.motor.resistance
    return dataclasses.replace(world, motor_inductance=inductance), Effect(
        "actuator_lag", "armature_inductance", {"time_constant": seconds}, {"inductance_H": inductance}
    )


def saturation(world, form: str, limit: float):
    """Saturation of the applied torque at ``limit`` m g l (torque-equivalent), ``hard`` or ``tanh``."""
    torque = limit * _mgl(world)
    return dataclasses.replace(world, saturation=_to_command(world, torque), saturation_form=form), Effect(
        "actuator_saturation", form, {"limit": torque}, {}
    )


def spring(world, linear: float, cubic: float = 0.0, offset: float = 0.0):
    """Arm spring k1 x + k3 x^3 with k1 = ``linear`` m g l/rad, k3 = ``cubic`` m g l/rad^3, x = phi - offset."""
    k1, k3 = linear * _mgl(world), cubic * _mgl(world)
    form = "cubic_cable" if cubic else "linear"
    return dataclasses.replace(world, spring_linear=k1, spring_cubic=k3, spring_offset=offset), Effect(
        "arm_spring", form, {"stiffness": k1, "equilibrium": offset}, {"cubic": k3} if cubic else {}
    )


def inertia(world, **factors: float):
    """True bodies with the rig file's fields scaled (e.g. pendulum_mass=1.15); truth as the scales of a, b, c, d."""
    nominal = world.rig.bodies
    true = nominal.scaled(**factors)
    scales = {
        f"{k}_scale": getattr(true, c) / getattr(nominal, c)
        for k, c in (("arm_inertia", "a"), ("pendulum_inertia", "b"), ("coupling", "c"), ("gravity", "d"))
    }
    return dataclasses.replace(world, bodies=true), Effect("inertia_mismatch", "bodies", scales, factors)


def cogging(world, amplitude: float, periods: int):
    """Cogging -A sin(N phi) with A = ``amplitude`` m g l."""
    torque = amplitude * _mgl(world)
    return dataclasses.replace(world, cogging_amplitude=torque, cogging_periods=periods), Effect(
        "cogging_torque", "sine", {"amplitude": torque, "periods": periods}, {}
    )


def backlash(world, half_gap: float, rotor_share: float):
    return dataclasses.replace(world, backlash=sim.Backlash(half_gap, rotor_share)), Effect(
        "gear_backlash", "tooth_contact", {"half_gap": half_gap, "rotor_share": rotor_share}, {}
    )


# --- the suite ------------------------------------------------------------------------------------------------


def make_case(rig: str, *effects, seed: int = 1, hidden: int = 0) -> Case:
    """A case on ``rig`` with ``effects``: (function, args...) tuples applied in turn; the last ``hidden`` of them
    are below their detection limit (a verdict may name them or not)."""
    world, truth = sim.World(sim.RIGS[rig]()), []
    for make, *args in effects:
        kwargs = args.pop() if args and isinstance(args[-1], dict) else {}
        world, effect = make(world, *args, **kwargs)
        truth.append(effect)
    label = "+".join(f"{e.name}[{e.form}]" for e in truth) or "none"
    hidden_names = tuple(e.name for e in truth[len(truth) - hidden :]) if hidden else ()
    return Case(f"{rig}__{label}__s{seed}", rig, world, tuple(truth), seed, hidden_names)


def all_cases() -> list[Case]:
    """The full suite (see the module docstring)."""
    return [
        make_case("lund", (arm_friction, "karnopp", 0.06, {"breakaway": 1.25})),
        make_case("qube", (arm_friction, "tanh", 0.08, {"smoothing": 0.02})),
        make_case("lund", (arm_friction, "sign_band", 0.05, {"smoothing": 0.002})),
        make_case("lund", (arm_friction, "tanh", 0.015, {"smoothing": 0.05}), seed=2),
        make_case("lund", (arm_viscous, 1.5)),
        make_case("qube", (arm_viscous, 0.5)),
        make_case(
            "lund", (arm_friction, "stribeck", 0.04, {"static": 0.1, "stribeck_velocity": 0.1, "smoothing": 0.01})
        ),
        make_case("qube", (arm_friction, "tanh", 0.05, {"neg_level": 0.09, "smoothing": 0.02})),
        make_case("lund", (pendulum_friction, 0.004, 0.3)),
        make_case("lund", (coarse_encoder, 1024)),
        make_case("qube", (noise, 1.5)),
        make_case("lund", (delay, 3)),
        make_case("qube", (delay, 2)),
        make_case("lund", (gain, 0.8)),
        make_case("qube", (gain, 1.15)),
        make_case("lund", (deadzone, "subtract", 0.03)),
        make_case("qube", (deadzone, "threshold", 0.05)),
        *near_limit_cases(),
        *hidden_second_cases(),
        *delay_beside_friction_cases(),
        *unread_form_cases(),
        make_case("lund", (lag, "inductance", 0.006)),
        make_case("qube", (lag, "inductance", 0.005)),
        make_case("lund", (lag, "filter", 0.008)),
        make_case("lund", (saturation, "hard", 0.3)),
        make_case("qube", (saturation, "tanh", 0.6)),
        make_case("lund", (spring, 0.25, {"offset": 0.05})),
        make_case("qube", (spring, 0.1, {"cubic": 0.3})),
        make_case("lund", (inertia, {"pendulum_mass": 1.15, "pendulum_com": 1.05, "arm_inertia": 0.85})),
        make_case("qube", (inertia, {"pendulum_mass": 1.1, "arm_inertia": 1.2})),
        make_case("lund", seed=1),
        make_case("qube", seed=2),
        make_case("qube", (cogging, 0.05, 18)),
        make_case("qube", (arm_friction, "tanh", 0.08, {"smoothing": 0.02}), (cogging, 0.05, 18), seed=3),
        make_case("lund", (backlash, 0.005, 0.3)),
        make_case("lund", (arm_friction, "karnopp", 0.06, {"breakaway": 1.25}), (delay, 3)),
        make_case("qube", (arm_friction, "tanh", 0.08, {"smoothing": 0.02}), (lag, "inductance", 0.005)),
        make_case("lund", (arm_friction, "sign_band", 0.05, {"smoothing": 0.002}), (deadzone, "threshold", 0.03)),
        make_case("lund", (arm_viscous, 1.5), (lag, "filter", 0.008)),
        make_case(
            "qube",
            (arm_friction, "tanh", 0.08, {"smoothing": 0.02}),
            (delay, 2),
            (inertia, {"pendulum_mass": 1.1, "arm_inertia": 1.2}),
        ),
        make_case(
            "lund",
            (arm_friction, "stribeck", 0.04, {"static": 0.1, "stribeck_velocity": 0.1, "smoothing": 0.01}),
            (delay, 3),
        ),
        make_case(
            "lund", (arm_friction, "tanh", 0.05, {"smoothing": 0.02}), (spring, 0.25, {"offset": 0.05}), (delay, 2)
        ),
        make_case("qube", (arm_viscous, 0.5), (delay, 2), (deadzone, "subtract", 0.03)),
    ]


def near_limit_cases() -> list[Case]:
    """Cases near the limits of the verdict: a one-sample computation delay alone (a gap of a fraction of a
    count), and both dead-zone forms at a second size on both rigs (a threshold one under LQR balancing with the
    balancing run's dither); the second sizes take the seed 2 (the names stay apart)."""
    return [
        make_case("lund", (delay, 1), seed=3, hidden=1),
        make_case("lund", (deadzone, "threshold", 0.03)),
        make_case("lund", (deadzone, "threshold", 0.06), seed=2),
        make_case("lund", (deadzone, "subtract", 0.06), seed=2),
        make_case("qube", (deadzone, "threshold", 0.025), seed=2),
        make_case("qube", (deadzone, "subtract", 0.03)),
        make_case("qube", (deadzone, "subtract", 0.06), seed=2),
    ]


def unread_form_cases() -> list[Case]:
    """Forms real drivers and sensors have: a delay that jitters from sample to sample (``--only jitter``) and
    sensor noise with a correlation time (``--only correlated``)."""
    return [
        make_case("lund", (jittering_delay, 2, 2), seed=5),
        make_case("qube", (correlated_noise, 1.5, 0.005), seed=5),
    ]


def hidden_second_cases() -> list[Case]:
    """A clear effect beside a small second one below its detection limit (a one-sample computation delay, a
    short lag): the interval coverage of the clear effect's parameters when the model cannot be complete."""
    return [
        make_case("lund", (gain, 0.8), (delay, 1), seed=4, hidden=1),
        make_case("qube", (gain, 1.15), (delay, 1), seed=4, hidden=1),
        make_case("lund", (arm_friction, "karnopp", 0.06, {"breakaway": 1.25}), (delay, 1), seed=4, hidden=1),
        make_case(
            "qube", (inertia, {"pendulum_mass": 1.1, "arm_inertia": 1.2}), (lag, "filter", 0.002), seed=4, hidden=1
        ),
        make_case("lund", (arm_viscous, 1.5), (delay, 1), seed=4, hidden=1),
    ]


def delay_beside_friction_cases() -> list[Case]:
    """Strong asymmetric arm friction beside an input delay of one and two samples (2 and 4 ms on the QUBE-like
    rig): the friction dominates the gap; the logs see the shorter delay only above its true size and take the
    longer one for an actuator lag (``benchmarks/design/limits.py`` designs the experiment that brings the
    delay's detection limit down)."""
    return [
        make_case("qube", (arm_friction, "tanh", 0.2, {"neg_level": 0.35, "smoothing": 0.02}), (delay, 1), seed=6),
        make_case("qube", (arm_friction, "tanh", 0.2, {"neg_level": 0.35, "smoothing": 0.02}), (delay, 2), seed=7),
    ]


QUICK = (
    "lund__none",
    "lund__arm_coulomb_friction[karnopp]__",
    "qube__arm_coulomb_friction[tanh]__",
    "lund__input_delay",
    "qube__actuator_lag[armature_inductance]__",
    "qube__cogging",
)


def select(cases: list[Case], quick: bool, only: list[str] | None) -> list[Case]:
    if quick:
        return [next(c for c in cases if c.name.startswith(prefix)) for prefix in QUICK]
    if only:
        return [c for c in cases if any(word in c.name for word in only)]
    return cases


def write_case(case: Case, folder: Path, duration: float) -> dict:
    """Simulate the case's four logs into ``folder`` with the nominal rig file; return its answer."""
    folder.mkdir(parents=True, exist_ok=True)
    sim.write_rig_file(case.world.rig, folder / "rig.yaml")
    fell, signal, sensor = {}, {}, {}
    for split, base in SEEDS.items():
        seed = base + 100 * case.seed
        for run in (sim.balance_run(duration, seed), sim.hanging_run(duration, seed + 1)):
            log = sim.simulate(case.world, run)
            sim.write_log(log, folder / f"{split}_{run.kind}.csv")
            if run.kind == "balance":
                fell[split] = log.fell
            if split == "train":
                signal[run.kind] = sim.window_divergence(case.world.rig, log)
                sensor[run.kind] = sim.sensor_error(case.world.rig, log)
    return {
        "case": case.name,
        "rig": case.rig,
        "expected": case.expected,
        "hidden": list(case.hidden),
        "seed": case.seed,
        "effects": [dataclasses.asdict(e) for e in case.effects],
        "balance_fell": fell,
        "signal_counts": signal,
        "sensor_counts": sensor,
    }


def _write_case(task: tuple[Case, Path, float]) -> dict:
    """A task: write one case folder; its answer."""
    case, suite, duration = task
    return write_case(case, suite / "cases" / case.name, duration)


def generate(cases: list[Case], suite: Path, duration: float, client) -> list[dict]:
    """Write every case folder under ``suite/cases`` on ``client``'s cluster, one case per task, and
    ``suite/answers.json``; print the time per case as it finishes."""
    answers: list[dict | None] = [None] * len(cases)

    def finished(done: int, total: int, index: int, outcome: Outcome) -> None:
        if outcome.error is not None:
            raise RuntimeError(f"{cases[index].name}: its logs could not be written: {outcome.error}")
        answer = answers[index] = outcome.value
        fell = [k for k, v in answer["balance_fell"].items() if v]
        print(
            f"  [{done}/{total}] {answer['case']}: {outcome.seconds:.1f} s"
            + (f"  BALANCE FELL in {', '.join(fell)}" if fell else ""),
            flush=True,
        )
        (suite / "answers.json").write_text(json.dumps([a for a in answers if a is not None], indent=2) + "\n")

    shard(client, _write_case, [(case, suite, duration) for case in cases], finished)
    return answers


def diagnose_blind(folder: Path, report_dir: Path, candidates: list[str] | None = None) -> tuple[dict, float]:
    """``diagnose`` on one case folder (rig.yaml and the four logs; no answer in sight) with one worker process,
    on ``candidates`` (None: the whole vocabulary); its report.json and the wall time [s]."""
    from furuta_drake.diagnosis.pipeline import diagnose
    from furuta_drake.diagnosis.report.files import write_report

    start = time.perf_counter()
    diagnosis = diagnose(
        rig=folder / "rig.yaml",
        train=sorted(folder.glob("train_*.csv")),
        heldout=sorted(folder.glob("heldout_*.csv")),
        candidates=candidates,
        workers=1,
    )
    seconds = time.perf_counter() - start
    write_report(report_dir, diagnosis, force=True)
    return json.loads((report_dir / "report.json").read_text()), seconds


def is_right(answer: dict, report: dict) -> bool:
    """A single effect: the verdict names it; several: every one is in ``effects``; ``none``; ``unexplained``.
    A hidden effect (below its detection limit) may be named beside them, or in place of ``none``."""
    expected, hidden = answer["expected"], set(answer.get("hidden", []))
    if hidden and report["verdict"] != "unexplained":
        needed = set() if expected == "none" else set(expected.split("+"))
        return needed <= set(report["effects"]) <= needed | hidden
    if "+" in expected:
        return set(expected.split("+")) <= set(report["effects"])
    if expected == "unexplained":  # listed effects beside an outside one: named beside the torque, or accepted
        listed = {e["name"] for e in answer["effects"]} - OUTSIDE
        named = set(report["effects"]) | set((report.get("beside_torque") or {}).get("effects", []))
        return report["verdict"] in ("unexplained", *listed) and listed <= named
    return report["verdict"] == expected


def fitted_params(report: dict) -> dict:
    """The accepted model's parameters (the last step's: prefixed 'effect.' when it holds several)."""
    steps = report.get("steps") or []
    return steps[-1]["params"] if steps else {}


def fitted_vs_true(answer: dict, report: dict) -> list[dict]:
    """For every true vocabulary parameter: the accepted model's value where it holds that effect, else the
    value of that effect fitted alone at the first step (``accepted`` False), if it was fitted."""
    fitted, steps = fitted_params(report), [s["effect"] for s in report.get("steps") or []]
    alone = {r["effect"]: r["params"] for r in report["ranking"] if r.get("step") == 1 and r["status"] == "ok"}
    out = []
    for effect in answer["effects"]:
        accepted = effect["name"] in steps
        for param, truth in effect["params"].items():
            if accepted:
                value = fitted.get(f"{effect['name']}.{param}" if len(steps) > 1 else param)
            else:
                value = alone.get(effect["name"], {}).get(param)
            out.append({"effect": effect["name"], "param": param, "true": truth, "fitted": value, "accepted": accepted})
    return out


def row_for(answer: dict, report: dict, seconds: float) -> dict:
    """One results row."""
    best = report["ranking"][0] if report["ranking"] else {}
    return {
        "case": answer["case"],
        "rig": answer["rig"],
        "expected": answer["expected"],
        "truth": [f"{e['name']}[{e['form']}]" for e in answer["effects"]] or ["none"],
        "true_params": {e["name"]: {**e["params"], **e["form_params"]} for e in answer["effects"]},
        "verdict": report["verdict"],
        "effects": report["effects"],
        "right": is_right(answer, report),
        "confusable": [p["effects"] for p in report.get("confusable", [])],
        "steps": [[s["effect"], s["reduction_over_previous"]] for s in report.get("steps") or []],
        "fitted": fitted_params(report),
        "fitted_vs_true": fitted_vs_true(answer, report),
        "best": {
            "effect": best.get("effect", ""),
            "heldout_reduction": best.get("heldout_reduction"),
            "params": best.get("params", {}),
        },
        "heldout_reduction": report["gap"]["heldout_reduction"],
        "nominal_heldout_gap": report["gap"]["nominal"]["heldout"],
        "choice": report.get("choice", ""),
        "balance_fell": answer["balance_fell"],
        "signal_counts": answer["signal_counts"],
        "sensor_counts": answer["sensor_counts"],
        "seconds": seconds,
    }


def error_row(answer: dict, error: str, seconds: float | None) -> dict:
    return {
        "case": answer["case"],
        "rig": answer["rig"],
        "expected": answer["expected"],
        "truth": [f"{e['name']}[{e['form']}]" for e in answer["effects"]] or ["none"],
        "verdict": f"ERROR {error}"[:200],
        "effects": [],
        "right": False,
        "confusable": [],
        "steps": [],
        "fitted": {},
        "fitted_vs_true": [],
        "best": {},
        "heldout_reduction": None,
        "nominal_heldout_gap": None,
        "choice": "",
        "balance_fell": answer["balance_fell"],
        "signal_counts": answer["signal_counts"],
        "sensor_counts": answer["sensor_counts"],
        "seconds": seconds,
    }


def _number(value) -> str:
    return "-" if value is None else f"{value:.3g}" if isinstance(value, (int, float)) else str(value)


def compare_text(row: dict) -> str:
    """'param fitted/true' for every true parameter ('*': the effect fitted alone, not accepted), and the form
    the accepted model chose where it has several."""
    parts = [
        f"{c['param']} {_number(c['fitted'])}{'' if c['accepted'] else '*'}/{_number(c['true'])}"
        for c in row["fitted_vs_true"]
    ]
    forms = [
        f"{k.split('.')[0] + ' ' if '.' in k else ''}form {v}" for k, v in row["fitted"].items() if k.endswith("form")
    ]
    return "; ".join(parts + forms) or "-"


def other_text(row: dict) -> str:
    """The accepted effects that are not in the truth, with their fitted parameters; with no effect accepted,
    the best candidate and its held-out reduction (what the gap looked like)."""
    true_names = {c["effect"] for c in row["fitted_vs_true"]}
    steps = [name for name, _ in row["steps"]]
    if not steps:
        best = row["best"]
        if not best or not best["effect"]:
            return "-"
        params = ", ".join(
            f"{k} {_number(v)}"
            for k, v in best["params"].items()
            if not k.endswith("_total") and k not in ("coupling", "gravity_torque")
        )
        return f"best {best['effect']} ({_number(best['heldout_reduction'])}): {params}"
    parts = []
    for name in steps:
        if name in true_names:
            continue
        prefix = f"{name}." if len(steps) > 1 else ""
        values = ", ".join(
            f"{k[len(prefix) :]} {_number(v)}"
            for k, v in row["fitted"].items()
            if k.startswith(prefix)
            and not k.endswith("_total")
            and k[len(prefix) :] not in ("coupling", "gravity_torque")
        )
        parts.append(f"{name}: {values}")
    return "; ".join(parts) or "-"


def table(rows: list[dict]) -> str:
    """The results as a markdown table."""
    head = (
        "| rig | truth (form) | signal bal/hang, sensor [counts] | verdict | effects | right | confusable | "
        "fitted/true | wrong or best fitted | held-out red. | s |\n"
        "|---|---|---|---|---|---|---|---|---|---|---|\n"
    )
    lines = []
    for r in rows:
        reduction = "-" if r["heldout_reduction"] is None else f"{r['heldout_reduction']:.0%}"
        confusable = ", ".join("~".join(p) for p in r["confusable"]) or "-"
        signal, sensor = r["signal_counts"], r["sensor_counts"]
        size = f"{signal['balance']:.2f}/{signal['hanging']:.2f}, {max(sensor.values()):.2f}"
        lines.append(
            f"| {r['rig']} | {' + '.join(r['truth'])} | {size} | {r['verdict']} | "
            f"{', '.join(r['effects']) or '-'} | {'yes' if r['right'] else 'NO'} | {confusable} | "
            f"{compare_text(r)} | {other_text(r)} | {reduction} | {r['seconds']:.0f} |"
        )
    return head + "\n".join(lines) + "\n"


def summary(rows: list[dict]) -> dict:
    """Share right overall and by kind of case (single, several, none, outside the vocabulary)."""

    def kind(row):
        if row["expected"] in ("none", "unexplained"):
            return row["expected"]
        return "several" if "+" in row["expected"] else "single"

    out = {"cases": len(rows), "right": sum(r["right"] for r in rows)}
    for name in ("single", "several", "none", "unexplained"):
        group = [r for r in rows if kind(r) == name]
        out[name] = f"{sum(r['right'] for r in group)}/{len(group)}"
    done = [r for r in rows if r["heldout_reduction"] is not None]
    out["median_heldout_reduction"] = float(np.median([r["heldout_reduction"] for r in done])) if done else None
    out["seconds_per_case"] = float(np.mean([r["seconds"] for r in rows])) if rows else None
    return out


def versions() -> dict:
    from importlib.metadata import PackageNotFoundError, version

    import scipy

    out = {"python": platform.python_version(), "numpy": np.__version__, "scipy": scipy.__version__}
    try:
        out["drake"] = version("drake")
    except PackageNotFoundError:
        out["drake"] = "unknown"
    root = Path(__file__).resolve().parent.parent  # benchmarks/: git finds the repository's commit from there
    commit = subprocess.run(["git", "rev-parse", "HEAD"], cwd=root, capture_output=True, text=True)
    out["furuta_drake_commit"] = commit.stdout.strip()
    return out


def write_results(out: Path, rows: list[dict], pending: int) -> None:
    """results.json, table.md and verdicts.json as they stand (``pending`` cases still to run)."""
    figures = summary(rows)
    (out / "results.json").write_text(
        json.dumps({"summary": figures, "pending": pending, "rows": rows}, indent=2) + "\n"
    )
    (out / "table.md").write_text(table(rows) + "\n" + json.dumps(figures) + "\n")
    write_verdicts(out / "verdicts.json", verdict_rows("independent", rows))


def _diagnose_case(task: tuple[dict, Path, Path, list[str] | None]) -> dict:
    """A task: diagnose one case folder blind; its results row."""
    answer, suite, out, candidates = task
    report, seconds = diagnose_blind(suite / "cases" / answer["case"], out / "reports" / answer["case"], candidates)
    return row_for(answer, report, seconds)


def diagnose_all(
    answers: list[dict], suite: Path, out: Path, client, candidates: list[str] | None = None
) -> list[dict]:
    """Diagnose every case on ``client``'s cluster on ``candidates`` (None: the whole vocabulary), one case per
    task; print a line per case and write the results as each finishes; the rows in the answers' order."""
    rows: list[dict | None] = [None] * len(answers)

    def finished(done: int, total: int, index: int, outcome: Outcome) -> None:
        failed = outcome.error is not None
        row = rows[index] = error_row(answers[index], outcome.error, outcome.seconds) if failed else outcome.value
        seconds = "-" if row["seconds"] is None else f"{row['seconds']:.0f}"
        print(
            f"[{done}/{total}] {'ok ' if row['right'] else 'BAD'} {row['case']:<70} -> {row['verdict']} "
            f"{row['effects']} ({seconds} s)",
            flush=True,
        )
        write_results(out, [r for r in rows if r is not None], total - done)

    start = time.perf_counter()
    tasks = [(answer, suite, out, candidates) for answer in answers]
    outcomes = shard(client, _diagnose_case, tasks, finished)
    print(speed_up_line(outcomes, time.perf_counter() - start, worker_count(client)))
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = suite_parser(__doc__.splitlines()[0], f"{len(QUICK)} cases")
    args = parser.parse_args(argv)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    cases = select(all_cases(), args.quick, args.only)
    with dask_client(args.scheduler, args.workers, len(cases)) as client:
        if args.suite is not None:
            suite = args.suite
            names = {case.name for case in cases}
            answers = [a for a in json.loads((suite / "answers.json").read_text()) if a["case"] in names]
        else:
            suite = out / "suite"
            print(f"simulating {len(cases)} cases ({args.duration:g} s logs) into {suite}", flush=True)
            answers = generate(cases, suite, args.duration, client)
        (out / "config.json").write_text(
            json.dumps(
                {
                    "argv": sys.argv[1:] if argv is None else argv,
                    "suite": str(suite),
                    "duration_s": args.duration,
                    "workers": worker_count(client),
                    "run_seeds": SEEDS,
                    "cases": {c.name: c.seed for c in cases},
                    "versions": versions(),
                },
                indent=2,
            )
            + "\n"
        )
        if args.generate_only:
            return 0
        rows = diagnose_all(answers, suite, out, client)
    print()
    print(table(rows))
    print(json.dumps(summary(rows), indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
