"""The bad-input corpus (``tests/bad_inputs/manifest.yaml``) through the command line.

Each case runs the command line's ``main`` in a process of its own, forked from this one after the commands'
modules are imported (a fresh interpreter per case would pay those imports 73 times), in its own copy of the
corpus (the cases run at once, a process per core), with its own working directory and its stdout and stderr
on files; the process's exit status is ``main``'s return value, argparse's exit, or 1 after a traceback, as
``python -m furuta_drake.cli`` would give (one case runs that way too). Each must end with the manifest's exit
code (2), exactly one stderr line starting with "furuta-drake" that contains every expected fragment, no
traceback, and nothing written or overwritten anywhere in the run's directory tree. Property tests feed the CSV
log loader random variations of a valid log: it returns a checked log or raises LogError.
"""

from __future__ import annotations

import os
import re
import shutil
import subprocess
import sys
import time
import traceback
from pathlib import Path
from typing import NamedTuple

import numpy as np
import pytest
import yaml
from conftest import REPO
from hypothesis import given, settings
from hypothesis import strategies as st

import furuta_drake.design.pipeline  # noqa: F401  (the commands' modules, imported before the cases fork)
import furuta_drake.diagnosis.pipeline  # noqa: F401
import furuta_drake.paper.report  # noqa: F401
import furuta_drake.real_rig.report  # noqa: F401
import furuta_drake.simulate  # noqa: F401
import furuta_drake.sweep  # noqa: F401
from furuta_drake.cli import main
from furuta_drake.diagnosis.logs.load import load_log
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


TIMEOUT = 120.0  # [s] a case's process is killed after this


class Result(NamedTuple):
    """A finished case: its exit status and what it printed."""

    returncode: int
    stdout: str
    stderr: str


def run_cli(argv: list[str], cwd: Path) -> Result:
    """``python -m furuta_drake.cli`` with ``argv`` in ``cwd``, in a fresh interpreter."""
    env = dict(
        os.environ,
        MPLBACKEND="Agg",
        PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])),
    )
    done = subprocess.run(
        [sys.executable, "-m", "furuta_drake.cli", *argv],
        cwd=cwd,
        env=env,
        capture_output=True,
        text=True,
        timeout=TIMEOUT,
    )
    return Result(done.returncode, done.stdout, done.stderr)


def _child(argv: list[str], cwd: Path, stdout: Path, stderr: Path) -> None:
    """In the forked process: ``main(argv)`` in ``cwd``, stdout and stderr on files; exits with its status."""
    code = 1
    try:
        os.chdir(cwd)
        for stream, path in ((1, stdout), (2, stderr)):
            os.dup2(os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC), stream)
        # Python's streams on those descriptors (pytest's capture had replaced them with its own).
        sys.stdout, sys.stderr = (open(stream, "w", closefd=False) for stream in (1, 2))  # noqa: SIM115
        code = main(argv)
    except SystemExit as exit_:  # argparse's exit, as the interpreter would turn it into a status
        code = exit_.code if isinstance(exit_.code, int) else (0 if exit_.code is None else 1)
    except BaseException:  # an uncaught exception: its traceback and status 1, as the interpreter gives
        traceback.print_exc()
    finally:
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)


class CaseProcess(NamedTuple):
    """A forked case: its pid, the files of its output streams and when it started."""

    pid: int
    streams: Path
    started: float

    @classmethod
    def start(cls, argv: list[str], cwd: Path, streams: Path) -> CaseProcess:
        """Fork a process running ``main(argv)`` in ``cwd``, its output on files in ``streams``."""
        pid = os.fork()
        if pid == 0:
            _child(argv, cwd, streams / "stdout", streams / "stderr")
        return cls(pid, streams, time.monotonic())

    def poll(self) -> Result | TimeoutError | None:
        """Its :class:`Result` once it has ended (a TimeoutError once killed after :data:`TIMEOUT`), else None."""
        done, status = os.waitpid(self.pid, os.WNOHANG)
        if not done:
            if time.monotonic() - self.started <= TIMEOUT:
                return None
            os.kill(self.pid, 9)
            os.waitpid(self.pid, 0)
            return TimeoutError(f"the case ran longer than {TIMEOUT} s")
        read = lambda name: (self.streams / name).read_text(errors="replace")  # noqa: E731
        return Result(os.waitstatus_to_exitcode(status), read("stdout"), read("stderr"))


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
    result: Result | TimeoutError
    before: dict[str, bytes | None]
    after: dict[str, bytes | None]


CASE_TEST = "test_bad_input_exits_2_with_one_clear_line_and_writes_nothing"


@pytest.fixture(scope="module")
def runs(request, tmp_path_factory) -> dict[str, Run]:
    """The selected cases, a process per core at a time: each in a directory tree of its own, sharing nothing
    with the others, so each gives what it gives run alone."""
    selected = {
        item.callspec.params["case"]["id"]
        for item in request.session.items
        if item.module is request.module and item.originalname == CASE_TEST
    }
    pending = [case for case in MANIFEST if case["id"] in selected]
    running, out = {}, {}
    while pending or running:
        while pending and len(running) < (os.cpu_count() or 1):
            case = pending.pop(0)
            root = tmp_path_factory.mktemp("case")
            argv, work = prepare(case, root)
            before = snapshot(root)
            process = CaseProcess.start(argv, work, tmp_path_factory.mktemp("streams"))
            running[case["id"]] = (argv, root, before, process)
        for case_id, (argv, root, before, process) in list(running.items()):
            result = process.poll()
            if result is not None:
                out[case_id] = Run(argv, result, before, snapshot(root))
                del running[case_id]
        time.sleep(0.01)
    return out


@pytest.mark.parametrize("case", MANIFEST, ids=[case["id"] for case in MANIFEST])
def test_bad_input_exits_2_with_one_clear_line_and_writes_nothing(case, runs):
    argv, result, before, after = runs[case["id"]]
    if isinstance(result, TimeoutError):
        raise result
    shown = f"\n$ furuta-drake {' '.join(argv)}\nexit {result.returncode}\nstderr:\n{result.stderr}"
    assert "Traceback" not in result.stderr + result.stdout, shown
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert len(lines) == 1 and lines[0].startswith("furuta-drake"), shown
    for fragment in case["stderr"]:
        assert fragment in lines[0], f"missing {fragment!r}" + shown
    assert result.returncode == case["exit"], shown
    assert after == before, "the run wrote or changed files" + shown


@pytest.mark.parametrize("case_id", ["log_empty", "config_gain_not_stabilising"])
def test_the_interpreter_gives_what_the_forked_process_gives(case_id, tmp_path):
    """``python -m furuta_drake.cli`` in a fresh interpreter: the same status and stderr as the forked run."""
    (case,) = [case for case in MANIFEST if case["id"] == case_id]
    fresh_argv, fresh_work = prepare(case, tmp_path / "fresh")
    fresh = run_cli(fresh_argv, fresh_work)
    forked_argv, forked_work = prepare(case, tmp_path / "forked")
    process = CaseProcess.start(forked_argv, forked_work, tmp_path)
    while (forked := process.poll()) is None:
        time.sleep(0.01)
    assert fresh.returncode == forked.returncode == case["exit"]
    normalise = lambda text, root: text.replace(str(root), "ROOT")  # noqa: E731
    assert normalise(fresh.stderr, tmp_path / "fresh") == normalise(forked.stderr, tmp_path / "forked")


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
