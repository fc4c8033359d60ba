"""Does the designed experiment bring a detection limit down? A delay beside strong friction, end to end on the
independent simulator (benchmarks/independent/simulator.py).

The cases (:func:`benchmarks.diagnosis.independent.delay_beside_friction_cases`): strong asymmetric arm friction
and an input delay of several ms; with ``--all-cases``, the cases of the whole independent suite that ``--only``
names (a delay the logs cannot tell from an actuator lag, say: the design then separates that confusable pair).
Each is diagnosed blind with its four 8 s logs (before); ``design`` is run on that diagnosis (with no rival it
targets every actuator effect not accepted whose detection limit is above the size that changes the rig's LQR
loop, and predicts the limit its experiment reaches); the designed command is played on the same independent
simulator and the case's true rig as the design says (open loop from rest hanging, or the dither added to the
design's LQR balancing the upright); the first half of its log joins the train logs and the second half the
held-out ones, and the case is diagnosed again (after). Without ``--balancing``/``--hanging`` and ``--duration``
the design chooses the mode and duration by their predicted limits (:mod:`furuta_drake.design.choice`); the
candidates it compared are printed.

Prints, per case and effect the design targets (and the case's true effects): its true size, the size that
changes the closed loop, the detection limit before, predicted by the design and after, and whether the effect
is accepted before and after at what size (its 95 % interval). Writes ``OUT/results.json`` and
``OUT/config.json``; every stage is kept under ``OUT`` (``suite``, ``before``, ``design``, ``after``) and
reused when the script is run again with the same ``--out``.

Run from the repository root: ``PYTHONPATH=. python benchmarks/design/limits.py --out runs/design_limits``
(``--only WORD ...``: the cases whose name holds a word; ``--all-cases``: the cases from the whole suite;
``--duration S``: the experiment's length; ``--balancing``: the design's dither added to its LQR balancing the
upright, played so on the simulator; ``--hanging``: an open-loop design).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import sys
import time
from pathlib import Path

import numpy as np

from benchmarks.design.suite import diagnosed
from benchmarks.diagnosis import independent as indep
from furuta_drake.design.output import write_design
from furuta_drake.design.pipeline import DesignSettings, design_experiment
from furuta_drake.diagnosis.selection.detection import INJECTIONS
from furuta_drake.errors import FurutaError
from furuta_drake.outputs import versions

sim = indep.sim
LOG_SECONDS = 8.0  # [s] each of a case's four logs
PLAY_SEED = 900  # added to a case's seed for the designed experiment's run (its sensor noise)


def case_folder(case, out: Path) -> tuple[Path, dict]:
    """The case's rig file and four logs (written once) and its answer."""
    folder = out / "suite" / case.name
    answer = folder / "answer.json"
    if not answer.is_file():
        answer.parent.mkdir(parents=True, exist_ok=True)
        answer.write_text(json.dumps(indep.write_case(case, folder, LOG_SECONDS), indent=2) + "\n")
    return folder, json.loads(answer.read_text())


def designed(before: Path, directory: Path, args) -> dict:
    """design.json of the design from the diagnosis ``before`` (written once), or ``{status: error, reason}``."""
    if not (directory / "design.json").is_file():
        try:
            design = design_experiment(
                before, duration=args.duration, balancing=args.balancing, settings=DesignSettings(seed=args.seed)
            )
        except FurutaError as err:
            return {"status": "error", "reason": str(err), "detection_limits": []}
        write_design(directory, design, force=True)
    return json.loads((directory / "design.json").read_text())


def played(case, design: dict, experiment: Path, directory: Path) -> tuple[Path, Path]:
    """The designed command played on the case's true rig (the independent simulator; with ``--balancing`` the
    dither added to the design's LQR gain), its log cut in a train half and a held-out half written in the
    suite's log format."""
    paths = (directory / "experiment_train.csv", directory / "experiment_heldout.csv")
    if not paths[1].is_file():
        command = np.loadtxt(experiment, delimiter=",", comments="#", skiprows=2)[:, 1]
        gain = design["excitation"].get("lqr_gain")
        if gain is not None:  # N m per state unit -> command units
            gain = np.array([gain]) / case.world.rig.torque_per_command
        log = sim.play(case.world, command, case.seed + PLAY_SEED, gain)
        half = log.time.size // 2
        directory.mkdir(parents=True, exist_ok=True)
        for path, part in zip(paths, (slice(0, half), slice(half, None))):
            piece = dataclasses.replace(
                log, time=log.time[part], measured=log.measured[part], command=log.command[part], state=log.state[part]
            )
            sim.write_log(piece, path)
    return paths


