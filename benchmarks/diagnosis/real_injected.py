"""Real logs with a known effect written into them: does ``diagnose`` name it?

Real logs carry an unknown mix of effects, but a known one can be added to them. The QUBE-Servo 2 logs in
``data/qube-servo2-real`` are voltage-driven; the model maps a voltage to the arm torque tau = kt (V - ke phi_dot)
/ R. So:

- a torque-level effect g(state) on the arm (the torque it exerts: viscous -b phi_dot, Coulomb -Fc sign(phi_dot),
  a spring -k (phi - phi_0), cogging A sin(N phi)) is written as V' = V - (R / kt) g(state), with phi and
  phi_dot from a Savitzky-Golay fit of the logged angles: a model fed V' needs the extra torque g to give back the
  logged motion, so the data look like a rig with that effect;
- an input delay of n samples shifts the logged command n samples earlier (the log's last n rows are dropped);
- a gain error g divides the command; a dead zone of width w (its subtract form) adds its inverse, V + w sign(V);
- a first-order lag tau is undone at the samples: V'[k] = (V[k + 1] - e V[k]) / (1 - e), e = exp(-T / tau), so
  that the lag's output at each sample is the logged command (between samples it is not: approximately a lag);
- a coarser encoder re-quantises the angles on a k times coarser grid; noise is added to them;
- an inertia error perturbs the rig file instead of the data.

Each case is diagnosed with the rig file (perturbed for the inertia case) on the same train and held-out logs
as the untouched baseline, whose own effects stay in the data: an injected effect is named when it is in the
report's ``effects`` (beside whatever the baseline needs; a variant of its law counts, as asymmetric friction
for Coulomb friction: the rig's own friction adds to the injected one); cogging, outside the vocabulary, is right
when the gap is ``unexplained`` or no effect beyond the baseline's is named for it. Sizes scale with the rig
(fractions of m g l and of the sample period), as the validation suite's do, and ``--scale`` multiplies them all.

Each row also sets the injected size against the detection limit the baseline's report states for that effect
(``size_over_limit``): an effect injected below the limit these very logs can show is expected to be missed, and
the summary counts the cases at or above it apart.

Every case is then diagnosed a second time *continued from the baseline*: with the case's rig file plus the
``effects:`` the baseline's ``fitted_rig.yaml`` holds, as a user who has diagnosed their rig once goes on from the
corrected model. The baseline's own effects are then stated, not searched for, so the injected effect need not
compete with them for the three places (the baseline already needs three) nor be absorbed by one of them (a lag
by the baseline's delay, a torque gain by its inertia scales). Named there means: in ``effects``; cogging is
right when the verdict is ``unexplained`` or names no effect.

Run from the repository root: ``PYTHONPATH=. python benchmarks/diagnosis/real_injected.py --out runs/injected``. Writes
``OUT/results.json`` (one row per case) and ``OUT/config.json``; prints the table. ``--rescore`` scores the
reports already in ``OUT/reports`` again without diagnosing.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.signal import savgol_filter

from furuta_drake.data import QUBE_REAL_DIR, QUBE_REAL_RIG
from furuta_drake.diagnosis.pipeline import diagnose
from furuta_drake.diagnosis.report.files import write_report
from furuta_drake.effects.vocabulary import law_of
from furuta_drake.outputs import versions
from furuta_drake.rig import RigParameters, encoder_resolution
from furuta_drake.rig_file import load_rig
from furuta_drake.yamlio import dump_yaml_dataclass

TRAIN = ("swingup_250Hz_10s_a.csv", "chirp_10to0Hz_pos1p5V_250Hz_10s.csv")
HELDOUT = ("swingup_250Hz_7s_negdir.csv", "swingup_250Hz_5s_0414.csv")
SMOOTHING_S = 0.04  # Savitzky-Golay window of the angles and their derivative [s]


@dataclass(frozen=True)
class Injection:
    """One case: the effect's vocabulary name (or cogging), its size and what it does to a log's columns or to the
    rig file."""

    name: str
    size: str
    data: Callable[[dict, RigParameters], dict] | None = None  # log columns -> log columns
    rig: Callable[[RigParameters], RigParameters] | None = None
    value: float | None = None  # the size in the unit of the effect's detection limit (its main parameter)


def size_over_limit(name: str, value: float | None, limit: float | None) -> float | None:
    """How many times its detection limit an injected size is (a gain's distance from 1; an encoder's coarseness)."""
    if value is None or limit is None:
        return None
    if name == "torque_gain_error":
        return abs(value - 1.0) / abs(limit - 1.0)
    if name == "encoder_quantization":
        return limit / value
    return value / limit


def _read(path: Path) -> dict[str, np.ndarray]:
    table = np.genfromtxt(path, delimiter=",", names=True)
    return {name: np.asarray(table[name], float) for name in table.dtype.names}


def _write(columns: dict[str, np.ndarray], path: Path) -> None:
    names = list(columns)
    np.savetxt(
        path,
        np.column_stack([columns[n] for n in names]),
        delimiter=",",
        header=",".join(names),
        comments="",
        fmt="%.9g",
    )


def _phi_and_rate(columns: dict, rig: RigParameters) -> tuple[np.ndarray, np.ndarray]:
    period = float(np.median(np.diff(columns["time"])))
    window = max(7, int(round(SMOOTHING_S / period)) | 1)
    return (savgol_filter(columns["phi"], window, 3), savgol_filter(columns["phi"], window, 3, deriv=1, delta=period))


def torque_effect(g: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> Callable[[dict, RigParameters], dict]:
    """V' = V - (R / kt) g(phi, phi_dot): the data of a rig whose arm feels the extra torque g [N m]."""

    def inject(columns, rig):
        phi, rate = _phi_and_rate(columns, rig)
        return {
            **columns,
            "voltage": columns["voltage"] - rig.motor.resistance / rig.motor.torque_constant * g(phi, rate),
        }

    return inject


