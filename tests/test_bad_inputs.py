"""The bad-input corpus (``tests/bad_inputs/manifest.yaml``) through the real command line.

Each case runs ``python -m furuta_drake.cli`` in a subprocess on its own copy of the corpus (the cases run at
once, a process per core) and must end with the manifest's exit code (2), exactly one stderr line starting with
"furuta-drake" that contains every expected fragment, no traceback, and nothing written or overwritten anywhere
in the run's directory tree. Property tests feed the CSV log loader random variations of a valid log: it
returns a checked log or raises LogError.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest
import yaml
from conftest import REPO
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.diagnosis.logs import load_log
from furuta_drake.errors import LogError
from furuta_drake.rig import lund_rig

pytestmark = pytest.mark.slow  # end-to-end runs: `pytest -m "not slow"` leaves them out

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
    env = dict(
        os.environ,
        MPLBACKEND="Agg",
        PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])),
    )
    return subprocess.run(
        [sys.executable, "-m", "furuta_drake.cli", *argv], cwd=cwd, env=env, capture_output=True, text=True, timeout=120
    )


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
        assert (CORPUS / name).exists(), name  # a file, or a directory (a diagnosis' output)
    inputs = {
        p.name
        for p in CORPUS.iterdir()
        if (p.suffix in (".csv", ".yaml", ".parquet", ".mcap") and p.name != "manifest.yaml")
        or (p.is_dir() and p.name != "__pycache__")  # Python's cache of generate.py is no corpus input
    }
    assert inputs == used, f"corpus files no case uses: {sorted(inputs - used)}; missing: {sorted(used - inputs)}"


class Run(NamedTuple):
    """One case's command line, its finished process (or its timeout) and its directory tree before and after
    the run."""

    argv: list[str]
    result: subprocess.CompletedProcess | subprocess.TimeoutExpired
    before: dict[str, bytes | None]
    after: dict[str, bytes | None]


def run_case(case: dict, root: Path) -> Run:
    """``case`` run in ``root``, on its own copy of the corpus and its output setup."""
    argv, work = prepare(case, root)
    before = snapshot(root)
    try:
        result = run_cli(argv, work)
    except subprocess.TimeoutExpired as timeout:  # the case's own test fails on it, not the others
        result = timeout
    return Run(argv, result, before, snapshot(root))


CASE_TEST = "test_bad_input_exits_2_with_one_clear_line_and_writes_nothing"


@pytest.fixture(scope="module")
def runs(request, tmp_path_factory) -> dict[str, Run]:
    """The selected cases run at once, a process per core: each in a directory tree of its own, sharing
    nothing with the others, so each gives what it gives run alone."""
    selected = {
        item.callspec.params["case"]["id"]
        for item in request.session.items
        if item.module is request.module and item.originalname == CASE_TEST
    }
    cases = [case for case in MANIFEST if case["id"] in selected]
    roots = [tmp_path_factory.mktemp("case") for _ in cases]
    with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as threads:
        return {case["id"]: run for case, run in zip(cases, threads.map(run_case, cases, roots))}


@pytest.mark.parametrize("case", MANIFEST, ids=[case["id"] for case in MANIFEST])
def test_bad_input_exits_2_with_one_clear_line_and_writes_nothing(case, runs):
    argv, result, before, after = runs[case["id"]]
    if isinstance(result, subprocess.TimeoutExpired):
        raise result
    shown = f"\n$ furuta-drake {' '.join(argv)}\nexit {result.returncode}\nstderr:\n{result.stderr}"
    assert "Traceback" not in result.stderr + result.stdout, shown
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("furuta-drake"), shown
    for fragment in case["stderr"]:
        assert fragment in lines[0], f"missing {fragment!r}" + shown
    assert result.returncode == case["exit"], shown
    assert after == before, "the run wrote or changed files" + shown


# --- The CSV log loader on random variations of a valid log (in-process, hypothesis) -----------------------

GARBAGE = [
    "",
    " ",
    "nan",
    "-inf",
    "1e999",
    "0x10",
    "1,5",
    "#VALUE!",
    '"0.1"',
    "1.2.3",
    "١٢",
    "--1",
    "0.1 0.2",
    "\x00",
    "é",
    "1e-400",
    "+.5",
    "TRUE",
]


def valid_log_lines(n: int) -> list[str]:
    """Header and n rows of a quiet 1 kHz torque log."""
    return ["time,theta,phi,torque"] + [
        f"{k * 1e-3:.3f},{0.02 * np.sin(9.4 * k * 1e-3):.6f},{0.1 * np.sin(3.1 * k * 1e-3):.6f},"
        f"{0.01 * np.cos(6.3 * k * 1e-3):.6f}"
        for k in range(n)
    ]


@st.composite
def mangled_logs(draw) -> bytes:
    """A valid log with up to three random edits: a cell replaced by garbage, a row deleted, duplicated or
    swapped, a blank line, a renamed or extra column, a cut, random bytes, CRLF endings, a BOM."""
    lines = valid_log_lines(draw(st.integers(3, 40)))
    for _ in range(draw(st.integers(0, 3))):
        edit = draw(st.sampled_from(["cell", "delete", "duplicate", "swap", "blank", "rename", "extra"]))
        row = draw(st.integers(1, len(lines) - 1)) if len(lines) > 1 else 0
        if edit == "cell":
            fields = lines[row].split(",")
            fields[draw(st.integers(0, len(fields) - 1))] = draw(st.sampled_from(GARBAGE) | st.text(max_size=6))
            lines[row] = ",".join(fields)
        elif edit == "delete":
            del lines[row]
        elif edit == "duplicate":
            lines.insert(row, lines[row])
        elif edit == "swap" and row + 1 < len(lines):
            lines[row], lines[row + 1] = lines[row + 1], lines[row]
        elif edit == "blank":
            lines.insert(row, draw(st.sampled_from(["", " ", ",,,"])))
        elif edit == "rename":
            names = lines[0].split(",")
            names[draw(st.integers(0, 3))] = draw(st.sampled_from(["voltage", "Theta", "time", "", "phi "]))
            lines[0] = ",".join(names)
        elif edit == "extra":
            lines = [line + ("," + draw(st.sampled_from(["x", "1.0", ""]))) for line in lines]
    text = draw(st.sampled_from(["\n", "\r\n"])).join(lines) + draw(st.sampled_from(["", "\n"]))
    data = draw(st.sampled_from([b"", "\ufeff".encode()])) + text.encode()
    if draw(st.booleans()):
        data = data[: draw(st.integers(0, len(data)))]
    if draw(st.booleans()):
        at = draw(st.integers(0, len(data)))
        data = data[:at] + draw(st.binary(max_size=4)) + data[at:]
    return data


@settings(max_examples=25, deadline=None)
@given(data=mangled_logs())
def test_a_mangled_log_loads_checked_or_raises_log_error(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("log") / "run.csv"
    path.write_bytes(data)
    try:
        log = load_log(path, lund_rig())
    except LogError as err:
        assert str(err).startswith(str(path)) and "\n" not in str(err)
    else:
        assert log.time.size >= 3 and np.all(np.diff(log.time) > 0)
        assert all(np.all(np.isfinite(a)) for a in (log.time, log.theta, log.phi, log.input))


@settings(max_examples=25, deadline=None)
@given(data=st.binary(max_size=200))
def test_random_bytes_raise_log_error(tmp_path_factory, data):
    path = tmp_path_factory.mktemp("log") / "run.csv"
    path.write_bytes(data)
    with pytest.raises(LogError):
        load_log(path, lund_rig())
