"""Shared test constants, and the session's guard against reading outside the repository.

The guard is an audit hook (``sys.addaudithook``) that records every ``open`` of a path under the repository's
parent directory but outside the repository itself (a sibling checkout, a data folder beside the clone), except
the Python installation, the temporary directory and pytest's own temporary directories. A test that opened such
a path fails at its teardown; an open outside any test (at import or collection) fails the session.
"""

from __future__ import annotations

import os
import site
import sys
import sysconfig
import tempfile
from pathlib import Path

import pytest

from furuta_drake.data import QUBE_REAL_DIR

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
            tempfile.gettempdir(),
            *site.getsitepackages(),
            *sysconfig.get_paths().values(),
        )
        if p
    }
)


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
    )


def _audit(event: str, args) -> None:
    if event == "open" and args and _is_outside_read(args[0]):
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
