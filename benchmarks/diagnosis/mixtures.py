"""Blind validation of ``furuta-drake diagnose`` on rigs that carry four to six unmodelled effects at once, as real
rigs do, on logs from the independent simulator (:mod:`benchmarks.independent.simulator`: its own equations of
motion and its own forms of every effect): the measuring stick for how many of a rig's effects the diagnosis names
and how much of the held-out gap its predictions leave.

The suite (:func:`all_mixtures`): fourteen rigs, seven Lund-like (torque logs, 1 kHz, 4096 counts) and seven
QUBE-like (voltage logs, 500 Hz, 2048 counts), each mixing four to six of: arm dry friction in one of its forms
(Karnopp stick-slip, tanh or banded-sign Coulomb, a Stribeck curve, an asymmetric Coulomb level), viscous arm
friction, pendulum friction, an input delay or an actuator lag (never both; two rigs have neither), a torque gain
error, an arm spring (linear or cubic), an inertia error (a heavier pendulum, a heavier arm) and at most one sensor
effect (Gaussian noise or a coarse encoder), at realistic sizes near those of
:mod:`benchmarks.diagnosis.independent`'s single-effect cases (the noise NOISE counts: about a count, and visible on
its own beside the other effects). No rig has more than five effects that change the dynamics (the diagnosis accepts
five at the most), so every effect can be named. The three mixtures the issue names are ``a`` (Stribeck arm
friction, pendulum friction, an actuator lag, an arm spring), ``b`` (Coulomb and viscous arm friction, pendulum
friction, a delay, a spring) and ``c`` (asymmetric Coulomb friction, a delay, a heavier pendulum, about a count of
noise), each on both rigs. Every case has its own seed; the runs' seeds follow
:data:`benchmarks.diagnosis.independent.SEEDS` (the same four 8 s logs as there: train and held-out, balancing under
the simulator's LQR with a multisine and hanging under an open-loop multisine), so every case is reproducible.

The oracle (:func:`visibility`): for every effect of every rig the same four runs (same seeds, same excitation) are
simulated again with that one effect removed, and the RMS difference of the logged encoder angles (theta and phi
together, over the four logs) is the effect's ``visible_counts``, in counts of the rig file's encoder. An effect is
visible on its own at VISIBLE counts or more (the issue's effects range from 1.5 to 140 counts); the sizes are
chosen so that every effect is. The balancing runs are closed loop, so removing an effect also changes the
trajectory: the oracle measures what the logs can show, not a torque. The table splits it into the balancing and the
hanging runs: in the open-loop hanging runs a removed friction, spring or inertia error lets the arm drift away from
the logged run, so those differences grow far beyond the closed-loop balancing runs'. It is written into
``OUT/suite/answers.json`` (per effect ``visible_counts`` and ``visible_counts_by_log``) and printed as a table.

Scoring, per case, against the report's ``effects``:

- named: every visible true effect named in ``effects`` (or, with a torque beyond the vocabulary, among the effects
  kept beside it, ``beside_torque``, as :mod:`benchmarks.diagnosis.independent` reads them), or a member of its
  family (:data:`FAMILIES`, with why); a variant's name is shown as ``true~named``, and the strict share (exact names
  only) is given beside it;
- missed: the visible true effects that are not named, with the detection limit the report states for each and
  whether the truth is above it (the report's limits are stated beside its accepted model; a limit beyond the
  search range counts as below), and a sensor effect that the report's ``choice`` says is accepted on its signature
  while ``effects`` leaves it out marked so (it stays missed: ``effects`` is the answer a user's script reads);
- false: named effects that are not a true effect nor in the family of one (a torque gain beside a true inertia
  error, or an inertia error beside a true gain, is not false: they are one confounded pair), and a torque beyond
  the vocabulary claimed at a joint (``unmodelled_torque``: every true effect is in the vocabulary). The simulator holds
  the logged command over its sample as the package does, so it adds no delay of its own; as
  :mod:`benchmarks.diagnosis.independent` counts a one-sample computation delay as a hidden effect (naming it is
  neither needed nor wrong), an input delay or actuator lag named on a rig without one, fitted at one sample or
  less, is listed as tolerated, not false;
- the held-out gap the predictions remove (``gap.heldout_reduction``), the share the effects close with an
  accepted sensor effect's share counted (:func:`closed_share`; target: TARGET_REDUCTION or more: on a rig with noise
  no prediction removes the noise), and the case's seconds; a case is right when every visible true effect is named
  and nothing false is.

Totals: the share of true effects named (with families, and strictly), the cases whose effects close at
least TARGET_REDUCTION of the held-out gap, the false effects, and per true effect how often it is named and what
is named instead where it is not.

The cases are written (logs and oracle) and diagnosed on a Dask cluster, one case per task
(:mod:`benchmarks.diagnosis.shards`; each case diagnosed with one worker process): ``--scheduler ADDRESS`` for an
existing cluster (its workers must import this repository and see ``OUT``), else a local cluster of ``--workers``
single-threaded processes (default one per core). Writes ``OUT/suite/`` (case folders, ``answers.json``),
``OUT/reports/<case>/``, and as the cases finish ``OUT/results.json`` (one row per case and the totals),
``OUT/results.md`` (the table), ``OUT/verdicts.json`` (suite ``mixtures``, the rows every suite writes: compare two
runs with ``python benchmarks/diagnosis/shards.py OLD/verdicts.json NEW/verdicts.json`` or
``benchmarks/diagnosis/verdict_table.py --independent OUT``) and ``OUT/config.json`` (argv, options, seeds,
workers, versions, the package files changed since the commit).

Run from the repository root: ``PYTHONPATH=. python benchmarks/diagnosis/mixtures.py --out runs/mixtures``
(``--quick``: the three named mixtures, ``a`` and ``b`` on the Lund-like rig and ``c`` on the QUBE-like one;
``--only WORD ...``: the cases whose name holds a word, e.g. ``stribeck`` or ``qube``; ``--suite DIR``: reuse the
logs and oracle of an earlier run's suite folder; ``--generate-only``: write the suite and stop; ``--rescore``: score
the reports already in ``OUT/reports`` again).
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import benchmarks
from benchmarks.diagnosis import independent as di
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
from furuta_drake.sweep import dask_client

SUITE = "mixtures"  # the suite's name in verdicts.json
VISIBLE = 1.5  # [counts] an effect whose removal changes the logged angles by less is not visible on its own
TARGET_REDUCTION = 0.95  # share of the held-out gap the effects should close
SEEDS = di.SEEDS  # base seeds of the train and held-out runs (a case adds 100 x its seed)
UNIFORM = 0.02  # an inertia error whose four scales of a, b, c, d agree within this is a uniform scaling

SHORT = {  # an effect's short name in a case's name
    "arm_coulomb_friction": "coulomb",
    "arm_stribeck": "stribeck",
    "friction_asymmetry": "asymmetric",
    "arm_viscous_friction": "viscous",
    "pendulum_friction": "pendulum",
    "input_delay": "delay",
    "actuator_lag": "lag",
    "torque_gain_error": "gain",
    "arm_spring": "spring",
    "inertia_mismatch": "inertia",
    "measurement_noise": "noise",
    "encoder_quantization": "encoder",
}

COULOMB_FORMS = {"karnopp": "karnopp", "tanh": "tanh", "sign_band": "band"}  # the Coulomb friction's form, short

# The families: a true effect counts as named when a member of its family is named; a named member of a true
# effect's family is never a false effect. Every other effect is a family of its own.
FAMILIES = (
    (
        frozenset({"arm_coulomb_friction", "arm_stribeck", "friction_asymmetry"}),
        "the arm's Coulomb-family friction: the vocabulary's variants of one law (SAME_LAW), the same Coulomb level at "
        "speed, with a breakaway curve or a level per direction near zero speed; one model never holds two",
    ),
    (
        frozenset({"input_delay", "actuator_lag"}),
        "the command's timing: at the frequencies the logs excite (up to about 10 Hz) a transport delay T and a "
        "first-order lag of time constant T shift the command by the same time (exp(-sT) and 1/(1 + sT) agree to "
        "first order in sT, differing by about (sT)^2/2: 2 % of the command at 5 Hz and 6 ms), and the report names "
        "them confusable when its bootstrap cannot tell them apart; the true form is checked strictly beside it",
    ),
    (
        frozenset({"torque_gain_error", "inertia_mismatch"}),
        "a confounded pair: a torque gain g is the same model as all of a, b, c, d (and every fitted torque) scaled "
        "by 1/g; an inertia error names a true gain, a gain names a true inertia error only when its four scales "
        "agree within UNIFORM (a uniform scaling), and neither is false beside the other",
    ),
)


def family(name: str) -> frozenset[str]:
    """The effects of ``name``'s family (``name`` alone for most effects)."""
    return next((members for members, _ in FAMILIES if name in members), frozenset({name}))


