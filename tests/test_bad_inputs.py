"""The bad-input corpus of issue 9 (``tests/bad_inputs/manifest.yaml``) through the real command line.

Each case runs ``python -m furuta_drake.cli`` in a subprocess on a copy of the corpus and must end with the
manifest's exit code (2), exactly one stderr line starting with "furuta-drake" that contains every expected
fragment, no traceback, and nothing written or overwritten anywhere in the run's directory tree.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from conftest import REPO

CORPUS = Path(__file__).resolve().parent / "bad_inputs"
MANIFEST = yaml.safe_load((CORPUS / "manifest.yaml").read_text())["cases"]
SETUPS = (None, "out_not_empty", "out_is_file", "out_parent_is_file")
PRECIOUS = "keep me: results of an earlier run\n"


def snapshot(root: Path) -> dict[str, bytes | None]:
    """Every path under ``root`` with its bytes (None for a directory)."""
    return {str(p.relative_to(root)): None if p.is_dir() else p.read_bytes() for p in sorted(root.rglob("*"))}


def prepare(case: dict, root: Path) -> tuple[list[str], Path]:
    """Copy the corpus under ``root``, create the case's output setup, return (argv, working directory)."""
    case_dir = root / "inputs"
    shutil.copytree(CORPUS, case_dir)
    work = root / "work"
    work.mkdir()
    out = work / "out"
    setup = case.get("setup")
    if setup == "out_not_empty":
        out.mkdir()
        (out / "report.json").write_text(PRECIOUS)
    elif setup == "out_is_file":
        out.write_text(PRECIOUS)
    elif setup == "out_parent_is_file":
        (work / "blocker").write_text(PRECIOUS)
        out = work / "blocker" / "out"
    argv = [arg.format(case_dir=case_dir, out=out) for arg in case["argv"]]
    return argv, work


def run_cli(argv: list[str], cwd: Path) -> subprocess.CompletedProcess:
    env = dict(os.environ, MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])))
    return subprocess.run([sys.executable, "-m", "furuta_drake.cli", *argv], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=120)


def test_manifest_is_well_formed_and_uses_every_corpus_file():
    ids = [case["id"] for case in MANIFEST]
    assert len(ids) >= 30 and len(set(ids)) == len(ids)
    used = set()
    for case in MANIFEST:
        assert set(case) <= {"id", "problem", "argv", "exit", "stderr", "setup"}, case["id"]
        assert case["exit"] == 2 and case["stderr"] and case.get("setup") in SETUPS, case["id"]
        assert "{out}" in case["argv"] and case["argv"][case["argv"].index("{out}") - 1] == "--out", case["id"]
        for arg in case["argv"]:
            used.update(re.findall(r"\{case_dir\}/([^/\s]+)", arg))
    for name in used:
        assert (CORPUS / name).is_file(), name
    inputs = {p.name for p in CORPUS.iterdir() if p.suffix in (".csv", ".yaml") and p.name != "manifest.yaml"}
    assert inputs == used, f"corpus files no case uses: {sorted(inputs - used)}; missing: {sorted(used - inputs)}"


@pytest.mark.parametrize("case", MANIFEST, ids=[case["id"] for case in MANIFEST])
def test_bad_input_exits_2_with_one_clear_line_and_writes_nothing(case, tmp_path):
    argv, work = prepare(case, tmp_path)
    before = snapshot(tmp_path)
    result = run_cli(argv, work)
    shown = f"\n$ furuta-drake {' '.join(argv)}\nexit {result.returncode}\nstderr:\n{result.stderr}"
    assert "Traceback" not in result.stderr + result.stdout, shown
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("furuta-drake"), shown
    for fragment in case["stderr"]:
        assert fragment in lines[0], f"missing {fragment!r}" + shown
    assert result.returncode == case["exit"], shown
    assert snapshot(tmp_path) == before, "the run wrote or changed files" + shown
