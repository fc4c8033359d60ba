"""Does the designed experiment settle what the default logs could not? ``furuta-drake design`` on the suite.

The cases (:mod:`benchmarks.diagnosis.suite`): every combination of :data:`SEVERAL_EFFECTS` at the strong
level and the input delay, actuator lag and arm Coulomb friction alone at both levels, on both rigs, with the
suite's four 8 s logs. Each case is diagnosed blind with its default logs. For every case whose verdict is wrong
or names a confusable pair, and for a few right ones (the check that no right verdict is turned wrong), the
experiment is designed from that diagnosis, played on the case's TRUE rig in simulation (Drake ``simulate`` with
the case's hidden effects, as the suite writes its logs), its log split into a train half and a held-out half
that join the case's logs, and the case is diagnosed again.

Prints a before/after table and the share of targeted cases whose verdict becomes right (and, for confusable
ones, no longer confusable); writes ``OUT/results.json`` (figures and rows) and ``OUT/config.json`` (options,
cases, versions). Target: >= 80 % of the targeted cases right after, no right verdict turned wrong. Every stage
is kept on disk (``OUT/suite``, ``OUT/before``, ``OUT/design``, ``OUT/after``) and reused when the script is run
again with the same ``--out``.

Run from the repository root: ``PYTHONPATH=. python benchmarks/design/suite.py --out runs/design_suite``
(``--only WORD ...`` keeps the cases whose name holds a word; ``--right-checks N`` sets how many right cases are
re-run).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.diagnosis.suite import SEVERAL_EFFECTS, CaseSpec, verdict_is_right, with_effect, write_case
from furuta_drake.config import ExcitationConfig, MonitorConfig, SimulationConfig
from furuta_drake.design.output import write_design
from furuta_drake.design.pipeline import DesignSettings, design_experiment
from furuta_drake.design.rollout import HANGING
from furuta_drake.diagnosis.pipeline import diagnose
from furuta_drake.diagnosis.report.files import write_report
from furuta_drake.errors import FurutaError
from furuta_drake.outputs import versions
from furuta_drake.rig import RIGS
from furuta_drake.simulate import simulate

SINGLE = ("input_delay", "actuator_lag", "arm_coulomb_friction")
TARGET = 0.8


def cases(rigs, seed: int) -> list[CaseSpec]:
    out = []
    for rig in rigs:
        out += [CaseSpec(rig, (effect,), level, seed) for effect in SINGLE for level in (1, 2)]
        out += [CaseSpec(rig, effects, 2, seed) for effects in SEVERAL_EFFECTS]
    return out


def diagnosed(out: Path, rig: Path, train: list[Path], heldout: list[Path], workers: int | None) -> dict:
    """The report of a diagnosis written to ``out`` (reused when already there)."""
    if not (out / "report.json").is_file():
        write_report(out, diagnose(rig=rig, train=train, heldout=heldout, workers=workers), force=True)
    return json.loads((out / "report.json").read_text())


def play_on_true_rig(case: CaseSpec, experiment: Path, directory: Path) -> tuple[Path, Path]:
    """The designed command played open loop from rest hanging on the case's true rig (its hidden effects, as
    :func:`~benchmarks.diagnosis.suite.write_case` realises them); its log's halves as train and held-out
    CSVs in the suite's log format."""
    rows = np.loadtxt(experiment, delimiter=",", comments="#", skiprows=2)
    header = experiment.read_text().splitlines()[1].split(",")
    rig = RIGS[case.rig]()
    torque = rows[:, 1] * (rig.motor.torque_constant / rig.motor.resistance if header[1] == "voltage" else 1.0)
    config = SimulationConfig.from_rig(rig)
    config = dataclasses.replace(
        config,
        controller=dataclasses.replace(config.controller, mode="open_loop"),
        excitation=ExcitationConfig(command=torque.tolist()),
        initial_state=list(HANGING),
        duration=float(rows.shape[0] * rig.sample_period),
        seed=case.seed + 900,
        monitor=MonitorConfig(theta_bound=None),
    )
    for effect in case.effects:
        config = with_effect(config, effect, case.level)
    result = simulate(config)
    half = result.time.size // 2
    paths = []
    directory.mkdir(parents=True, exist_ok=True)
    for name, part in (("experiment_train.csv", slice(0, half)), ("experiment_heldout.csv", slice(half, None))):
        table = np.column_stack([result.time[part], result.torque[part], result.measured[part]])
        path = directory / name
        np.savetxt(path, table, delimiter=",", header="time,torque,theta,phi", comments="", fmt="%.9g")
        paths.append(path)
    return paths[0], paths[1]


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    """The command line's options."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--rigs", nargs="+", default=["lund", "qube_servo2"], choices=list(RIGS))
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--only", nargs="+", help="keep the cases whose name contains one of these words")
    parser.add_argument(
        "--right-checks",
        type=int,
        default=3,
        help="right, non-confusable cases with rivals to separate that are re-run with a design",
    )
    parser.add_argument(
        "--duration", type=float, help="length of the designed experiment [s] (default: the design's own choice)"
    )
    parser.add_argument("--workers", type=int, help="processes of each diagnosis (default: all cores)")
    return parser.parse_args(argv)


def answer_of(case: CaseSpec, folder: Path) -> dict:
    """The case's answer, its logs written to ``folder`` first when they are not there yet."""
    answer_path = folder / "answer.json"
    if not answer_path.is_file():
        answer_path.parent.mkdir(parents=True, exist_ok=True)
        answer = write_case(case, folder)
        answer_path.write_text(json.dumps(answer, indent=2, sort_keys=True) + "\n")
    return json.loads(answer_path.read_text())