def uniform_inertia(effect: dict) -> bool:
    """Whether a true inertia error scales a, b, c and d alike (what a torque gain can stand for)."""
    scales = list(effect["params"].values())
    return max(scales) / min(scales) - 1.0 <= UNIFORM


def named_as(effect: dict, found: list[str]) -> str | None:
    """The named effect that names the true ``effect``: itself, else a member of its family (a gain for an inertia
    error only when that error is a uniform scaling); None when none does."""
    if effect["name"] in found:
        return effect["name"]
    for other in sorted(family(effect["name"]) - {effect["name"]}):
        if other not in found:
            continue
        if effect["name"] == "inertia_mismatch" and other == "torque_gain_error" and not uniform_inertia(effect):
            continue
        return other
    return None


# --- the suite ------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Mixture:
    """A rig with several true effects: its id (a letter: the mixture), the rig, the effects as
    :func:`benchmarks.diagnosis.independent.make_case` takes them ((function, args...) tuples) and the seed."""

    key: str
    rig: str
    effects: tuple
    seed: int

    def case(self, without: int | None = None) -> di.Case:
        """The case, or its world with the effect at index ``without`` removed (the others' sizes are stated in
        the nominal rig's units, so they stay the same)."""
        kept = [effect for i, effect in enumerate(self.effects) if i != without]
        return di.make_case(self.rig, *kept, seed=self.seed)

    @property
    def name(self) -> str:
        shorts = "+".join(
            f"coulomb-{COULOMB_FORMS[e.form]}" if e.name == "arm_coulomb_friction" else SHORT[e.name]
            for e in self.case().effects
        )
        return f"{self.rig}__{self.key}_{shorts}__s{self.seed}"


