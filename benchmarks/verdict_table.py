"""The verdict table: every case's verdict on the project's own suite (``diagnosis_confusion.py``) and on the
independent simulator's (``diagnosis_independent.py``), side by side with a table written earlier, so that a change
to the rule, the fits or the effects shows every verdict it moves.

Reads the ``results.json`` each suite's benchmark writes (``--own DIR``, ``--independent DIR``: their ``--out``
folders; either may be left out), and writes ``OUT/verdicts.json`` (one row per case: suite, case, expected, verdict,
effects, right, held-out reduction by the predictions, the sensor's share) and ``OUT/verdicts.md``. With
``--against FILE`` (an earlier ``verdicts.json``) it lists every case whose verdict, effects or rightness changed,
and the counts of right verdicts before and after; ``--fail-on-change`` exits 1 when any did (for scripts).

Run from the repository root after the suites:
``PYTHONPATH=. python benchmarks/verdict_table.py --own runs/own --independent runs/indep --out runs/verdicts
[--against runs/verdicts_before/verdicts.json]``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path


def _report(folder: Path, case: str) -> dict:
    """A case's report.json under the suite's ``reports/`` folder ({} when it is missing)."""
    path = folder / "reports" / case / "report.json"
    return json.loads(path.read_text()) if path.exists() else {}


def own_rows(folder: Path) -> list[dict]:
    """The own suite's rows (``diagnosis_confusion.py``'s results.json and reports)."""
    out = []
    for row in json.loads((folder / "results.json").read_text())["rows"]:
        report = _report(folder, row["case"])
        out.append(
            _row("own", row["case"], row["expected"], row["found"], report, row["right"], row["heldout_reduction"])
        )
    return out


def independent_rows(folder: Path) -> list[dict]:
    """The independent simulator's rows (``diagnosis_independent.py``'s results.json and reports)."""
    out = []
    for row in json.loads((folder / "results.json").read_text())["rows"]:
        report = _report(folder, row["case"])
        out.append(
            _row(
                "independent",
                row["case"],
                row["expected"],
                row["verdict"],
                report,
                row["right"],
                row["heldout_reduction"],
            )
        )
    return out


def _row(suite: str, case: str, expected: str, verdict: str, report: dict, right: bool, reduction) -> dict:
    gap = report.get("gap", {})
    return {
        "suite": suite,
        "case": case,
        "expected": expected,
        "verdict": verdict,
        "effects": report.get("effects", []),
        "right": bool(right),
        "heldout_reduction": reduction,
        "sensor_share": gap.get("sensor_share"),
    }


def changes(before: list[dict], after: list[dict]) -> list[dict]:
    """The cases in both tables whose verdict, effects or rightness differ."""
    old = {(row["suite"], row["case"]): row for row in before}
    out = []
    for row in after:
        was = old.get((row["suite"], row["case"]))
        if was is None:
            continue
        if (was["verdict"], sorted(was["effects"]), was["right"]) != (
            row["verdict"],
            sorted(row["effects"]),
            row["right"],
        ):
            out.append({"suite": row["suite"], "case": row["case"], "before": was, "after": row})
    return out


def _percent(value) -> str:
    return "-" if value is None else f"{100 * value:.0f} %"


def markdown(rows: list[dict], moved: list[dict] | None) -> str:
    lines = ["| suite | case | expected | verdict | effects | right | predictions remove | sensor |", "|---" * 8 + "|"]
    for row in rows:
        lines.append(
            f"| {row['suite']} | {row['case']} | {row['expected']} | {row['verdict']} | "
            f"{', '.join(row['effects']) or '-'} | {'yes' if row['right'] else 'NO'} | "
            f"{_percent(row['heldout_reduction'])} | {_percent(row['sensor_share'])} |"
        )
    for suite in sorted({row["suite"] for row in rows}):
        group = [row for row in rows if row["suite"] == suite]
        lines.append(f"\n{suite}: {sum(row['right'] for row in group)}/{len(group)} right")
    if moved is not None:
        lines.append(f"\n{len(moved)} verdicts changed against the earlier table:")
        for change in moved:
            b, a = change["before"], change["after"]
            lines.append(
                f"- {change['suite']} {change['case']}: {b['verdict']} {b['effects']} "
                f"({'right' if b['right'] else 'wrong'}) -> {a['verdict']} {a['effects']} "
                f"({'right' if a['right'] else 'wrong'})"
            )
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--own", type=Path, help="diagnosis_confusion.py's output folder")
    parser.add_argument("--independent", type=Path, help="diagnosis_independent.py's output folder")
    parser.add_argument("--out", type=Path, required=True, help="folder for verdicts.json and verdicts.md")
    parser.add_argument("--against", type=Path, help="an earlier verdicts.json to compare with")
    parser.add_argument("--fail-on-change", action="store_true", help="exit 1 when a verdict changed")
    args = parser.parse_args(argv)
    if args.own is None and args.independent is None:
        parser.error("give --own, --independent or both")
    for flag, folder in (("--own", args.own), ("--independent", args.independent)):
        if folder is not None and not (folder / "results.json").exists():
            parser.error(f"{flag} {folder}: no results.json there (run the suite's benchmark with --out {folder})")
    rows = (own_rows(args.own) if args.own else []) + (independent_rows(args.independent) if args.independent else [])
    moved = None
    if args.against is not None:
        if not args.against.exists():
            parser.error(f"--against {args.against}: no such file")
        moved = changes(json.loads(args.against.read_text())["rows"], rows)
    args.out.mkdir(parents=True, exist_ok=True)
    (args.out / "verdicts.json").write_text(json.dumps({"rows": rows, "changed": moved}, indent=2) + "\n")
    text = markdown(rows, moved)
    (args.out / "verdicts.md").write_text(text)
    print(text)
    return 1 if args.fail_on_change and moved else 0


if __name__ == "__main__":
    sys.exit(main())
