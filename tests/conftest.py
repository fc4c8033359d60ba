"""Shared test constants and fixtures, and the session's guard against reading outside the repository.

The guard is an audit hook (``sys.addaudithook``) that records every ``open`` for reading of a path under the
repository's parent directory but outside the repository itself (a sibling checkout, a data folder beside the
clone), except the Python installation, pytest's own temporary directories and, in the system's temporary
directory, what this session made there or the tools' own scratch folders (Dask's, matplotlib's). A repository
cloned into the temporary directory is guarded like any other: what lay beside it before the session is outside. A
test that opened such a path fails at its teardown; an open outside any test (at import or collection) fails the
session.
"""

from __future__ import annotations

import dataclasses
import functools
import os
import site
import sys
import sysconfig
import tempfile
import time
from pathlib import Path

import pytest

from furuta_drake.data import QUBE_REAL_DIR
from furuta_drake.diagnosis.logs.load import RunLog

REPO = Path(__file__).resolve().parent.parent
QUBE_DATA = QUBE_REAL_DIR

OUTSIDE_READS: list[str] = []  # paths opened outside the repository, in the order opened
_GUARDED = str(REPO.parent) + os.sep
_INSIDE = str(REPO) + os.sep
_ALLOWED: list[str] = sorted(
    {
        os.path.realpath(p) + os.sep
        for p in (
            sys.prefix,
            sys.base_prefix,
            sys.exec_prefix,
            *site.getsitepackages(),
            *sysconfig.get_paths().values(),
        )
        if p
    }
)


_TEMP = os.path.realpath(tempfile.gettempdir()) + os.sep
_SESSION_START = time.time()
_SCRATCH = {"dask-scratch-space", "matplotlib", "numba"}  # tools' scratch folders (name prefixes) in the temp dir


def _session_scratch(path: str) -> bool:
    """True for a path in the temporary directory under an entry this session made, or a tool's scratch folder."""
    if not path.startswith(_TEMP):
        return False
    top = path[len(_TEMP) :].split(os.sep, 1)[0]
    if any(top.startswith(prefix) for prefix in _SCRATCH):
        return True
    try:
        return os.stat(_TEMP + top).st_ctime >= _SESSION_START - 1.0
    except OSError:
        return False


def _is_outside_read(path) -> bool:
    """True for a path under the repository's parent that is neither in the repository nor allowed."""
    if isinstance(path, int):
        return False
    path = os.fsdecode(path)
    if not path.startswith(os.sep):
        path = os.path.join(os.getcwd(), path)
    path = os.path.normpath(path)
    return (
        path.startswith(_GUARDED)
        and not (path + os.sep).startswith(_INSIDE)
        and not any((path + os.sep).startswith(allowed) for allowed in _ALLOWED)
        and not _session_scratch(path)
    )


def _is_write(mode, flags) -> bool:
    """Whether an ``open`` event writes (or creates) rather than reads: what the guard watches is reading."""
    if isinstance(mode, str):
        return any(c in mode for c in "wax")
    return isinstance(flags, int) and bool(flags & (os.O_WRONLY | os.O_CREAT))


def _audit(event: str, args) -> None:
    if event != "open" or not args:
        return
    mode, flags = (args[1] if len(args) > 1 else None), (args[2] if len(args) > 2 else None)
    if _is_write(mode, flags):
        return
    if _is_outside_read(args[0]):
        OUTSIDE_READS.append(os.fsdecode(args[0]))


def allow_directory(path: Path) -> None:
    """Stop the guard from recording opens under ``path`` (pytest's temporary directory when it is configured
    under the repository's parent)."""
    entry = os.path.realpath(path) + os.sep
    if entry not in _ALLOWED:
        _ALLOWED.append(entry)


sys.addaudithook(_audit)


def pytest_sessionstart(session) -> None:
    basetemp = session.config.option.basetemp
    if basetemp:
        allow_directory(Path(basetemp))


@pytest.fixture(autouse=True)
def no_reads_outside_the_repository(tmp_path_factory):
    """Fail the test that opened a file outside the repository (see the module docstring)."""
    allow_directory(tmp_path_factory.getbasetemp())
    before = len(OUTSIDE_READS)
    yield
    opened = OUTSIDE_READS[before:]
    del OUTSIDE_READS[before:]
    if opened:
        pytest.fail(f"the test read outside the repository {REPO}: {', '.join(sorted(set(opened)))}")


def pytest_sessionfinish(session, exitstatus) -> None:
    if OUTSIDE_READS:
        print(
            f"\nfiles read outside the repository {REPO} outside any test: {', '.join(sorted(set(OUTSIDE_READS)))}",
            file=sys.stderr,
        )
        session.exitstatus = pytest.ExitCode.TESTS_FAILED


@pytest.fixture
def fast_cli_diagnoses(monkeypatch):
    """``furuta-drake diagnose`` (the CLI's own parsing, loading and writing) run with the FAST sizes and two
    candidate effects (a friction law and a delay): for the tests that compare two diagnoses of the same data
    given in two ways, whose reports must agree whatever the sizes and the candidates tried. Every stage still
    runs and enters the report (the fits, the bootstrap, the Drake replay, the detection limits), briefly."""
    from furuta_drake.diagnosis import pipeline
    from furuta_drake.diagnosis.settings import FAST

    settings = dataclasses.replace(FAST, detection_limits=True)
    monkeypatch.setattr(
        pipeline,
        "diagnose",
        functools.partial(pipeline.diagnose, settings=settings, candidates=["arm_coulomb_friction", "input_delay"]),
    )


def run_notebook(path: Path, tmp_path: Path, monkeypatch) -> None:
    """Run the notebook ``path`` (a jupytext percent script) top to bottom headless in ``tmp_path``, in its small
    size (``FURUTA_NOTEBOOK_SMALL``); nbclient's CellExecutionError, with the cell and traceback, when a cell fails."""
    import jupytext
    import nbclient

    monkeypatch.setenv("FURUTA_NOTEBOOK_SMALL", "1")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    monkeypatch.chdir(tmp_path)
    notebook = jupytext.read(path)
    client = nbclient.NotebookClient(
        notebook, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}
    )
    client.execute()
    executed = [cell for cell in notebook.cells if cell.cell_type == "code"]
    assert executed and all(cell.get("execution_count") for cell in executed)


def suite_log(run: str, seed: int, effect: str | None = None, level: int = 2, duration: float = 3.0, rig="lund"):
    """The benchmark suite's ``run`` ("hanging": an open-loop multisine; "balance": LQR with the suite's
    excitation) on ``rig``, simulated in Drake with ``effect`` at ``level`` added, as a diagnosis log."""
    from benchmarks.diagnosis.suite import run_configs, with_effect  # Drake is imported by the tests that simulate only
    from furuta_drake.rig import RIGS
    from furuta_drake.simulate import simulate

    config = run_configs(RIGS[rig](), seed, duration)[run]
    if effect is not None:
        config = with_effect(config, effect, level)
    result = simulate(config)
    return RunLog(
        name=f"{run}_{seed}.csv",
        path="",
        time=result.time,
        theta=result.measured[:, 0],
        phi=result.measured[:, 1],
        input_kind="torque",
        input=result.torque,
        sample_period=config.control_period,
    )


def hanging_log(seed: int, effect: str | None = None, level: int = 2, duration: float = 3.0) -> RunLog:
    """A Lund hanging run under an open-loop multisine (:func:`suite_log`)."""
    return suite_log("hanging", seed, effect, level, duration)