STRIBECK = ("stribeck", 0.04, {"static": 0.1, "stribeck_velocity": 0.1, "smoothing": 0.01})
KARNOPP = ("karnopp", 0.06, {"breakaway": 1.25})
ASYMMETRIC = ("tanh", 0.05, {"neg_level": 0.09, "smoothing": 0.02})
TANH = ("tanh", 0.05, {"smoothing": 0.02})
SIGN_BAND = ("sign_band", 0.05, {"smoothing": 0.002})  # in one mixture: in others tried (beside pendulum
# friction; on the QUBE-like rig with a spring, a gain and noise) the simulator's hybrid law switched modes more often
# within a sample than it allows
NOISE = 1.3  # [counts] the noise of a rig with noise: about a count, and visible on its own


PENDULUM = (di.pendulum_friction, 0.004, 0.3)
# Each mixture: its key and its effects, as (the independent suite's effect function, its arguments...).
LUND_MIXTURES = [
    ("a", (di.arm_friction, *STRIBECK), PENDULUM, (di.lag, "inductance", 0.006), (di.spring, 0.25, {"offset": 0.05})),
    (
        "b",
        (di.arm_friction, *KARNOPP),
        (di.arm_viscous, 1.5),
        PENDULUM,
        (di.delay, 3),
        (di.spring, 0.25, {"offset": 0.05}),
    ),
    ("c", (di.arm_friction, *ASYMMETRIC), (di.delay, 3), (di.inertia, {"pendulum_mass": 1.15}), (di.noise, NOISE)),
    (
        "d",
        (di.arm_friction, *TANH),
        (di.arm_viscous, 1.0),
        PENDULUM,
        (di.lag, "filter", 0.008),
        (di.gain, 0.85),
        (di.coarse_encoder, 1024),
    ),
    (
        "e",
        (di.arm_friction, *SIGN_BAND),
        (di.arm_viscous, 1.0),
        (di.delay, 2),
        (di.inertia, {"pendulum_mass": 1.1, "arm_inertia": 0.9}),
        (di.spring, 0.15, {"cubic": 0.5}),
    ),
    (
        "f",
        (di.arm_friction, *STRIBECK),
        (di.arm_viscous, 1.5),
        (di.gain, 1.15),
        (di.spring, 0.25),
        (di.noise, NOISE),
    ),
    (
        "g",
        (di.arm_friction, *KARNOPP),
        PENDULUM,
        (di.lag, "inductance", 0.004),
        (di.inertia, {"pendulum_mass": 1.1, "pendulum_com": 1.05}),
        (di.gain, 0.9),
    ),
]
QUBE_MIXTURES = [
    ("a", (di.arm_friction, *STRIBECK), PENDULUM, (di.lag, "inductance", 0.005), (di.spring, 0.1, {"cubic": 0.3})),
    (
        "b",
        (di.arm_friction, "tanh", 0.08, {"smoothing": 0.02}),
        (di.arm_viscous, 0.5),
        PENDULUM,
        (di.delay, 2),
        (di.spring, 0.1),
    ),
    ("c", (di.arm_friction, *ASYMMETRIC), (di.delay, 2), (di.inertia, {"pendulum_mass": 1.15}), (di.noise, NOISE)),
    (
        "d",
        (di.arm_friction, *KARNOPP),
        (di.arm_viscous, 0.5),
        (di.lag, "filter", 0.006),
        (di.inertia, {"pendulum_mass": 1.1, "arm_inertia": 1.2}),
        (di.coarse_encoder, 512),
    ),
    (
        "e",
        (di.arm_friction, *ASYMMETRIC),
        PENDULUM,
        (di.delay, 2),
        (di.gain, 1.15),
        (di.spring, 0.1),
        (di.noise, NOISE),
    ),
    (
        "f",
        (di.arm_friction, "karnopp", 0.05, {"neg_level": 0.08, "breakaway": 1.25}),
        (di.arm_viscous, 0.5),
        (di.gain, 0.85),
        (di.spring, 0.1),
        (di.noise, NOISE),
    ),
    (
        "g",
        (di.arm_friction, *STRIBECK),
        PENDULUM,
        (di.lag, "inductance", 0.004),
        (di.inertia, {"pendulum_mass": 1.15, "arm_inertia": 1.1}),
        (di.noise, NOISE),
    ),
]