def diagnose_before(selected: list[CaseSpec], out: Path, workers: int | None) -> tuple[dict, dict]:
    """Write (or reuse) every case's logs and diagnose it with its default logs; the answers and the reports by
    case name."""
    answers, before = {}, {}
    for i, case in enumerate(selected, 1):
        folder = out / "suite" / case.name
        answers[case.name] = answer_of(case, folder)
        before[case.name] = diagnosed(
            out / "before" / case.name,
            folder / "rig.yaml",
            sorted(folder.glob("train_*.csv")),
            sorted(folder.glob("heldout_*.csv")),
            workers,
        )
        report = before[case.name]
        print(
            f"[{i}/{len(selected)}] {case.name:<58} before: {report['verdict']:<22} "
            f"{'right' if verdict_is_right(answers[case.name], report) else 'WRONG'}"
            f"{' confusable' if report.get('confusable') else ''}",
            flush=True,
        )
    return answers, before


def redo_all(selected: list[CaseSpec], targeted: list[CaseSpec], answers: dict, before: dict, out: Path, args):
    """Re-run every targeted case with a design, then right ones until ``--right-checks`` of them had something
    to separate; print and return the rows."""
    rows, checks = [], 0
    for case in targeted + [c for c in selected if c not in targeted]:
        if case not in targeted and checks >= args.right_checks:
            break
        row = redo(case, answers[case.name], before[case.name], out, args, case in targeted)
        if row is None:  # a right case with nothing to separate: no check
            continue
        checks += case not in targeted
        rows.append(row)
        print(
            f"{case.name:<58} {row['before']:<34} -> {row['design']:<13} "
            f"p={_percent(row['predicted_detection'])} -> {row['after']:<34} "
            f"{'right' if row['right_after'] else 'WRONG'}{' confusable' if row['confusable_after'] else ''}",
            flush=True,
        )
    return rows


def write_config(out: Path, argv, args, selected: list[CaseSpec], targeted: list[CaseSpec], rows, start: float):
    """``config.json``: the options, the cases (all, targeted, checks), the wall time and the versions."""
    (out / "config.json").write_text(
        json.dumps(
            {
                "argv": sys.argv[1:] if argv is None else argv,
                "cases": [c.name for c in selected],
                "targeted": [c.name for c in targeted],
                "checks": [r["case"] for r in rows if not r["targeted"]],
                "experiment_duration_s": args.duration,
                "log_duration_s": 8.0,
                "seed": args.seed,
                "workers": args.workers,
                "wall_time_s": time.perf_counter() - start,
                "python": platform.python_version(),
                **versions(),
            },
            indent=2,
        )
        + "\n"
    )


def main(argv: list[str] | None = None) -> int:
    """Diagnose the cases, re-run the targeted ones (and a few right ones) with a design, print and write the table."""
    args = parse_args(argv)
    out = args.out
    out.mkdir(parents=True, exist_ok=True)
    selected = [c for c in cases(args.rigs, args.seed) if not args.only or any(w in c.name for w in args.only)]
    start = time.perf_counter()

    answers, before = diagnose_before(selected, out, args.workers)
    targeted = [
        c for c in selected if not verdict_is_right(answers[c.name], before[c.name]) or before[c.name].get("confusable")
    ]
    rows = redo_all(selected, targeted, answers, before, out, args)

    figures = summarise(rows)
    print_table(rows, figures)
    (out / "results.json").write_text(json.dumps({"figures": figures, "target": TARGET, "rows": rows}, indent=2) + "\n")
    write_config(out, argv, args, selected, targeted, rows, start)
    return 0


