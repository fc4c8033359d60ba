"""``furuta-drake reproduce --only real --quick``: the real-rig tables from the logs and the simulations, the
controller's fit to the logged voltage, the files and the report that reads them."""

from __future__ import annotations

import csv
import json
import math

import pytest

from furuta_drake.cli import main
from furuta_drake.config import load_config
from furuta_drake.controllers.swingup import catch_time
from furuta_drake.real_rig.runs import HELDOUT_SWINGUPS, SWINGUPS, load_real_runs, log_result

pytestmark = pytest.mark.slow  # end-to-end runs: `pytest -m "not slow"` leaves them out

REQUIRED = [
    "catch_time",
    "peak_arm_angle",
    "theta_rms",
    "phi_rms",
    "voltage_rms",
    "limit_cycle_hz",
    "limit_cycle_amplitude",
]


@pytest.fixture(scope="module")
def out(tmp_path_factory):
    out = tmp_path_factory.mktemp("real") / "out"
    assert main(["reproduce", "--only", "real", "--quick", "--out", str(out)]) == 0
    return out


def rows(path):
    with open(path) as file:
        return list(csv.DictReader(file))


def test_writes_the_tables_plots_reports_and_a_simulate_config(out):
    for name in (
        "real_observers.csv",
        "real_observer_sweep.csv",
        "real_closed_loop.csv",
        "real_closed_loop_gap.csv",
        "controller_fit.json",
        "report.md",
        "config.yaml",
        "real_observers.png",
        "controller_fit.png",
        "limit_cycle_spectra.png",
        "diagnosis_corrected/report.json",
        "diagnosis_balancing/report.json",
        "diagnosis_corrected/fitted_model.yaml",
    ):
        assert (out / name).stat().st_size > 0, name
    config = load_config(out / "config.yaml")
    assert config.controller.mode == "quanser_swingup" and config.rig.sample_period == 0.004
    assert sorted(p.suffix for p in (out / "logs").iterdir()) == sorted(
        [".csv", ".yaml"] * (len(list((out / "logs").glob("*.csv"))))
    )
    report = (out / "report.md").read_text()
    for section in (
        "Observers on measured data",
        "The controller against the logs",
        "The closed loop, real and simulated",
        "Where it does not close",
    ):
        assert section in report


def test_observer_table_has_both_observers_and_models_on_held_out_logs(out):
    table = rows(out / "real_observers.csv")
    assert list(table[0]) == ["observer", "model", "log", "phi_dot_mse", "theta_dot_mse"]
    assert {(r["observer"], r["model"]) for r in table} == {
        (o, m) for o in ("HG", "VFE") for m in ("nominal", "fitted")
    }
    assert set(HELDOUT_SWINGUPS) <= {r["log"] for r in table}
    assert "swingup_250Hz_10s_a.csv" not in {r["log"] for r in table}  # the train swing-up tunes, never judges
    assert all(0 < float(r[key]) < 10 for r in table for key in ("phi_dot_mse", "theta_dot_mse"))


def test_closed_loop_rows_come_from_the_logs_and_the_simulations(out):
    table = rows(out / "real_closed_loop.csv")
    assert set(REQUIRED) <= set(table[0]) and {"log", "source"} <= set(table[0])
    assert {"real", "sim_nominal", "sim_fitted"} <= {r["source"] for r in table}
    runs = load_real_runs(names=SWINGUPS)
    for row in (r for r in table if r["source"] == "real"):
        assert float(row["catch_time"]) == pytest.approx(catch_time(log_result(runs.logs[row["log"]])))
    for row in table:
        assert math.isfinite(float(row["peak_arm_angle"])) and float(row["voltage_rms"]) > 0
        if row["source"].startswith("sim"):
            assert float(row["voltage_rms"]) <= 4.0  # the clip


def test_controller_gives_back_the_logged_voltage(out):
    """With the server's filtered derivative the law reproduces the rig's voltage to a few percent of its RMS;
    with the zero-phase reference much less well."""
    fit = json.loads((out / "controller_fit.json").read_text())
    assert 10 < fit["velocity_filter_corner"] < 200
    assert set(fit["logs"]) == set(SWINGUPS)
    for name, entry in fit["logs"].items():
        assert {"voltage_rmse", "voltage_rms", "voltage_rmse_server_filter", "swing", "balance"} <= set(entry)
        assert entry["voltage_rmse_server_filter"] < 0.05 * entry["voltage_rms"], name
        assert entry["voltage_rmse"] > 5 * entry["voltage_rmse_server_filter"], name