def all_mixtures() -> list[Mixture]:
    """The suite (see the module docstring): mixtures a-g on each rig."""
    rows = [("lund", row) for row in LUND_MIXTURES] + [("qube", row) for row in QUBE_MIXTURES]
    return [Mixture(key, rig, tuple(effects), seed) for seed, (rig, (key, *effects)) in enumerate(rows, start=1)]


QUICK = ("lund__a_", "lund__b_", "qube__c_")


def select(mixtures: list[Mixture], quick: bool, only: list[str] | None) -> list[Mixture]:
    if quick:
        return [next(m for m in mixtures if m.name.startswith(prefix)) for prefix in QUICK]
    if only:
        return [m for m in mixtures if any(word in m.name for word in only)]
    return mixtures


# --- the oracle -----------------------------------------------------------------------------------------------


def runs(case: di.Case, duration: float) -> list[tuple[str, sim.RunSpec]]:
    """The case's four runs as :func:`benchmarks.diagnosis.independent.write_case` records them: (log name, run)."""
    out = []
    for split, base in SEEDS.items():
        seed = base + 100 * case.seed
        for run in (sim.balance_run(duration, seed), sim.hanging_run(duration, seed + 1)):
            out.append((f"{split}_{run.kind}", run))
    return out


def visibility(mixture: Mixture, logged: dict[str, np.ndarray], duration: float) -> list[dict]:
    """Per effect of ``mixture``: the RMS difference [counts of the rig file's encoder] between the logged angles of
    the case (``logged``: log name -> (n, 2) measured [theta, phi]) and those of the same runs with that effect
    removed, over the four logs and by log; and whether a removed world's balancing run fell."""
    case = mixture.case()
    count = 2 * math.pi / case.world.rig.counts_per_rev
    out = []
    for index, effect in enumerate(case.effects):
        without = mixture.case(without=index)
        by_log, squares, samples, fell = {}, 0.0, 0, []
        for name, run in runs(without, duration):
            log = sim.simulate(without.world, run)
            difference = (logged[name] - log.measured) / count
            by_log[name] = float(np.sqrt(np.mean(np.square(difference))))
            squares, samples = squares + float(np.sum(np.square(difference))), samples + difference.size
            if run.kind == "balance" and log.fell:
                fell.append(name)
        out.append(
            {
                "effect": effect.name,
                "visible_counts": math.sqrt(squares / samples),
                "visible_counts_by_log": by_log,
                "fell_without": fell,
            }
        )
    return out


def read_angles(path: Path) -> np.ndarray:
    """The measured [theta, phi] [rad] of a written log."""
    return np.loadtxt(path, delimiter=",", skiprows=1, usecols=(1, 2), ndmin=2)


def write_mixture(mixture: Mixture, folder: Path, duration: float) -> dict:
    """Write the case's folder (:func:`benchmarks.diagnosis.independent.write_case`) and return its answer with the
    oracle's visibility of every effect."""
    case = dataclasses.replace(mixture.case(), name=mixture.name)
    answer = di.write_case(case, folder, duration)
    logged = {name: read_angles(folder / f"{name}.csv") for name, _ in runs(case, duration)}
    seen = visibility(mixture, logged, duration)
    for effect, oracle in zip(answer["effects"], seen):
        effect["visible_counts"] = oracle["visible_counts"]
        effect["visible_counts_by_log"] = oracle["visible_counts_by_log"]
        effect["fell_without"] = oracle["fell_without"]
        effect["visible"] = oracle["visible_counts"] >= VISIBLE
    answer["mixture"] = mixture.key
    return answer


def _write_mixture(task: tuple[Mixture, Path, float]) -> dict:
    """A task: write one case folder and its oracle; its answer."""
    mixture, suite, duration = task
    return write_mixture(mixture, suite / "cases" / mixture.name, duration)


