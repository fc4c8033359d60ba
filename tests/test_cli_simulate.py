"""``furuta-drake simulate``: files in the spec's format, safe output directories (reruns: test_determinism.py)."""

import json

import numpy as np
import pytest

from furuta_drake.cli import main
from furuta_drake.config import load_config
from furuta_drake.diagnosis.logs import load_log, load_rig
from furuta_drake.rig import lund_rig
from furuta_drake.yamlio import dump_yaml_dataclass


def test_simulate_writes_log_config_summary_and_plot(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["simulate", "--out", str(out), "--duration", "1", "--seed", "3"]) == 0
    assert {p.name for p in out.iterdir()} == {"log.csv", "config.yaml", "summary.json", "states.png"}
    header = (out / "log.csv").read_text().splitlines()[0].split(",")
    assert header[:4] == ["time", "torque", "theta", "phi"]
    config = load_config(out / "config.yaml")
    assert config.seed == 3 and config.duration == 1.0
    summary = json.loads((out / "summary.json").read_text())
    assert summary["samples"] == 1000 and summary["diverged"] is False
    # The log loads through the diagnosis' own strict loader, against the rig it came from.
    rig_path = tmp_path / "rig.yaml"
    rig_path.write_text(dump_yaml_dataclass(lund_rig()))
    log = load_log(out / "log.csv", load_rig(rig_path))
    assert log.input_kind == "torque" and log.sample_period == pytest.approx(1e-3, rel=1e-9)
    assert "real time" in capsys.readouterr().out


def test_refuses_a_non_empty_directory_without_force(tmp_path, capsys):
    out = tmp_path / "run"
    out.mkdir()
    (out / "precious.txt").write_text("keep me")
    assert main(["simulate", "--out", str(out), "--duration", "0.2"]) == 2
    assert "--force" in capsys.readouterr().err
    assert (out / "precious.txt").read_text() == "keep me"
    assert main(["simulate", "--out", str(out), "--duration", "0.2", "--force"]) == 0
    assert not (out / "precious.txt").exists() and (out / "log.csv").exists()


def test_a_diverging_run_exits_3_with_time_and_cause_and_writes_nothing(tmp_path, capsys):
    config = tmp_path / "fall.yaml"
    config.write_text("controller: {mode: open_loop}\nexcitation: {torque_rms: 0.001}\n"
                      "initial_state: [0.2, 0, 0, 0]\nduration: 3.0\n")
    out = tmp_path / "run"
    assert main(["simulate", "--config", str(config), "--out", str(out)]) == 3
    err = capsys.readouterr().err
    assert "diverged at t =" in err and "fell" in err
    assert not out.exists()


def test_qube_rig_simulates_with_its_motor_back_emf(tmp_path):
    out = tmp_path / "qube"
    assert main(["simulate", "--rig", "qube_servo2", "--out", str(out), "--duration", "1"]) == 0
    data = np.loadtxt(out / "log.csv", delimiter=",", skiprows=1)
    assert np.max(np.abs(data[:, 2])) < 0.2  # balanced
