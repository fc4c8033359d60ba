"""``furuta-drake simulate``: files in the diagnosis' log format, safe output directories.

Reruns are checked in test_determinism.py."""

import base64
import json
import re

import msgpack
import numpy as np
import pytest
from pydrake.common.eigen_geometry import AngleAxis, Quaternion
from pydrake.math import RotationMatrix

from furuta_drake.cli import main
from furuta_drake.config import load_config
from furuta_drake.diagnosis.logs.load import load_log
from furuta_drake.plant import joint_indices, make_furuta_plant
from furuta_drake.rig import lund_rig
from furuta_drake.rig_file import load_rig
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
    config.write_text(
        "controller: {mode: open_loop}\nexcitation: {torque_rms: 0.001}\ninitial_state: [0.2, 0, 0, 0]\nduration: 3.0\n"
    )
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


def recorded_animation(html: str) -> dict:
    """The Meshcat animation a static HTML page embeds (msgpack commands as base64 data URIs), by path."""
    commands = [
        msgpack.unpackb(base64.b64decode(blob))
        for blob in re.findall(r"data:application/octet-binary;base64,([A-Za-z0-9+/=]+)", html)
    ]
    (animation,) = [command for command in commands if command["type"] == "set_animation"]
    return {entry["path"].rsplit("/", 1)[-1]: entry["clip"] for entry in animation["animations"]}


def test_html_recording_is_self_contained_replays_the_logged_run_and_leaves_the_log_unchanged(tmp_path):
    plain, recorded, html = tmp_path / "plain", tmp_path / "recorded", tmp_path / "run.html"
    run = ["simulate", "--duration", "0.3", "--seed", "2", "--out"]
    assert main([*run, str(plain)]) == 0
    assert main([*run, str(recorded), "--html", str(html)]) == 0
    # Recording (a visualizer in the diagram) must not perturb the simulation.
    for file in ("log.csv", "summary.json"):
        assert (recorded / file).read_bytes() == (plain / file).read_bytes(), file
    page = html.read_text()
    assert page.startswith("<!DOCTYPE html>")
    # Self-contained: no script, style or model fetched from a server.
    assert not re.search(r"<script[^>]+src=|<link[^>]+stylesheet|fetch\(\"(?!data:)", page)
    clips = recorded_animation(page)
    # The pendulum body's recorded pose is the logged state's: forward kinematics of the same rig, frame by
    # frame. A pose published at t lands on frame round(t fps), so allow the motion over half a frame.
    log = np.loadtxt(recorded / "log.csv", delimiter=",", skiprows=1)
    time, theta, phi, theta_dot, phi_dot = log[:, 0], log[:, 4], log[:, 5], log[:, 6], log[:, 7]
    clip = clips["pendulum"]
    tracks = {track["name"]: track["keys"] for track in clip["tracks"]}
    frames = [key["time"] for key in tracks[".position"]]
    assert frames[0] == 0 and np.all(np.diff(frames) > 0)
    assert frames[-1] / clip["fps"] == pytest.approx(0.3, abs=0.03)  # the whole run
    half_frame = 0.5 / clip["fps"]
    rig = lund_rig()
    plant = make_furuta_plant(rig)
    context = plant.CreateDefaultContext()
    theta_index, phi_index = joint_indices(plant)
    body = plant.GetBodyByName("pendulum")
    tolerance_angle = (np.max(np.abs(theta_dot)) + np.max(np.abs(phi_dot))) * half_frame + 1e-6
    tolerance_position = rig.arm_length * np.max(np.abs(phi_dot)) * half_frame + 1e-9
    for position, quaternion in zip(tracks[".position"], tracks[".quaternion"]):
        t = min(position["time"] / clip["fps"], time[-1])
        q = np.zeros(plant.num_positions())
        q[theta_index], q[phi_index] = np.interp(t, time, theta), np.interp(t, time, phi)
        plant.SetPositions(context, q)
        expected = plant.EvalBodyPoseInWorld(context, body)
        assert np.linalg.norm(np.array(position["value"]) - expected.translation()) <= tolerance_position
        x, y, z, w = quaternion["value"]  # three.js order
        relative = RotationMatrix(Quaternion(w, x, y, z)).InvertAndCompose(expected.rotation())
        assert AngleAxis(relative.matrix()).angle() <= tolerance_angle


def test_a_rig_file_simulates_with_the_effects_it_states(tmp_path):
    """A rig file's ``effects:`` section (as ``fitted_rig.yaml`` writes it) is part of the model ``simulate --rig``
    runs: the delay, the lag and the spring reach the world's actuator and disturbance, the rest unchanged."""
    rig_path = tmp_path / "rig.yaml"
    effects = {
        "input_delay": {"form": "fixed", "delay": 0.004},
        "actuator_lag": {"time_constant": 0.01},
        "arm_spring": {"form": "linear", "stiffness": 0.02, "equilibrium": 0.1},
    }
    rig_path.write_text(dump_yaml_dataclass(lund_rig().replace(effects=effects)))
    assert main(["simulate", "--rig", str(rig_path), "--out", str(tmp_path / "with"), "--duration", "0.5"]) == 0
    config = load_config(tmp_path / "with" / "config.yaml")
    assert config.actuator.delay == pytest.approx(0.004)
    assert config.actuator.lag_time_constant == pytest.approx(0.01)
    assert config.disturbance.arm_spring_stiffness == pytest.approx(0.02)
    assert config.disturbance.arm_spring_equilibrium == pytest.approx(0.1)
    assert config.rig.arm_inertia == pytest.approx(lund_rig().arm_inertia, rel=1e-12)
    # Without the section, the same file is the nominal model: no delay, no lag, no spring.
    rig_path.write_text(dump_yaml_dataclass(lund_rig()))
    assert main(["simulate", "--rig", str(rig_path), "--out", str(tmp_path / "without"), "--duration", "0.5"]) == 0
    nominal = load_config(tmp_path / "without" / "config.yaml")
    assert nominal.actuator.delay == 0.0 and nominal.actuator.lag_time_constant == 0.0
    assert nominal.disturbance.arm_spring_stiffness == 0.0
