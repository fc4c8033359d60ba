"""Does ``diagnose`` finish on any valid logs? N random rigs-with-effects, each diagnosed with the command's own
settings: how many finished with a report (the target is all of them), how many candidates failed and why, and
the seconds per case.

Each case: a shipped rig (Lund or QUBE-Servo 2), up to three effects of the vocabulary or cogging drawn at random
magnitudes (levels 0.2-3 of the validation suite's scale), a balancing run under LQR and a hanging run for
training and the same for held-out, simulated in Drake (a balancing run that falls is replaced by a second
hanging run: the logs must be valid, the effects may be anything). Seeded: ``--seed`` fixes every draw.

Run from the repository root: ``PYTHONPATH=. python benchmarks/diagnosis/robustness.py --cases 40 --out runs/robust``.
Writes ``OUT/results.json`` (figures, one row per case) and ``OUT/config.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
import traceback
from collections import Counter
from pathlib import Path

import numpy as np

from benchmarks.diagnosis.suite import OUTSIDE_VOCABULARY, SUITE_RIGS, VOCABULARY, run_configs, with_effect
from furuta_drake.diagnosis.pipeline import diagnose
from furuta_drake.diagnosis.report.files import write_report
from furuta_drake.errors import SimulationDiverged
from furuta_drake.outputs import versions
from furuta_drake.results import write_log_csv
from furuta_drake.rig import RIGS
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import dump_yaml_dataclass


def draw_case(rng: np.random.Generator) -> dict:
    effects = list(rng.choice(VOCABULARY + (OUTSIDE_VOCABULARY,), size=rng.integers(0, 4), replace=False))
    return {
        "rig": str(rng.choice(SUITE_RIGS)),
        "effects": effects,
        "levels": [float(v) for v in rng.uniform(0.2, 3.0, len(effects))],
        "seed": int(rng.integers(0, 10_000)),
    }


def write_logs(case: dict, folder: Path, duration: float) -> list[str]:
    """The case's four logs; returns the names of the runs that had to be replaced (a balancing run that fell)."""
    rig = RIGS[case["rig"]]()
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    replaced = []
    for split, seed in (("train", case["seed"]), ("heldout", case["seed"] + 500)):
        runs = run_configs(rig, seed, duration)
        for run, config in runs.items():
            for effect, level in zip(case["effects"], case["levels"]):
                config = with_effect(config, effect, level)
            try:
                result = simulate(config)
            except SimulationDiverged:
                replaced.append(f"{split}_{run}")
                config = run_configs(rig, seed + 7, duration)["hanging"]
                for effect, level in zip(case["effects"], case["levels"]):
                    config = with_effect(config, effect, level)
                result = simulate(config)
            write_log_csv(result, folder / f"{split}_{run}.csv")
    return replaced


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, required=True)
    parser.add_argument("--cases", type=int, default=40)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--duration", type=float, default=4.0, help="length of every log [s]")
    parser.add_argument("--workers", type=int)
    args = parser.parse_args(argv)
    rng = np.random.default_rng(args.seed)
    args.out.mkdir(parents=True, exist_ok=True)
    rows = []
    for i in range(args.cases):
        case = draw_case(rng)
        folder = args.out / "cases" / f"case_{i:03d}"
        replaced = write_logs(case, folder, args.duration)
        start = time.perf_counter()
        row = {"case": i, **case, "replaced_runs": replaced}
        try:
            diagnosis = diagnose(
                rig=folder / "rig.yaml",
                train=sorted(folder.glob("train_*.csv")),
                heldout=sorted(folder.glob("heldout_*.csv")),
                workers=args.workers,
            )
            write_report(args.out / "reports" / f"case_{i:03d}", diagnosis, force=True)
            row.update(
                finished=True,
                verdict=diagnosis.verdict,
                effects=diagnosis.effects,
                failed=[(entry.effect, entry.reason) for entry in diagnosis.failed],
            )
        except Exception as err:  # noqa: BLE001 - the benchmark counts what the diagnosis did not contain
            row.update(finished=False, error=traceback.format_exception_only(err)[-1].strip())
        row["seconds"] = time.perf_counter() - start
        rows.append(row)
        print(
            f"[{i + 1}/{args.cases}] {case['rig']:<12} {'+'.join(case['effects']) or 'none':<60} -> "
            f"{row.get('verdict', 'CRASH: ' + row.get('error', ''))} ({len(row.get('failed', []))} failed "
            f"candidates, {row['seconds']:.0f} s)",
            flush=True,
        )
    finished = sum(row["finished"] for row in rows)
    reasons = Counter(reason.split(":")[0] for row in rows for _, reason in row.get("failed", []))
    figures = {
        "cases": len(rows),
        "finished": finished,
        "failed_candidates": sum(len(r.get("failed", [])) for r in rows),
        "failure_kinds": dict(reasons),
        "seconds_per_case": float(np.mean([r["seconds"] for r in rows])),
    }
    print(
        f"\nfinished {finished}/{len(rows)} (target: all); {figures['failed_candidates']} failed candidates "
        f"{dict(reasons)}; {figures['seconds_per_case']:.0f} s per case"
    )
    (args.out / "results.json").write_text(json.dumps({"figures": figures, "rows": rows}, indent=2) + "\n")
    (args.out / "config.json").write_text(
        json.dumps({"argv": sys.argv[1:] if argv is None else argv, "versions": versions()}, indent=2) + "\n"
    )
    return 0 if finished == len(rows) else 1


if __name__ == "__main__":
    sys.exit(main())