def accepted_size(report: dict, effect: str, param: str) -> dict:
    """The effect's fitted ``param`` in the accepted model (with its 95 % interval), or, when it was not accepted,
    fitted beside the accepted effects at the next step (else at the latest step it was fitted)."""
    steps = [step["effect"] for step in report.get("steps") or []]
    key = f"{effect}.{param}"
    if effect in report["effects"]:
        final = next(e for e in report["ranking"] if set(e["effect"].split("+")) == set(steps))
        name = key if len(steps) > 1 else param
        return {"accepted": True, "value": final["params"].get(name), "interval": final.get("params_ci", {}).get(name)}
    fits = [e for e in report["ranking"] if e["effect"].split("+")[-1] == effect and e["status"] == "ok"]
    beside = [e for e in fits if e["effect"].split("+") == steps + [effect]] or sorted(fits, key=lambda e: -e["step"])
    if not beside:
        return {"accepted": False, "value": None, "interval": None}
    single = "+" not in beside[0]["effect"]
    return {"accepted": False, "value": beside[0]["params"].get(param if single else key), "interval": None}


def limit_of(report: dict, effect: str) -> float | None | str:
    """The report's detection limit of ``effect`` ('accepted' when it was; None when not reached)."""
    if effect in report["effects"]:
        return "accepted"
    return next((limit["value"] for limit in report.get("detection_limits", []) if limit["effect"] == effect), None)


def rows_of(case, answer: dict, before: dict, design: dict, after: dict | None) -> list[dict]:
    """One row per effect the design targets, true effect of the case and effect accepted before or after, in
    its main parameter (the detection limits')."""
    truth = {e["name"]: e["params"] for e in answer["effects"]}
    targets = {limit["effect"]: limit for limit in design.get("detection_limits", [])}
    accepted = [name for report in (before, after) if report for name in report["effects"]]
    names = [name for name in dict.fromkeys([*targets, *truth, *accepted]) if name in INJECTIONS]
    rows = []
    for effect in names:
        target, param = targets.get(effect, {}), INJECTIONS[effect].param
        rows.append(
            {
                "case": case.name,
                "effect": effect,
                "param": param,
                "true": truth.get(effect, {}).get(param),
                "size_that_matters": target.get("size"),
                "before": {"limit": limit_of(before, effect), **accepted_size(before, effect, param)},
                "predicted": target.get("predicted"),
                "predicted_below_size": target.get("predicted_below_size"),
                "after": None
                if after is None
                else {"limit": limit_of(after, effect), **accepted_size(after, effect, param)},
            }
        )
    return rows


def run_case(case, out: Path, args) -> tuple[list[dict], dict]:
    """Before, design, play, after for one case: its rows and a summary of its verdicts."""
    folder, answer = case_folder(case, out)
    train, heldout = sorted(folder.glob("train_*.csv")), sorted(folder.glob("heldout_*.csv"))
    before = diagnosed(out / "before" / case.name, folder / "rig.yaml", train, heldout, args.workers)
    design = designed(out / "before" / case.name, out / "design" / case.name, args)
    after = None
    if design["status"] == "design":
        experiment = out / "design" / case.name / "experiment.csv"
        extra = played(case, design, experiment, out / "after" / case.name / "logs")
        after = diagnosed(
            out / "after" / case.name / "report",
            folder / "rig.yaml",
            train + [extra[0]],
            heldout + [extra[1]],
            args.workers,
        )
    summary = {
        "case": case.name,
        "expected": answer["expected"],
        "before": before["verdict"],
        "before_effects": before["effects"],
        "design": design["status"],
        "design_reason": design.get("reason", ""),
        "duration_s": design.get("duration_s"),
        "mode": design.get("mode"),
        "choice": design.get("choice"),
        "hypotheses": [h["name"] for h in design.get("hypotheses", [])],
        "after": None if after is None else after["verdict"],
        "after_effects": None if after is None else after["effects"],
    }
    return rows_of(case, answer, before, design, after), summary


def _number(value, missing: str = "not reached") -> str:
    if value is None:
        return missing
    return value if isinstance(value, str) else f"{value:.3g}"


