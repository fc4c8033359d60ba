"""The pendulum angle's zero (rig key ``theta_zero``): a log counted from the hanging pendulum is converted when the
rig file says so and refused, naming the key, when it does not; the real QUBE logs (zeroed upright) pass."""

from __future__ import annotations

import json
import math
import shutil

import numpy as np
import pytest
from conftest import QUBE_DATA

from furuta_drake.diagnosis.logs.load import check_theta_direction, load_log, load_logs
from furuta_drake.errors import ConfigError, LogError
from furuta_drake.rig_file import load_rig

QUBE_RIG = QUBE_DATA / "rig.yaml"
QUBE_LOGS = sorted(QUBE_DATA.glob("*.csv"))
CHIRP = QUBE_DATA / "chirp_10to0Hz_pos1p5V_250Hz_10s.csv"  # the pendulum hanging throughout
SATBAL = QUBE_DATA / "swingup_250Hz_10s_satbal.csv"  # swing-up, then balancing from t = 3.5 s


def hanging_zero_copy(path, out, rows=slice(None)):
    """``path`` (theta 0 upright, counted against the paper's direction: theta_direction -1) rewritten as a lab
    that zeroes the encoder with the pendulum hanging would log it: the logged theta minus pi in its own
    direction, i.e. logged + pi for theta_direction -1."""
    data = np.genfromtxt(path, delimiter=",", names=True)
    names = list(data.dtype.names)
    table = np.column_stack([data[n][rows] + (math.pi if n == "theta" else 0.0) for n in names])
    np.savetxt(out, table, delimiter=",", header=",".join(names), comments="", fmt="%.12g")
    return out


def rig_with(tmp_path, zero: str):
    path = tmp_path / f"rig_{len(list(tmp_path.glob('rig_*')))}.yaml"
    shutil.copy(QUBE_RIG, path)
    with path.open("a") as stream:
        stream.write(f"theta_zero: {zero}\n")
    return path


def test_a_hanging_zero_log_is_refused_naming_theta_zero_and_read_with_it(tmp_path):
    hanging = [hanging_zero_copy(p, tmp_path / p.name) for p in QUBE_LOGS]
    upright_rig = load_rig(QUBE_RIG)
    with pytest.raises(LogError, match=r"theta_zero: upright contradicts the logs.*set theta_zero: hanging$") as err:
        load_logs(hanging, upright_rig, QUBE_RIG)
    assert str(err.value).startswith(str(QUBE_RIG)) and "\n" not in str(err.value)
    rig_path = rig_with(tmp_path, "hanging")
    for path in (CHIRP, SATBAL):  # a hanging run and a swing-up with balancing each decide on their own
        with pytest.raises(LogError, match=r"theta_zero: upright contradicts.*set theta_zero: hanging$"):
            load_logs([hanging_zero_copy(path, tmp_path / "one.csv")], upright_rig, QUBE_RIG)
    converted = load_logs(hanging, load_rig(rig_path), rig_path)
    for log, original in zip(converted, load_logs(QUBE_LOGS, upright_rig, QUBE_RIG)):
        np.testing.assert_allclose(log.theta, original.theta, atol=1e-9)


def test_a_balancing_run_with_the_wrong_zero_is_refused_naming_theta_zero(tmp_path):
    # Balancing alone hides gravity's sign behind the feedback: the check refuses, naming both keys that would
    # explain the reversed coupling, rather than diagnosing.
    data = np.genfromtxt(SATBAL, delimiter=",", names=True)
    path = hanging_zero_copy(SATBAL, tmp_path / "bal.csv", data["time"] >= 3.5)
    rig = load_rig(QUBE_RIG)
    with pytest.raises(LogError, match=r"theta_zero: upright or theta_direction: -1 contradicts.*theta_zero: hanging"):
        check_theta_direction([load_log(path, rig)], rig, QUBE_RIG)