def delay(samples: int) -> Callable[[dict, RigParameters], dict]:
    def inject(columns, rig):
        out = {name: values[:-samples] for name, values in columns.items()}
        out["voltage"] = columns["voltage"][samples:]
        return out

    return inject


def lag(time_constant: float) -> Callable[[dict, RigParameters], dict]:
    def inject(columns, rig):
        decay = np.exp(-float(np.median(np.diff(columns["time"]))) / time_constant)
        voltage = columns["voltage"]
        out = {name: values[:-1] for name, values in columns.items()}
        out["voltage"] = (voltage[1:] - decay * voltage[:-1]) / (1.0 - decay)
        return out

    return inject


def requantise(factor: int) -> Callable[[dict, RigParameters], dict]:
    def inject(columns, rig):
        step = factor * encoder_resolution(rig.counts_per_rev)
        return {
            **columns,
            **{
                name: columns[name][0] + np.round((columns[name] - columns[name][0]) / step) * step
                for name in ("theta", "phi")
            },
        }

    return inject


def noise(counts: float, seed: int = 0) -> Callable[[dict, RigParameters], dict]:
    def inject(columns, rig):
        rng = np.random.default_rng(seed + len(columns["time"]))
        sigma = counts * encoder_resolution(rig.counts_per_rev)
        return {
            **columns,
            **{name: columns[name] + rng.normal(0.0, sigma, columns[name].size) for name in ("theta", "phi")},
        }

    return inject


def injections(rig: RigParameters, scale: float) -> list[Injection]:
    """The cases: sizes scale with m g l, the arm's inertia and the sample period (times ``scale``)."""
    mgl, arm, period, volts = (
        rig.gravity_torque,
        rig.arm_inertia_total,
        rig.sample_period,
        rig.motor.resistance / rig.motor.torque_constant,
    )
    s = scale
    return [
        Injection("baseline", "-"),
        Injection(
            "arm_viscous_friction",
            f"b = {0.8 * s * arm:.3g} N m s/rad",
            torque_effect(lambda phi, rate: -0.8 * s * arm * rate),
            value=0.8 * s * arm,
        ),
        Injection(
            "arm_coulomb_friction",
            f"Fc = {0.1 * s * mgl:.3g} N m",
            torque_effect(lambda phi, rate: -0.1 * s * mgl * np.tanh(rate / 0.05)),
            value=0.1 * s * mgl,
        ),
        Injection(
            "arm_spring",
            f"k = {0.25 * s * mgl:.3g} N m/rad, phi0 = 0.1 rad",
            torque_effect(lambda phi, rate: -0.25 * s * mgl * (phi - 0.1)),
            value=0.25 * s * mgl,
        ),
        Injection(
            "input_delay",
            f"{max(1, round(2 * s))} samples = {max(1, round(2 * s)) * period:.3g} s",
            delay(max(1, round(2 * s))),
            value=max(1, round(2 * s)) * period,
        ),
        Injection("actuator_lag", f"tau = {3 * s * period:.3g} s", lag(3 * s * period), value=3 * s * period),
        Injection(
            "torque_gain_error",
            f"gain = {1 - 0.2 * s:.3g}",
            lambda c, r: {**c, "voltage": c["voltage"] / (1 - 0.2 * s)},
            value=1 - 0.2 * s,
        ),
        Injection(
            "actuator_deadzone",
            f"w = {0.3 * s:.3g} V = {0.3 * s / volts:.3g} N m (subtract)",
            lambda c, r: {**c, "voltage": c["voltage"] + 0.3 * s * np.sign(c["voltage"])},
            value=0.3 * s / volts,
        ),
        Injection(
            "encoder_quantization",
            f"{rig.counts_per_rev // max(2, round(4 * s))} counts/rev",
            requantise(max(2, round(4 * s))),
            value=rig.counts_per_rev // max(2, round(4 * s)),
        ),
        Injection(
            "measurement_noise",
            f"{1.5 * s:.3g} counts",
            noise(1.5 * s),
            value=1.5 * s * encoder_resolution(rig.counts_per_rev),
        ),
        Injection(
            "inertia_mismatch",
            "rig file: pendulum mass x 1.25, arm inertia x 0.8",
            rig=lambda r: r.replace(
                pendulum_mass=r.pendulum_mass * (1 + 0.25 * s), arm_inertia=r.arm_inertia * (1 - 0.2 * s)
            ),
        ),
        Injection(
            "cogging_torque",
            f"A = {0.15 * s * mgl:.3g} N m, 12 per turn",
            torque_effect(lambda phi, rate: 0.15 * s * mgl * np.sin(12 * phi)),
        ),
    ]


