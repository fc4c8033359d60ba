"""Coverage of the accepted model's 95 % parameter intervals on the independent simulator's cases
(benchmarks/diagnosis/independent.py): for every true parameter of an accepted true effect, whether the truth lies
in the report's interval (``params_ci``: widened by the strongest rival's shift) and in the bootstrap's own
(``params_ci_if_complete``), split by whether the case holds a hidden second effect below its detection limit.

Run after the benchmark: ``PYTHONPATH=. python benchmarks/diagnosis/interval_coverage.py OUT [OUT ...]`` (its output
directories); prints a table per parameter and the coverage figures.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

DERIVED = {"arm_inertia_total", "pendulum_inertia_total", "coupling", "gravity_torque"}


def final_row(report: dict) -> dict | None:
    """The ranking entry of the accepted model (its effects are the report's steps)."""
    kept = {step["effect"] for step in report.get("steps") or []}
    return next((row for row in report["ranking"] if kept and set(row["effect"].split("+")) == kept), None)


def checks(out: Path) -> list[dict]:
    """One row per true parameter of an accepted true effect, over every case of ``out``."""
    rows = []
    answers = {a["case"]: a for a in json.loads((out / "results.json").read_text())["rows"]}
    for case, answer in answers.items():
        path = out / "reports" / case / "report.json"
        if not path.exists():
            continue
        report = json.loads(path.read_text())
        row = final_row(report)
        if row is None:
            continue
        several = "+" in row["effect"]
        hidden = any(c["effect"] not in row["effect"].split("+") for c in answer["fitted_vs_true"])
        for effect, params in answer["true_params"].items():
            if effect not in row["effect"].split("+"):
                continue
            for param, truth in params.items():
                key = f"{effect}.{param}" if several else param
                if key not in row["params_ci"] or param in DERIVED:
                    continue
                widened = row["params_ci"][key]
                own = (row.get("params_ci_if_complete") or {}).get(key, widened)
                rows.append(
                    {
                        "case": case,
                        "param": key,
                        "true": truth,
                        "fitted": row["params"].get(key),
                        "own": own,
                        "widened": widened,
                        "hidden_second": hidden,
                        "covered_own": own[0] <= truth <= own[1],
                        "covered_widened": widened[0] <= truth <= widened[1],
                    }
                )
    return rows


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("outs", nargs="+", type=Path, help="output directories of benchmarks/diagnosis/independent.py")
    args = parser.parse_args(argv)
    rows = [row for out in args.outs for row in checks(out)]
    print("| case | parameter | true | fitted | 95 % own | covered | 95 % widened | covered | hidden 2nd |")
    print("|---|---|---:|---:|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['case']} | {r['param']} | {r['true']:.4g} | {r['fitted']:.4g} | "
            f"[{r['own'][0]:.4g}, {r['own'][1]:.4g}] | {'yes' if r['covered_own'] else 'NO'} | "
            f"[{r['widened'][0]:.4g}, {r['widened'][1]:.4g}] | {'yes' if r['covered_widened'] else 'NO'} | "
            f"{'yes' if r['hidden_second'] else '-'} |"
        )
    print()
    for label, group in (
        ("all", rows),
        ("no hidden effect", [r for r in rows if not r["hidden_second"]]),
        ("hidden second effect", [r for r in rows if r["hidden_second"]]),
    ):
        n = len(group)
        own, widened = sum(r["covered_own"] for r in group), sum(r["covered_widened"] for r in group)
        print(f"{label}: {n} parameters; own intervals cover {own}/{n}, widened intervals cover {widened}/{n}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