def generate(mixtures: list[Mixture], suite: Path, duration: float, client) -> list[dict]:
    """Write every case folder under ``suite/cases`` and ``suite/answers.json`` on ``client``'s cluster, one case
    per task; a line per case as it finishes. A case whose runs cannot be simulated (e.g. the simulator's hybrid
    friction law switching too often) is reported with the others' and stops the run before the diagnosis."""
    answers: list[dict | None] = [None] * len(mixtures)
    failed = []

    def finished(done: int, total: int, index: int, outcome: Outcome) -> None:
        if outcome.error is not None:
            failed.append(f"{mixtures[index].name}: {outcome.error}")
            print(f"  [{done}/{total}] {mixtures[index].name}: FAILED {outcome.error}", flush=True)
            return
        answer = answers[index] = outcome.value
        fell = [k for k, v in answer["balance_fell"].items() if v]
        hidden = [e["name"] for e in answer["effects"] if not e["visible"]]
        print(
            f"  [{done}/{total}] {answer['case']}: {outcome.seconds:.0f} s"
            + (f"  BALANCE FELL in {', '.join(fell)}" if fell else "")
            + (f"  NOT VISIBLE: {', '.join(hidden)}" if hidden else ""),
            flush=True,
        )
        suite.mkdir(parents=True, exist_ok=True)
        (suite / "answers.json").write_text(json.dumps([a for a in answers if a is not None], indent=2) + "\n")

    shard(client, _write_mixture, [(m, suite, duration) for m in mixtures], finished)
    if failed:
        raise RuntimeError("logs that could not be written:\n" + "\n".join(failed))
    return answers


def effect_label(effect: dict) -> str:
    return f"{effect['name']}[{effect['form']}]"


def visibility_table(answers: list[dict]) -> str:
    """Every effect's oracle visibility: all four logs, and balancing / hanging (train and held-out together)."""
    lines = [
        "| case | effect [form] | visible [counts] | balancing | hanging | on its own |",
        "|---|---|---|---|---|---|",
    ]
    for answer in answers:
        for effect in answer["effects"]:
            by_log = effect["visible_counts_by_log"]
            kinds = {
                kind: math.sqrt(np.mean([v**2 for k, v in by_log.items() if k.endswith(kind)]))
                for kind in ("balance", "hanging")
            }
            lines.append(
                f"| {answer['case']} | {effect_label(effect)} | {effect['visible_counts']:.2f} | "
                f"{kinds['balance']:.2f} | {kinds['hanging']:.2f} | {'yes' if effect['visible'] else 'NO'} |"
            )
    return "\n".join(lines) + "\n"


# --- scoring --------------------------------------------------------------------------------------------------


def _timing_at_most_a_sample(name: str, params: dict, period: float) -> bool:
    """Whether an accepted input delay or actuator lag (``name``) is fitted at one sample ``period`` or less in the
    final model's ``params`` (prefixed with the effect's name when the model holds several)."""
    key = {"input_delay": "delay", "actuator_lag": "time_constant"}[name]
    value = params.get(f"{name}.{key}", params.get(key))
    return isinstance(value, (int, float)) and value <= period * (1 + 1e-6)


def stated_limit(effect: dict, report: dict) -> dict | None:
    """The detection limit the report states for a missed true effect, and whether the truth is above it (None
    where the truth has no parameter of that name, e.g. an inertia error's other scales; False where the report
    found it undetectable even at the end of its search range, ``limit`` None)."""
    limit = next((d for d in report.get("detection_limits") or [] if d["effect"] == effect["name"]), None)
    if limit is None:
        return None
    truth, value = effect["params"].get(limit["param"]), limit["value"]
    if not isinstance(truth, (int, float)):
        above = None
    elif value is None:
        above = False
    elif effect["name"] == "encoder_quantization":
        above = truth <= value  # a coarser encoder than the limit's
    elif effect["name"] in ("torque_gain_error", "inertia_mismatch"):
        above = abs(truth - 1.0) >= abs(value - 1.0)
    else:
        above = abs(truth) >= abs(value)
    return {"param": limit["param"], "limit": value, "true": truth, "above": above, "note": limit.get("note", "")}


SIGNATURE = re.compile(r"(\w+) is accepted on its signature")  # a sensor effect's acceptance in ``choice``


def named_effects(report: dict) -> tuple[list[str], list[str]]:
    """The effects the report names: ``effects`` and, beside a torque beyond the vocabulary, the effects kept beside
    it (``beside_torque``, as :func:`benchmarks.diagnosis.independent.is_right` reads them); and those beside it."""
    beside = list((report.get("beside_torque") or {}).get("effects", []))
    return list(dict.fromkeys([*report["effects"], *beside])), beside