def redo(case: CaseSpec, answer: dict, report: dict, out: Path, args, targeted: bool) -> dict | None:
    """Design from the case's diagnosis, play it on the true rig, diagnose again; the row of the table (None for
    a right case whose diagnosis has nothing to separate)."""
    row = {
        "case": case.name,
        "expected": answer["expected_verdict"],
        "before": _found(answer, report),
        "right_before": verdict_is_right(answer, report),
        "confusable_before": bool(report.get("confusable")),
        "targeted": targeted,
    }
    design_dir = out / "design" / case.name
    try:
        if not (design_dir / "design.json").is_file():
            write_design(
                design_dir,
                design_experiment(
                    out / "before" / case.name,
                    duration=args.duration,
                    balancing=False,  # played open loop from rest hanging
                    settings=DesignSettings(seed=args.seed),
                ),
                force=True,
            )
    except FurutaError as err:
        if not targeted:
            return None
        row.update(design="none", predicted_detection=None, hypotheses=[], reason=str(err))
    else:
        design = json.loads((design_dir / "design.json").read_text())
        row.update(
            design=design["status"],
            duration=design["duration_s"],
            hypotheses=[h["name"] for h in design["hypotheses"]],
            predicted_detection=min((p["detection_probability"] for p in design["pairs"]), default=None),
        )
    after = report
    if row["design"] == "design":
        folder = out / "suite" / case.name
        logs = out / "after" / case.name / "logs"
        if not (logs / "experiment_heldout.csv").is_file():
            play_on_true_rig(case, design_dir / "experiment.csv", logs)
        after = diagnosed(
            out / "after" / case.name / "report",
            folder / "rig.yaml",
            sorted(folder.glob("train_*.csv")) + [logs / "experiment_train.csv"],
            sorted(folder.glob("heldout_*.csv")) + [logs / "experiment_heldout.csv"],
            args.workers,
        )
    row.update(
        after=_found(answer, after),
        right_after=verdict_is_right(answer, after),
        confusable_after=bool(after.get("confusable")),
    )
    row["settled"] = row["right_after"] and not row["confusable_after"]
    return row


def _found(answer: dict, report: dict) -> str:
    return "+".join(sorted(report["effects"])) if "+" in answer["expected_verdict"] else report["verdict"]


def _percent(value) -> str:
    return "  - " if value is None else f"{value:4.0%}"


def summarise(rows: list[dict]) -> dict:
    targeted = [row for row in rows if row["targeted"]]
    wrong = [row for row in targeted if not row["right_before"]]
    confusable = [row for row in targeted if row["right_before"]]
    checks = [row for row in rows if not row["targeted"]]
    return {
        "targeted": len(targeted),
        "designed": sum(row["design"] == "design" for row in targeted),
        "right_after": sum(row["right_after"] for row in targeted),
        "settled_after": sum(row["settled"] for row in targeted),
        "share_right_after": sum(row["right_after"] for row in targeted) / len(targeted) if targeted else None,
        "share_settled_after": sum(row["settled"] for row in targeted) / len(targeted) if targeted else None,
        "wrong_before": len(wrong),
        "wrong_made_right": sum(row["right_after"] for row in wrong),
        "confusable_before": len(confusable),
        "confusable_settled": sum(row["settled"] for row in confusable),
        "right_checks": len(checks),
        "right_turned_wrong": sum(not row["right_after"] for row in checks)
        + sum(row["right_before"] and not row["right_after"] for row in targeted),
    }


def print_table(rows: list[dict], figures: dict) -> None:
    print("\n| case | expected | before | design (p) | after |\n|---|---|---|---|---|")
    for row in rows:
        before = (
            row["before"]
            + ("" if row["right_before"] else " (wrong)")
            + (" (confusable)" if row["confusable_before"] else "")
        )
        after = (
            row["after"]
            + ("" if row["right_after"] else " (wrong)")
            + (" (confusable)" if row["confusable_after"] else "")
        )
        print(
            f"| {row['case']} | {row['expected']} | {before} | {row['design']} ({_percent(row['predicted_detection'])})"
            f" | {after} |"
        )
    print(
        f"\ntargeted (wrong or confusable with the default logs): {figures['targeted']}; designed "
        f"{figures['designed']}; right after {figures['right_after']} ({_percent(figures['share_right_after'])}), "
        f"right and no longer confusable {figures['settled_after']} ({_percent(figures['share_settled_after'])}); "
        f"wrong made right {figures['wrong_made_right']}/{figures['wrong_before']}, confusable settled "
        f"{figures['confusable_settled']}/{figures['confusable_before']}; right verdicts turned wrong "
        f"{figures['right_turned_wrong']} (of {figures['right_checks']} right cases re-run and the confusable "
        f"right ones); target >= {TARGET:.0%} right after"
    )


if __name__ == "__main__":
    sys.exit(main())
