"""``furuta-drake reproduce`` end to end on short runs: the tables, figures and logs with their stable formats,
and byte-identical CSV/JSON for the same seed."""

from __future__ import annotations

import csv
import json

import pytest

from furuta_drake.cli import main
from furuta_drake.config import load_config

pytestmark = pytest.mark.slow  # end-to-end runs: `pytest -m "not slow"` leaves them out

SHORT = ["--table-duration", "4", "--adaptation-duration", "12"]


@pytest.fixture(scope="module")
def two_runs(tmp_path_factory):
    """The same reproduction twice (every experiment, short runs, seed 5)."""
    root = tmp_path_factory.mktemp("reproduce")
    outs = [root / "first", root / "second"]
    for out in outs:
        assert main(["reproduce", "--seed", "5", *SHORT, "--out", str(out)]) == 0
    return outs


def test_writes_every_table_figure_log_and_config(two_runs):
    out = two_runs[0]
    for name in (
        "table1.csv",
        "table2.csv",
        "observer_sweep.csv",
        "adaptation.json",
        "report.md",
        "config.yaml",
        "reproduction.yaml",
        *(f"fig{i}.png" for i in range(3, 8)),
    ):
        assert (out / name).stat().st_size > 0, name
    logs = sorted(p.stem for p in (out / "logs").glob("*.csv"))
    assert logs == ["adaptation", "fig5_set1_low", "fig5_set2_high", "table_lqr_on_hg", "table_lqr_on_vfe"]
    # Every raw log has its config beside it, and config.yaml is a simulate config.
    assert all((out / "logs" / f"{name}.yaml").exists() for name in logs)
    assert load_config(out / "config.yaml").encoder.counts_per_rev == 4096


def test_tables_have_their_stable_columns_and_the_papers_values(two_runs):
    with open(two_runs[0] / "table1.csv") as file:
        rows = list(csv.DictReader(file))
    assert list(rows[0]) == ["signal", "statistic", "HG", "VFE", "paper_HG", "paper_VFE"]
    assert {(r["signal"], r["statistic"]) for r in rows} == {(s, t) for s in ("phi", "theta") for t in ("mean", "std")}
    assert next(r for r in rows if r["signal"] == "phi" and r["statistic"] == "mean")["paper_HG"] == "0.0035"
    with open(two_runs[0] / "table2.csv") as file:
        rows = list(csv.DictReader(file))
    assert list(rows[0]) == ["reference", "signal", "statistic", "HG", "VFE", "paper_HG", "paper_VFE"]
    assert len(rows) == 8 and {r["reference"] for r in rows} == {"butterworth", "true"}
    assert all(float(r["HG"]) > 0 and float(r["VFE"]) > 0 for r in rows)


def test_adaptation_json_keys(two_runs):
    data = json.loads((two_runs[0] / "adaptation.json").read_text())
    assert set(data) == {
        "K_sigma_plus",
        "K_sigma_minus",
        "friction_pos",
        "friction_neg",
        "theta_abs_max",
        "enable_time",
        "fig5",
    }
    assert data["enable_time"] == 7.8
    assert data["friction_pos"] < 0 < data["friction_neg"]  # friction opposes the arm velocity
    for steady in data["fig5"].values():
        assert set(steady) == {"F_hat", "F_hat_plus_eps", "true"}
        assert steady["true"]["pos"] == pytest.approx(-0.012, rel=0.02)
        assert steady["true"]["neg"] == pytest.approx(0.018, rel=0.02)


def test_same_seed_gives_byte_identical_results(two_runs):
    first, second = two_runs
    files = [
        "table1.csv",
        "table2.csv",
        "observer_sweep.csv",
        "adaptation.json",
        *(f"logs/{p.name}" for p in (first / "logs").glob("*.csv")),
    ]
    for name in files:
        assert (first / name).read_bytes() == (second / name).read_bytes(), name


def test_only_runs_the_selected_experiments(tmp_path):
    out = tmp_path / "fig5"
    assert main(["reproduce", "--only", "fig5", "--seed", "6", *SHORT, "--out", str(out)]) == 0
    assert (out / "fig5.png").exists() and not (out / "table1.csv").exists() and not (out / "fig6.png").exists()
    data = json.loads((out / "adaptation.json").read_text())
    assert data["K_sigma_plus"] is None and set(data["fig5"]) == {"set1_low", "set2_high"}
    # A different seed is a different excitation: the Fig. 5 logs differ from seed 7's.
    other = tmp_path / "fig5_seed7"
    assert main(["reproduce", "--only", "fig5", "--seed", "7", *SHORT, "--out", str(other)]) == 0
    assert (out / "logs/fig5_set1_low.csv").read_bytes() != (other / "logs/fig5_set1_low.csv").read_bytes()


def test_beyond_writes_its_table_plots_and_logs(tmp_path, monkeypatch):
    # One short study through the real command (each study's figures are asserted in its own tests).
    from furuta_drake.paper import report as reproduction_report

    monkeypatch.setattr(reproduction_report, "BEYOND_STUDIES", ("lugre_observer_study",))
    out = tmp_path / "beyond"
    assert main(["reproduce", "--only", "beyond", "--quick", "--out", str(out)]) == 0
    text = (out / "beyond.md").read_text()
    assert "## LuGre observer" in text and "| F_hat_rms_error |" in text
    with open(out / "beyond.csv") as file:
        rows = list(csv.DictReader(file))
    assert list(rows[0])[:4] == ["study", "metric", "paper", "extension"]
    assert (out / "beyond_lugre_observer_lugre.png").stat().st_size > 0
    assert (out / "logs" / "beyond_lugre_rig_lugre_observer.csv").exists()
    assert not (out / "table1.csv").exists()
