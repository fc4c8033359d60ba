"""Every notebook in notebooks/ (jupytext percent scripts) but the diagnosis ones runs top to bottom headless, in its
small size (the diagnosis notebooks: ``test_notebooks_diagnosis.py``, a file of their own so that the two halves
run on two cores)."""

import pytest
from conftest import REPO, run_notebook

pytestmark = pytest.mark.slow  # end-to-end runs: `pytest -m "not slow"` leaves them out

NOTEBOOKS = sorted(p for p in (REPO / "notebooks").glob("*.py") if not p.stem.startswith("diagnose_"))


def test_there_are_notebooks():
    assert len(NOTEBOOKS) >= 1


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs_headless(path, tmp_path, monkeypatch):
    run_notebook(path, tmp_path, monkeypatch)
