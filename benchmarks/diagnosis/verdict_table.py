"""The verdict table: every case's verdict on the project's own suite (``confusion.py``) and on the independent
simulator's (``independent.py``) in one table, side by side with a table written earlier, so that a change to the
rule, the fits or the effects shows every verdict it moves.

Each suite writes its ``verdicts.json`` (:mod:`benchmarks.diagnosis.shards`'s rows) into its ``--out`` folder; this
script joins those of ``--own DIR`` and ``--independent DIR`` (either may be left out) into ``OUT/verdicts.json`` and
``OUT/verdicts.md`` (suite, case, expected, verdict, effects, right, held-out reduction by the predictions, the
case's seconds). With ``--against FILE`` (an earlier joined ``verdicts.json``, or one suite's) it lists every case
whose verdict, effects or rightness changed and the counts of right verdicts before and after
(:func:`benchmarks.diagnosis.shards.compare`); ``--fail-on-change`` exits 1 when any did (for scripts).

Run from the repository root after the suites:
``PYTHONPATH=. python benchmarks/diagnosis/verdict_table.py --own runs/own --independent runs/indep
--out runs/verdicts [--against runs/verdicts_before/verdicts.json]``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from benchmarks.diagnosis.shards import compare, write_verdicts


def _percent(value) -> str:
    return "-" if value is None else f"{100 * value:.0f} %"


def markdown(rows: list[dict], changed: list[str] | None) -> str:
    lines = ["| suite | case | expected | verdict | effects | right | predictions remove | s |", "|---" * 8 + "|"]
    for row in rows:
        seconds = "-" if row["seconds"] is None else f"{row['seconds']:.0f}"
        lines.append(
            f"| {row['suite']} | {row['case']} | {row['expected']} | {row['verdict']} | "
            f"{', '.join(row['effects']) or '-'} | {'yes' if row['right'] else 'NO'} | "
            f"{_percent(row['heldout_reduction'])} | {seconds} |"
        )
    for suite in sorted({row["suite"] for row in rows}):
        group = [row for row in rows if row["suite"] == suite]
        lines.append(f"\n{suite}: {sum(row['right'] for row in group)}/{len(group)} right")
    if changed is not None:
        lines += ["\nAgainst the earlier table:", *(f"- {line}" for line in changed)]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--own", type=Path, help="confusion.py's output folder")
    parser.add_argument("--independent", type=Path, help="independent.py's output folder")
    parser.add_argument("--out", type=Path, required=True, help="folder for verdicts.json and verdicts.md")
    parser.add_argument("--against", type=Path, help="an earlier verdicts.json to compare with")
    parser.add_argument("--fail-on-change", action="store_true", help="exit 1 when a verdict changed")
    args = parser.parse_args(argv)
    if args.own is None and args.independent is None:
        parser.error("give --own, --independent or both")
    rows = []
    for flag, folder in (("--own", args.own), ("--independent", args.independent)):
        if folder is None:
            continue
        if not (folder / "verdicts.json").exists():
            parser.error(f"{flag} {folder}: no verdicts.json there (run the suite's benchmark with --out {folder})")
        rows += json.loads((folder / "verdicts.json").read_text())
    changed = None
    if args.against is not None:
        if not args.against.exists():
            parser.error(f"--against {args.against}: no such file")
        changed = compare(json.loads(args.against.read_text()), rows)
    args.out.mkdir(parents=True, exist_ok=True)
    write_verdicts(args.out / "verdicts.json", rows)
    text = markdown(rows, changed)
    (args.out / "verdicts.md").write_text(text)
    print(text)
    moved = changed is not None and len(changed) > 1  # the last line is the count
    return 1 if args.fail_on_change and moved else 0


if __name__ == "__main__":
    sys.exit(main())