def score(answer: dict, report: dict, seconds: float, period: float) -> dict:
    """One results row: the true effects named, missed and the false effects (module docstring)."""
    found, beside = named_effects(report)
    signature_only = [name for name in SIGNATURE.findall(report.get("choice") or "") if name not in found]
    outside = [f"unmodelled_torque[{joint}]" for joint in report.get("unmodelled_torque") or {}]
    truths = answer["effects"]
    true_names = {e["name"] for e in truths}
    has_timing = bool(true_names & family("input_delay"))
    effects = []
    for effect in truths:
        by = named_as(effect, found)
        effects.append(
            {
                "name": effect["name"],
                "form": effect["form"],
                "visible_counts": effect["visible_counts"],
                "visible": effect["visible"],
                "named_as": by,
                "exact": by == effect["name"],
                "beside_torque": by is not None and by in beside and by not in report["effects"],
                "signature_only": by is None and effect["name"] in signature_only,
                "stated_limit": None if by is not None else stated_limit(effect, report),
            }
        )
    covered = set().union(*(family(name) for name in true_names)) if true_names else set()
    fitted = di.fitted_params(report)
    false, tolerated = [], []
    for name in found:
        if name in covered:
            continue
        if not has_timing and name in family("input_delay") and _timing_at_most_a_sample(name, fitted, period):
            tolerated.append(name)
        else:
            false.append(name)
    false += outside
    needed = [e for e in effects if e["visible"]]
    named = [e for e in needed if e["named_as"] is not None]
    right = len(named) == len(needed) and not false
    return {
        "case": answer["case"],
        "rig": answer["rig"],
        "mixture": answer.get("mixture"),
        "expected": answer["expected"],
        "truth": effects,
        "verdict": report["verdict"],
        "effects": report["effects"],
        "beside_torque": beside,
        "signature_only": signature_only,
        "named": len(named),
        "named_exact": sum(e["exact"] for e in named),
        "needed": len(needed),
        "missed": [e["name"] for e in needed if e["named_as"] is None],
        "false": false,
        "tolerated": tolerated,
        "right": right,
        "confusable": [p["effects"] for p in report.get("confusable") or []],
        "steps": [[s["effect"], s["reduction_over_previous"]] for s in report.get("steps") or []],
        "fitted": fitted,
        "heldout_reduction": report["gap"]["heldout_reduction"],
        "closed": closed_share(report["gap"]),
        "nominal_heldout_gap": report["gap"]["nominal"]["heldout"],
        "final_heldout_gap": report["gap"]["with_effects"]["heldout"],
        "balance_fell": answer["balance_fell"],
        "seconds": seconds,
    }


def closed_share(gap: dict) -> float:
    """The share of the nominal held-out gap the accepted effects close: 1 - sqrt(1 - P - S), P the share of the
    nominal mean squared excess the predictions remove (from ``heldout_reduction``), S the share an accepted sensor
    effect accounts for (``sensor_share``, each passing its own held-out test). On a rig with noise no prediction
    removes the noise's part, so the predictions' own reduction cannot reach the target there."""
    predicted = 1.0 - (1.0 - gap["heldout_reduction"]) ** 2
    return 1.0 - float(np.sqrt(max(1.0 - predicted - (gap.get("sensor_share") or 0.0), 0.0)))


def error_row(answer: dict, error: str, seconds: float | None) -> dict:
    """The row of a case whose diagnosis raised: nothing named, every visible effect missed."""
    needed = [e for e in answer["effects"] if e["visible"]]
    return {
        "case": answer["case"],
        "rig": answer["rig"],
        "mixture": answer.get("mixture"),
        "expected": answer["expected"],
        "truth": [
            {
                "name": e["name"],
                "form": e["form"],
                "visible_counts": e["visible_counts"],
                "visible": e["visible"],
                "named_as": None,
                "exact": False,
                "beside_torque": False,
                "signature_only": False,
                "stated_limit": None,
            }
            for e in answer["effects"]
        ],
        "verdict": f"ERROR {error}"[:200],
        "effects": [],
        "beside_torque": [],
        "signature_only": [],
        "named": 0,
        "named_exact": 0,
        "needed": len(needed),
        "missed": [e["name"] for e in needed],
        "false": [],
        "tolerated": [],
        "right": False,
        "confusable": [],
        "steps": [],
        "fitted": {},
        "heldout_reduction": None,
        "closed": None,
        "nominal_heldout_gap": None,
        "final_heldout_gap": None,
        "balance_fell": answer["balance_fell"],
        "seconds": seconds,
    }


def totals(rows: list[dict]) -> dict:
    """The suite's figures: shares named (families / strict), cases at the target, false effects, and per true
    effect how often it is named and what is named in its place when it is not."""
    needed = sum(r["needed"] for r in rows)
    done = [r for r in rows if r["heldout_reduction"] is not None]
    per_effect: dict[str, dict] = {}
    for row in rows:
        for effect in row["truth"]:
            if not effect["visible"]:
                continue
            entry = per_effect.setdefault(effect["name"], {"cases": 0, "named": 0, "exact": 0, "instead": {}})
            entry["cases"] += 1
            entry["named"] += effect["named_as"] is not None
            entry["exact"] += effect["exact"]
            if effect["named_as"] is None:
                for other in row["false"] or ["-"]:
                    entry["instead"][other] = entry["instead"].get(other, 0) + 1
    false = {}
    for row in rows:
        for name in row["false"]:
            false[name] = false.get(name, 0) + 1
    return {
        "cases": len(rows),
        "right": sum(r["right"] for r in rows),
        "effects": needed,
        "named": sum(r["named"] for r in rows),
        "named_share": sum(r["named"] for r in rows) / needed if needed else None,
        "named_exact": sum(r["named_exact"] for r in rows),
        "named_exact_share": sum(r["named_exact"] for r in rows) / needed if needed else None,
        "all_named_cases": sum(r["named"] == r["needed"] for r in rows),
        "at_target": sum(r["closed"] >= TARGET_REDUCTION for r in done),
        "median_closed": float(np.median([r["closed"] for r in done])) if done else None,
        "target_reduction": TARGET_REDUCTION,
        "median_heldout_reduction": float(np.median([r["heldout_reduction"] for r in done])) if done else None,
        "min_heldout_reduction": min((r["heldout_reduction"] for r in done), default=None),
        "false_effects": sum(len(r["false"]) for r in rows),
        "false_by_effect": false,
        "tolerated": sum(len(r["tolerated"]) for r in rows),
        "seconds_per_case": float(np.mean([r["seconds"] for r in rows if r["seconds"] is not None])) if rows else None,
        "per_effect": per_effect,
    }