def write_case(injection: Injection, rig: RigParameters, folder: Path) -> tuple[Path, list[Path], list[Path]]:
    folder.mkdir(parents=True, exist_ok=True)
    case_rig = injection.rig(rig) if injection.rig else rig
    rig_path = folder / "rig.yaml"
    rig_path.write_text(dump_yaml_dataclass(case_rig))
    paths = {}
    for name in TRAIN + HELDOUT:
        columns = _read(QUBE_REAL_DIR / name)
        if injection.data:
            columns = injection.data(columns, rig)
        _write(columns, folder / name)
        paths[name] = folder / name
    return rig_path, [paths[n] for n in TRAIN], [paths[n] for n in HELDOUT]


def score(injection: Injection, report: dict, baseline: dict, seconds: float | None) -> dict:
    """One row of the table from a case's ``report.json``, judged against the baseline's report: named, and the
    injected size against the detection limit the baseline states for that effect."""
    effects, before = report["effects"], baseline["effects"]
    if injection.name == "cogging_torque":  # right when no vocabulary effect is invented for it
        named = report["verdict"] == "unexplained" or set(effects) <= set(before)
    else:  # named, or a variant of its law (asymmetric friction for Coulomb friction: the rig has its own)
        named = injection.name == "baseline" or any(effect in law_of(injection.name) for effect in effects)
    limit = next((d for d in baseline["detection_limits"] if d["effect"] == injection.name), None)
    same_law = [s["params"] for s in baseline["steps"] if s["effect"] in law_of(injection.name)]
    return {
        "case": injection.name,
        "size": injection.size,
        "verdict": report["verdict"],
        "effects": effects,
        "new_beside_baseline": sorted(set(effects) - set(before)),
        "named": named,
        "heldout_reduction": report["gap"]["heldout_reduction"],
        "fitted": next((s["params"] for s in report["steps"] if s["effect"] in law_of(injection.name)), None),
        "confusable": report.get("confusable", []),
        "in_baseline": injection.name != "baseline" and any(e in law_of(injection.name) for e in before),
        "baseline_fitted": same_law[0] if same_law else None,
        "detection_limit": limit,
        "size_over_limit": size_over_limit(injection.name, injection.value, limit and limit["value"]),
        "seconds": seconds,
    }


def _diagnose(rig_path: Path, train: list[Path], heldout: list[Path], folder: Path, workers) -> float:
    start = time.perf_counter()
    write_report(folder, diagnose(rig=rig_path, train=train, heldout=heldout, workers=workers), force=True)
    return time.perf_counter() - start


def continued(injection: Injection, report: dict) -> dict:
    """One row of the second table: the case diagnosed from the baseline's fitted rig."""
    effects = report["effects"]
    if injection.name == "cogging_torque":
        named = report["verdict"] == "unexplained" or not effects
    else:
        named = any(effect in law_of(injection.name) for effect in effects)
    return {
        "case": injection.name,
        "verdict": report["verdict"],
        "effects": effects,
        "named": named,
        "heldout_reduction": report["gap"]["heldout_reduction"],
        "fitted": next((s["params"] for s in report["steps"] if s["effect"] in law_of(injection.name)), None),
        "confusable": report.get("confusable", []),
    }


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command line's options."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--scale", type=float, default=1.0, help="multiplies every injected size")
    parser.add_argument("--only", nargs="+", help="the cases to run (their effect names)")
    parser.add_argument("--workers", type=int)
    parser.add_argument("--rescore", action="store_true", help="score the reports already in OUT/reports again")
    return parser.parse_args(argv)