def _fit(entry: dict | None) -> str:
    if entry is None:
        return "-"
    interval = entry["interval"]
    span = f" [{_number(interval[0])}, {_number(interval[1])}]" if interval else ""
    return f"{'accepted' if entry['accepted'] else 'not accepted'}, {_number(entry['value'], 'not fitted')}{span}"


def print_choices(summaries: list[dict]) -> None:
    """The candidate experiments each design compared by their predicted limits (shortfall: limit over size)."""
    print("\n| case | mode | duration [s] | predicted limits (shortfall) | chosen |\n|---|---|---:|---|---|")
    for s in summaries:
        for c in (s["choice"] or {}).get("candidates", []):
            limits = "; ".join(
                f"{t['effect']} {_number(t['predicted'])} ({_number(t['shortfall'], 'inf')})"
                for t in c["detection_limits"]
            )
            print(
                f"| {s['case']} | {c['mode']} | {c['duration_s']:g} | {limits or c['status']} | "
                f"{'yes' if c['chosen'] else ''} |"
            )
        for longer in (s["choice"] or {}).get("longer", []):
            print(
                f"{s['case']}: {longer['effect']} in {longer['mode']} reaches {longer['size']:.3g} at "
                f"{_number(longer['duration_reaching_size_s'], 'no duration')} s (exponent "
                f"{_number(longer['exponent'], '-')})"
            )


def print_table(rows: list[dict], summaries: list[dict]) -> None:
    print("\n| case | verdict before | design | verdict after |\n|---|---|---|---|")
    for s in summaries:
        design = s["design"] + (
            f" ({s['mode']}, {s['duration_s']:g} s)" if s["duration_s"] else f": {s['design_reason']}"
        )
        print(
            f"| {s['case']} | {'+'.join(s['before_effects']) or s['before']} | {design} | "
            f"{'-' if s['after'] is None else '+'.join(s['after_effects']) or s['after']} |"
        )
    print(
        "\n| case | effect (param) | true | size that matters | limit before | predicted | limit after | fit before "
        "| fit after |\n|---|---|---:|---:|---:|---:|---:|---|---|"
    )
    for r in rows:
        after, targeted = r["after"] or {}, r["size_that_matters"] is not None
        print(
            f"| {r['case']} | {r['effect']} ({r['param']}) | {_number(r['true'], '-')} | "
            f"{_number(r['size_that_matters'], '-')} | {_number(r['before']['limit'])} | "
            f"{_number(r['predicted']) if targeted else '-'} | {_number(after.get('limit'), '-')} | "
            f"{_fit(r['before'])} | {_fit(r['after'])} |"
        )


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--only", nargs="+", help="the cases whose name contains one of these words")
    parser.add_argument("--all-cases", action="store_true", help="draw the cases from the whole independent suite")
    parser.add_argument("--duration", type=float, help="the experiment's length [s] (default: the design's choice)")
    mode = parser.add_mutually_exclusive_group()
    mode.add_argument("--balancing", dest="balancing", action="store_true", help="a dither added to the LQR")
    mode.add_argument("--hanging", dest="balancing", action="store_false", help="open loop from rest hanging")
    parser.set_defaults(balancing=None)
    parser.add_argument("--seed", type=int, default=0, help="the design's seed")
    parser.add_argument("--workers", type=int, default=1, help="processes of each diagnosis (default 1)")
    args = parser.parse_args(argv)
    args.out.mkdir(parents=True, exist_ok=True)
    pool = indep.all_cases() if args.all_cases else indep.delay_beside_friction_cases()
    cases = indep.select(pool, False, args.only)
    start, rows, summaries = time.perf_counter(), [], []
    for case in cases:
        case_rows, summary = run_case(case, args.out, args)
        rows += case_rows
        summaries.append(summary)
        print(
            f"{case.name}: before {summary['before']}, design {summary['design']}, after {summary['after']}", flush=True
        )
    print_table(rows, summaries)
    print_choices(summaries)
    (args.out / "results.json").write_text(json.dumps({"cases": summaries, "rows": rows}, indent=2) + "\n")
    config = {"argv": sys.argv[1:] if argv is None else argv, "cases": [c.name for c in cases], "seed": args.seed}
    config.update(all_cases=args.all_cases, duration_s=args.duration, balancing=args.balancing, workers=args.workers)
    config["wall_time_s"] = time.perf_counter() - start
    (args.out / "config.json").write_text(json.dumps({**config, **versions()}, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