def _percent(value) -> str:
    return "-" if value is None else f"{100 * value:.0f} %"


def markdown(rows: list[dict], figures: dict) -> str:
    """The results table, the totals and the per-effect table."""
    lines = [
        "| case | true effects (visible counts) | named | missed | false | held-out removed | closed | s |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        truth = ", ".join(
            f"{e['name']}[{e['form']}] ({e['visible_counts']:.1f}{'' if e['visible'] else ', hidden'})"
            for e in r["truth"]
        )
        named = ", ".join(
            (e["name"] if e["exact"] else f"{e['name']}~{e['named_as']}")
            + (" (beside torque)" if e["beside_torque"] else "")
            for e in r["truth"]
            if e["named_as"]
        )
        missed = []
        for e in r["truth"]:
            if e["visible"] and e["named_as"] is None:
                limit = e["stated_limit"]
                above = "" if limit is None or limit["above"] is None else (" >lim" if limit["above"] else " <lim")
                missed.append(f"{e['name']}{above}{' (choice only)' if e['signature_only'] else ''}")
        false = ", ".join(r["false"] + [f"({n}, tolerated)" for n in r["tolerated"]])
        seconds = "-" if r["seconds"] is None else f"{r['seconds']:.0f}"
        lines.append(
            f"| {r['case']} | {truth} | {r['named']}/{r['needed']}: {named or '-'} | {', '.join(missed) or '-'} | "
            f"{false or '-'} | {_percent(r['heldout_reduction'])} | {_percent(r['closed'])} | {seconds} |"
        )
    f = figures
    lines += [
        "",
        f"True effects named: {f['named']}/{f['effects']} ({_percent(f['named_share'])}; exact names "
        f"{f['named_exact']}/{f['effects']}, {_percent(f['named_exact_share'])}); cases with every effect named: "
        f"{f['all_named_cases']}/{f['cases']}; right (all named, nothing false): {f['right']}/{f['cases']}.",
        f"Cases whose effects close >= {_percent(f['target_reduction'])} of the held-out gap: {f['at_target']}/"
        f"{f['cases']} (median {_percent(f['median_closed'])}); the predictions alone remove a median "
        f"{_percent(f['median_heldout_reduction'])}, lowest {_percent(f['min_heldout_reduction'])}.",
        f"False effects: {f['false_effects']} {json.dumps(f['false_by_effect'])}; tolerated one-sample timing: "
        f"{f['tolerated']}. Seconds per case: "
        f"{'-' if f['seconds_per_case'] is None else format(f['seconds_per_case'], '.0f')}.",
        "",
        "Named variants show as true~named; '(beside torque)': named beside a torque beyond the vocabulary "
        "(`beside_torque`); '>lim' / '<lim': the truth above / below the detection limit the report states for the "
        "missed effect; '(choice only)': a sensor effect the report's `choice` says is accepted on its signature, "
        "absent from `effects`; unmodelled_torque[joint]: a torque beyond the vocabulary claimed at that joint.",
        "",
        "| true effect | cases | named | exact | false effects in the cases it is missed |",
        "|---|---|---|---|---|",
    ]
    for name, e in sorted(f["per_effect"].items()):
        instead = ", ".join(f"{k} x{v}" for k, v in sorted(e["instead"].items())) or "-"
        lines.append(f"| {name} | {e['cases']} | {e['named']} | {e['exact']} | {instead} |")
    return "\n".join(lines) + "\n"


def write_results(out: Path, rows: list[dict], pending: int) -> None:
    """results.json, results.md and verdicts.json as they stand (``pending`` cases still to run)."""
    figures = totals(rows)
    (out / "results.json").write_text(
        json.dumps({"totals": figures, "pending": pending, "rows": rows}, indent=2) + "\n"
    )
    (out / "results.md").write_text(markdown(rows, figures))
    write_verdicts(out / "verdicts.json", verdict_rows(SUITE, rows))