@pytest.mark.parametrize("zero, angle", [("upright", 0.0), ("hanging", math.pi), ("0.5", 0.5), ("-3", -3.0)])
def test_theta_zero_offsets_the_logged_theta(tmp_path, zero, angle):
    rig_path = rig_with(tmp_path, zero)
    log = load_log(CHIRP, load_rig(rig_path))
    reference = load_log(CHIRP, load_rig(QUBE_RIG))
    np.testing.assert_allclose(log.theta - reference.theta, angle, atol=1e-12)


@pytest.mark.parametrize("zero", ["sideways", "true", ".nan", "[0, 1]"])
def test_a_bad_theta_zero_names_the_key_and_line(tmp_path, zero):
    rig_path = rig_with(tmp_path, zero)
    line = len(rig_path.read_text().splitlines())
    with pytest.raises(ConfigError, match=rf"{rig_path.name}:{line}: theta_zero must be upright, hanging"):
        load_rig(rig_path)


@pytest.mark.slow
def test_diagnose_exits_2_on_the_wrong_zero_and_agrees_with_the_upright_log_when_told(
    tmp_path, capsys, fast_cli_diagnoses
):
    """Both diagnoses run with the same brief sizes: a converted log that is not the upright one (a zero off by
    more than rounding) changes the fits behind the verdict, effects and reduction compared, whatever the sizes."""
    from furuta_drake.cli import main

    log = SATBAL
    hanging = hanging_zero_copy(log, tmp_path / log.name)
    common = ["diagnose", "--workers", "1", "--train"]
    assert main(common + [str(hanging), "--rig", str(QUBE_RIG), "--out", str(tmp_path / "refused")]) == 2
    message = capsys.readouterr().err.strip().splitlines()
    assert len(message) == 1 and "theta_zero" in message[0] and str(QUBE_RIG) in message[0]
    assert not (tmp_path / "refused" / "report.json").exists()
    rig_path = rig_with(tmp_path, "hanging")
    assert main(common + [str(hanging), "--rig", str(rig_path), "--out", str(tmp_path / "hanging")]) == 0
    assert main(common + [str(log), "--rig", str(QUBE_RIG), "--out", str(tmp_path / "upright")]) == 0
    a, b = (json.loads((tmp_path / d / "report.json").read_text()) for d in ("upright", "hanging"))
    assert a["verdict"] == b["verdict"] and a["effects"] == b["effects"]
    assert a["gap"]["heldout_reduction"] == pytest.approx(b["gap"]["heldout_reduction"], rel=1e-6, abs=1e-9)


def test_a_pendulum_spinning_many_turns_is_radians_and_a_file_all_beyond_two_turns_is_degrees(tmp_path):
    # Bang-bang commands spin the pendulum through tens of turns: in radians it gets there from near the upright
    # or hanging. A file of degrees of a hanging pendulum (about 180) never comes within two turns (4 pi rad).
    data = np.genfromtxt(CHIRP, delimiter=",", names=True)
    names = list(data.dtype.names)
    turns = 30 * 2 * math.pi * (data["time"] - data["time"][0]) / np.ptp(data["time"])
    spinning = np.column_stack([data[n] + (turns if n == "theta" else 0.0) for n in names])
    path = tmp_path / "spin.csv"
    np.savetxt(path, spinning, delimiter=",", header=",".join(names), comments="", fmt="%.12g")
    log = load_log(path, load_rig(QUBE_RIG))
    assert np.max(np.abs(log.theta)) > 29 * 2 * math.pi
    degrees = np.column_stack([np.degrees(data[n]) if n in ("theta", "phi") else data[n] for n in names])
    np.savetxt(path, degrees, delimiter=",", header=",".join(names), comments="", fmt="%.12g")
    with pytest.raises(LogError, match=r"spin\.csv:2: .* no sample comes within two turns.*look like degrees"):
        load_log(path, load_rig(QUBE_RIG))
