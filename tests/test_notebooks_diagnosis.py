"""The diagnosis notebooks in notebooks/ (``diagnose_*``, jupytext percent scripts) run top to bottom headless, in
their small size."""

import pytest
from conftest import REPO, run_notebook

pytestmark = pytest.mark.slow  # end-to-end runs: `pytest -m "not slow"` leaves them out

NOTEBOOKS = sorted((REPO / "notebooks").glob("diagnose_*.py"))


def test_there_are_diagnosis_notebooks():
    assert len(NOTEBOOKS) >= 1


@pytest.mark.parametrize("path", NOTEBOOKS, ids=[p.stem for p in NOTEBOOKS])
def test_notebook_runs_headless(path, tmp_path, monkeypatch):
    run_notebook(path, tmp_path, monkeypatch)