def _diagnose_case(task: tuple[dict, Path, Path]) -> dict:
    """A task: diagnose one case folder blind; its results row."""
    answer, suite, out = task
    folder = suite / "cases" / answer["case"]
    report, seconds = di.diagnose_blind(folder, out / "reports" / answer["case"])
    period = sim.RIGS[answer["rig"]]().sample_period
    return score(answer, report, seconds, period)


def diagnose_all(answers: list[dict], suite: Path, out: Path, client) -> list[dict]:
    """Diagnose every case on ``client``'s cluster, one case per task; a line per case and the results written as
    each finishes; the rows in the answers' order."""
    rows: list[dict | None] = [None] * len(answers)

    def finished(done: int, total: int, index: int, outcome: Outcome) -> None:
        failed = outcome.error is not None
        row = rows[index] = error_row(answers[index], outcome.error, outcome.seconds) if failed else outcome.value
        seconds = "-" if row["seconds"] is None else f"{row['seconds']:.0f}"
        print(
            f"[{done}/{total}] {row['case']}: named {row['named']}/{row['needed']}, missed {row['missed'] or '-'}, "
            f"false {row['false'] or '-'}, removes {_percent(row['heldout_reduction'])} ({seconds} s)"
            + (f" {row['verdict']}" if failed else ""),
            flush=True,
        )
        write_results(out, [r for r in rows if r is not None], total - done)

    start = time.perf_counter()
    outcomes = shard(client, _diagnose_case, [(answer, suite, out) for answer in answers], finished)
    print(speed_up_line(outcomes, time.perf_counter() - start, worker_count(client)))
    return rows


def rescore(out: Path, suite: Path, mixtures: list[Mixture]) -> int:
    """Score the reports in ``out/reports`` again (their seconds read from ``out/results.json``) and rewrite the
    results; the cases of ``mixtures`` that have a report."""
    answers = {a["case"]: a for a in json.loads((suite / "answers.json").read_text())}
    seconds = {r["case"]: r["seconds"] for r in json.loads((out / "results.json").read_text())["rows"]}
    rows = []
    for mixture in mixtures:
        path = out / "reports" / mixture.name / "report.json"
        if mixture.name not in answers or not path.exists():
            continue
        period = sim.RIGS[mixture.rig]().sample_period
        report = json.loads(path.read_text())
        rows.append(score(answers[mixture.name], report, seconds.get(mixture.name), period))
    write_results(out, rows, 0)
    print(markdown(rows, totals(rows)))
    return 0


def changed_package_files() -> list[str]:
    """The package's files that differ from the commit (a run on a tree being edited says so)."""
    root = Path(benchmarks.__file__).resolve().parent.parent  # the repository holding this script
    status = subprocess.run(
        ["git", "status", "--porcelain", "--", "furuta_drake"], cwd=root, capture_output=True, text=True
    )
    return [line[3:] for line in status.stdout.splitlines() if line.strip()]


def main(argv: list[str] | None = None) -> int:
    parser = suite_parser(__doc__.splitlines()[0], f"{len(QUICK)} cases: the issue's mixtures a, b, c")
    parser.add_argument("--rescore", action="store_true", help="score the reports already in OUT/reports again")
    args = parser.parse_args(argv)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    mixtures = select(all_mixtures(), args.quick, args.only)
    if not mixtures:
        parser.error("no case matches")
    if args.rescore:
        return rescore(out, args.suite or out / "suite", mixtures)
    with dask_client(args.scheduler, args.workers, len(mixtures)) as client:
        if args.suite is not None:
            suite = args.suite
            by_name = {a["case"]: a for a in json.loads((suite / "answers.json").read_text())}
            missing = [m.name for m in mixtures if m.name not in by_name]
            if missing:
                parser.error(f"--suite {suite}: no answers for {', '.join(missing)}")
            answers = [by_name[m.name] for m in mixtures]
        else:
            suite = out / "suite"
            print(f"simulating {len(mixtures)} cases and their oracle ({args.duration:g} s logs) into {suite}")
            answers = generate(mixtures, suite, args.duration, client)
        print()
        print(visibility_table(answers))
        (out / "config.json").write_text(
            json.dumps(
                {
                    "argv": sys.argv[1:] if argv is None else argv,
                    "suite": str(suite),
                    "duration_s": args.duration,
                    "quick": args.quick,
                    "only": args.only,
                    "workers": worker_count(client),
                    "scheduler": args.scheduler,
                    "run_seeds": SEEDS,
                    "cases": {m.name: m.seed for m in mixtures},
                    "visible_counts": VISIBLE,
                    "target_reduction": TARGET_REDUCTION,
                    "families": [{"effects": sorted(members), "why": why} for members, why in FAMILIES],
                    "versions": di.versions(),
                    "package_files_changed": changed_package_files(),
                },
                indent=2,
            )
            + "\n"
        )
        if args.generate_only:
            return 0
        rows = diagnose_all(answers, suite, out, client)
    figures = totals(rows)
    print()
    print(markdown(rows, figures))
    return 0


if __name__ == "__main__":
    sys.exit(main())