def injected_pass(args: argparse.Namespace, rig: RigParameters) -> tuple[list[dict], dict]:
    """Write and diagnose every case (the baseline first) or, with ``--rescore``, read its report; print and return
    the scored rows and the baseline's report."""
    rows, baseline = [], None
    for injection in injections(rig, args.scale):
        if args.only and injection.name not in args.only and injection.name != "baseline":
            continue
        folder, seconds = args.out / "reports" / injection.name, None
        if not args.rescore:
            rig_path, train, heldout = write_case(injection, rig, args.out / "cases" / injection.name)
            seconds = _diagnose(rig_path, train, heldout, folder, args.workers)
        elif not (folder / "report.json").is_file():
            continue
        report = json.loads((folder / "report.json").read_text())
        baseline = baseline or report
        row = score(injection, report, baseline, seconds)
        rows.append(row)
        ratio = "" if row["size_over_limit"] is None else f"{row['size_over_limit']:.2g}x limit"
        print(
            f"{injection.name:<22} {injection.size:<44} {ratio:<10} -> {row['verdict']:<22} "
            f"{','.join(row['effects']):<60} {'named' if row['named'] else 'MISSED'}"
            f"{' (the baseline has it too)' if row['in_baseline'] else ''} ({row['heldout_reduction']:.0%}"
            f"{'' if seconds is None else f', {seconds:.0f} s'})",
            flush=True,
        )
    return rows, baseline


def continued_pass(args: argparse.Namespace, rig: RigParameters) -> list[dict]:
    """Diagnose every case again from its rig file plus the baseline's fitted effects (or, with ``--rescore``,
    read those reports); print and return the rows."""
    baseline_effects = load_rig(args.out / "reports" / "baseline" / "fitted_rig.yaml").effects
    print(f"\ncontinued from the baseline's fitted rig (effects: {', '.join(baseline_effects or {})}):")
    further = []
    for injection in injections(rig, args.scale):
        folder = args.out / "reports_continued" / injection.name
        if injection.name == "baseline" or not (args.out / "reports" / injection.name / "report.json").is_file():
            continue
        if not args.rescore:
            case = args.out / "cases" / injection.name
            rig_path = case / "rig_continued.yaml"
            rig_path.write_text(dump_yaml_dataclass(load_rig(case / "rig.yaml").replace(effects=baseline_effects)))
            _diagnose(rig_path, [case / n for n in TRAIN], [case / n for n in HELDOUT], folder, args.workers)
        elif not (folder / "report.json").is_file():
            continue
        further.append(continued(injection, json.loads((folder / "report.json").read_text())))
        row = further[-1]
        print(
            f"{injection.name:<22} -> {row['verdict']:<22} {','.join(row['effects']):<50} "
            f"{'named' if row['named'] else 'MISSED'} ({row['heldout_reduction']:.0%})",
            flush=True,
        )
    return further


def tallies(rows: list[dict], further: list[dict]) -> dict[str, int]:
    """Injected effects named, and cases, in all, at or above the baseline's detection limit (or without one), of
    a law the baseline does not hold, and continued from the baseline's fitted rig."""
    scored = [row for row in rows if row["case"] != "baseline"]
    above = [row for row in scored if row["size_over_limit"] is None or row["size_over_limit"] >= 1.0]
    apart = [row for row in scored if not row["in_baseline"]]
    return {
        "named": sum(row["named"] for row in scored),
        "cases": len(scored),
        "named_at_or_above_limit": sum(r["named"] for r in above),
        "cases_at_or_above_limit": len(above),
        "named_apart_from_baseline": sum(r["named"] for r in apart),
        "cases_apart_from_baseline": len(apart),
        "named_continued": sum(r["named"] for r in further),
        "cases_continued": len(further),
    }


def main(argv: list[str] | None = None) -> int:
    """Diagnose every injected case, then again continued from the baseline; print and write the tallies."""
    args = parse_args(argv)
    rig = load_rig(QUBE_REAL_RIG)
    args.out.mkdir(parents=True, exist_ok=True)
    rows, baseline = injected_pass(args, rig)
    further = continued_pass(args, rig)
    counts = tallies(rows, further)
    print(
        f"\nbaseline effects: {baseline['effects']}; injected effects named: {counts['named']}/{counts['cases']}; "
        f"at or above the baseline's detection limit (or without one): "
        f"{counts['named_at_or_above_limit']}/{counts['cases_at_or_above_limit']}; "
        f"of a law the baseline does not hold: "
        f"{counts['named_apart_from_baseline']}/{counts['cases_apart_from_baseline']}; "
        f"continued from the baseline's fitted rig: {counts['named_continued']}/{counts['cases_continued']}"
    )
    (args.out / "results.json").write_text(
        json.dumps(
            {"baseline": baseline["effects"], **counts, "rows": rows, "rows_continued": further}, indent=2, default=str
        )
        + "\n"
    )
    (args.out / "config.json").write_text(
        json.dumps(
            {
                "argv": sys.argv[1:] if argv is None else argv,
                "train": TRAIN,
                "heldout": HELDOUT,
                "versions": versions(),
            },
            indent=2,
        )
        + "\n"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
