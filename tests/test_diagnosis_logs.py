"""Log and rig loading of the diagnosis: format errors name file, line and column; sign checks on real data."""

import math
import shutil

import numpy as np
import pytest
from conftest import QUBE_DATA
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.diagnosis.logs.load import (
    check_input_direction,
    check_theta_direction,
    ignored_columns_note,
    load_log,
    load_logs,
)
from furuta_drake.errors import ConfigError, LogError
from furuta_drake.rig import lund_rig
from furuta_drake.rig_file import load_rig

QUBE_RIG = QUBE_DATA / "rig.yaml"
QUBE_LOGS = sorted(QUBE_DATA.glob("*.csv"))
CHIRP = QUBE_DATA / "chirp_10to0Hz_pos1p5V_250Hz_10s.csv"
SATBAL = QUBE_DATA / "swingup_250Hz_10s_satbal.csv"


def write_csv(path, header, rows):
    path.write_text(",".join(header) + "\n" + "".join(",".join(str(v) for v in row) + "\n" for row in rows))
    return path


def good_rows(n=50, period=0.001):
    t = np.arange(n) * period
    return [[f"{ti:.6f}", f"{0.1 * math.sin(ti):.6f}", f"{0.2 * ti:.6f}", "0.01"] for ti in t]


def read_qube(path):
    data = np.genfromtxt(path, delimiter=",", names=True)
    return {name: data[name] for name in data.dtype.names}


def write_qube(path, columns, rows=slice(None)):
    names = list(columns)
    table = np.column_stack([columns[n][rows] for n in names])
    np.savetxt(path, table, delimiter=",", header=",".join(names), comments="", fmt="%.9g")
    return path


HEADER = ["time", "theta", "phi", "torque"]


@pytest.mark.parametrize(
    "case, header, edit, expected",
    [
        ("empty", None, None, ":1: empty file"),
        ("header only", HEADER, lambda rows: [], ":1: header only"),
        ("missing theta", ["time", "phi", "torque", "x"], None, "missing column 'theta'"),
        ("no input", ["time", "theta", "phi", "current"], None, "no input column"),
        (
            "both inputs",
            ["time", "theta", "phi", "torque", "voltage"],
            lambda rows: [r + ["1"] for r in rows],
            "both 'torque' and 'voltage'",
        ),
        (
            "nan",
            HEADER,
            lambda rows: rows[:3] + [rows[3][:1] + ["nan"] + rows[3][2:]] + rows[4:],
            ":5: column 'theta' is nan",
        ),
        ("inf", HEADER, lambda rows: rows[:7] + [rows[7][:3] + ["inf"]] + rows[8:], ":9: column 'torque' is inf"),
        (
            "text",
            HEADER,
            lambda rows: rows[:2] + [rows[2][:2] + ["abc", rows[2][3]]] + rows[3:],
            ":4: column 'phi': 'abc' is not a number",
        ),
        (
            "empty field",
            HEADER,
            lambda rows: rows[:10] + [[""] + rows[10][1:]] + rows[11:],
            ":12: column 'time': '' is not a number",
        ),
        ("short row", HEADER, lambda rows: rows[:20] + [rows[20][:3]] + rows[21:], ":22: 3 fields, the header has 4"),
        (
            "duplicate time",
            HEADER,
            lambda rows: rows[:6] + [[rows[5][0]] + rows[6][1:]] + rows[7:],
            ":8: column 'time': 0.005 duplicates",
        ),
        ("backwards", HEADER, lambda rows: rows[:6] + [["0.001"] + rows[6][1:]] + rows[7:], ":8: column 'time'"),
        ("gap", HEADER, lambda rows: rows[:30] + rows[35:], ":32: column 'time': gap of 0.006 s from t = 0.029"),
        (
            "irregular",
            HEADER,
            lambda rows: rows[:40] + [["0.04002"] + rows[40][1:]] + rows[41:],
            ":42: column 'time': step 0.00102 s deviates by 2.0%",
        ),
    ],
)
def test_bad_logs_name_file_line_and_column(tmp_path, case, header, edit, expected):
    path = tmp_path / "run.csv"
    if header is None:
        path.write_text("")
    else:
        rows = good_rows()
        write_csv(path, header, edit(rows) if edit else rows)
    with pytest.raises(LogError) as err:
        load_log(path, lund_rig())
    message = str(err.value)
    assert "\n" not in message
    assert message.startswith(str(path))
    assert expected in message


def test_small_period_jitter_within_one_percent_is_accepted(tmp_path):
    rows = good_rows()
    rows[10][0] = "0.010005"  # 0.5 % late, then back on the grid
    log = load_log(write_csv(tmp_path / "run.csv", HEADER, rows), lund_rig())
    assert log.sample_period == pytest.approx(0.001)


def test_voltage_log_needs_a_motor_in_the_rig(tmp_path):
    path = write_csv(tmp_path / "run.csv", ["time", "theta", "phi", "voltage"], good_rows())
    with pytest.raises(LogError, match=r"rig_lund\.yaml has no 'motor' block"):
        load_log(path, lund_rig(), rig_path="rig_lund.yaml")


def test_voltage_command_maps_to_torque_through_the_motor():
    rig = load_rig(QUBE_RIG)
    log = load_log(CHIRP, rig)
    assert log.input_kind == "voltage"
    assert log.sample_period == pytest.approx(0.004)
    # kt / R = 0.042 / 8.4 N m per volt: the +-1.5 V chirp is +-7.5 mN m at stall.
    np.testing.assert_allclose(log.torque_command, log.input * 0.005)
    assert np.max(np.abs(log.torque_command)) == pytest.approx(7.5e-3, rel=1e-3)


def test_theta_direction_is_applied():
    raw = read_qube(CHIRP)
    log = load_log(CHIRP, load_rig(QUBE_RIG))  # theta_direction: -1
    np.testing.assert_allclose(log.theta, -raw["theta"])
    np.testing.assert_allclose(log.phi, raw["phi"])


def test_extra_columns_are_ignored_and_named_once(tmp_path):
    rows = [r + ["7", "x"] for r in good_rows()]
    log = load_log(write_csv(tmp_path / "run.csv", HEADER + ["true_theta", "note"], rows), lund_rig())
    assert log.ignored_columns == ("true_theta", "note")
    note = ignored_columns_note([log, log])
    assert note.count("\n") == 0 and "run.csv: true_theta, note" in note
    plain = load_log(write_csv(tmp_path / "plain.csv", HEADER, good_rows()), lund_rig())
    assert ignored_columns_note([plain]) is None


def test_velocity_columns_are_named_as_unused_with_the_reason(tmp_path):
    rows = [r + ["0.5", "-0.25"] for r in good_rows()]
    log = load_log(write_csv(tmp_path / "run.csv", HEADER + ["theta_dot", "phi_dot"], rows), lund_rig())
    assert log.ignored_columns == ("theta_dot", "phi_dot")
    note = ignored_columns_note([log])
    assert "velocity columns (phi_dot, theta_dot) are not used" in note and "start state" in note
    other = load_log(
        write_csv(tmp_path / "other.csv", HEADER + ["true_theta"], [r + ["7"] for r in good_rows()]), lund_rig()
    )
    assert "velocity" not in ignored_columns_note([other])


def test_wrapped_angles_are_refused_with_the_line(tmp_path):
    raw = read_qube(QUBE_DATA / "swingup_250Hz_10s_a.csv")
    wrapped = dict(raw, theta=np.angle(np.exp(1j * raw["theta"])))  # into (-pi, pi]
    first_wrap = int(np.flatnonzero(np.abs(np.diff(wrapped["theta"])) > math.pi)[0]) + 1
    path = write_qube(tmp_path / "wrapped.csv", wrapped)
    with pytest.raises(
        LogError,
        match=rf"wrapped\.csv:{first_wrap + 2}: column 'theta' .* wrapped; the diagnosis "
        r"wants unwrapped",
    ):
        load_log(path, load_rig(QUBE_RIG))


def test_hanging_log_in_degrees_is_refused(tmp_path):
    raw = read_qube(CHIRP)
    degrees = dict(raw, theta=np.degrees(raw["theta"]), phi=np.degrees(raw["phi"]))
    with pytest.raises(LogError, match=r"degrees; the diagnosis wants radians"):
        load_log(write_qube(tmp_path / "deg.csv", degrees), load_rig(QUBE_RIG))


def test_balancing_log_in_degrees_is_refused_from_the_arm_response(tmp_path):
    # The balancing segment stays within +-6 degrees of the upright: only the arm's response to the input,
    # 57 times what the rig's inertia allows, gives the unit away.
    raw = read_qube(SATBAL)
    balancing = raw["time"] >= 3.5
    degrees = dict(raw, theta=np.degrees(raw["theta"]), phi=np.degrees(raw["phi"]))
    path = write_qube(tmp_path / "deg.csv", degrees, balancing)
    rig = load_rig(QUBE_RIG)
    log = load_log(path, rig)
    assert np.max(np.abs(log.theta)) < 2 * math.pi
    with pytest.raises(LogError, match=r"degrees; the diagnosis wants radians"):
        check_input_direction([log], rig)


def test_real_qube_logs_pass_the_sign_checks_with_their_rig_file():
    logs = load_logs(QUBE_LOGS, load_rig(QUBE_RIG), QUBE_RIG)
    assert [log.name for log in logs] == [p.name for p in QUBE_LOGS]
    assert sorted({round(log.sample_period, 9) for log in logs}) == [0.002, 0.004]


def test_flipped_theta_direction_is_refused_naming_it(tmp_path):
    rig_path = tmp_path / "rig.yaml"
    shutil.copy(QUBE_RIG, rig_path)
    rig_path.write_text(rig_path.read_text().replace("theta_direction: -1", "theta_direction: 1"))
    rig = load_rig(rig_path)
    assert rig.theta_direction == 1
    with pytest.raises(LogError, match=r"theta_direction: 1 contradicts the logs.*set theta_direction: -1") as err:
        load_logs(QUBE_LOGS, rig, rig_path)
    assert str(err.value).startswith(str(rig_path))
    for path in QUBE_LOGS:  # every single real log carries enough motion to decide on its own
        with pytest.raises(LogError, match="theta_direction"):
            check_theta_direction([load_log(path, rig)], rig)


def test_reversed_phi_is_refused(tmp_path):
    raw = read_qube(CHIRP)
    path = write_qube(tmp_path / "negphi.csv", dict(raw, phi=-raw["phi"]))
    with pytest.raises(LogError, match=r"column 'phi' counts against the input"):
        load_logs([path], load_rig(QUBE_RIG))


def test_quiet_logs_decide_nothing(tmp_path):
    # A balancing segment of a real log moves a few encoder counts: too little to judge a sign, so even the
    # wrong theta_direction passes (the full logs above decide).
    raw = read_qube(QUBE_DATA / "swingup_250Hz_10s_a.csv")
    flipped = load_rig(QUBE_RIG).replace(theta_direction=1)
    path = write_qube(tmp_path / "bal.csv", raw, raw["time"] >= 3.5)
    log = load_log(path, flipped)
    check_theta_direction([log], flipped)
    check_input_direction([log], flipped)


def test_logs_too_short_to_judge_pass_the_sign_checks(tmp_path):
    logs = load_logs([write_csv(tmp_path / "short.csv", HEADER, good_rows(5))], lund_rig())
    assert len(logs[0].time) == 5


def test_rig_file_errors_name_the_key(tmp_path):
    rig_path = tmp_path / "rig.yaml"
    rig_path.write_text(QUBE_RIG.read_text() + "arm_lenght: 0.1\n")
    with pytest.raises(ConfigError, match=r"rig\.yaml:\d+: arm_lenght unknown key"):
        load_rig(rig_path)
    assert load_rig(QUBE_RIG).counts_per_rev == 2048


def test_a_ten_minute_1khz_log_loads_whole(tmp_path):
    """600k rows (a ten-minute log at 1 kHz) load completely; their speed is measured in benchmarks, not here."""
    n = 600_000
    t = np.arange(n) * 1e-3
    path = tmp_path / "long.csv"
    np.savetxt(
        path,
        np.column_stack([t, 0.01 * np.sin(t), 0.1 * np.sin(3 * t), np.sin(t)]),
        delimiter=",",
        header="time,torque,theta,phi",
        comments="",
        fmt="%.9g",
    )
    log = load_log(path, lund_rig())
    assert len(log.time) == n and log.time[-1] == pytest.approx(599.999)


@settings(max_examples=25, deadline=None)
@given(period=st.sampled_from([0.001, 0.002, 0.004]), n=st.integers(5, 400), data=st.data())
def test_first_non_finite_value_is_located(tmp_path_factory, period, n, data):
    rows = good_rows(n, period)
    row = data.draw(st.integers(0, n - 1))
    column = data.draw(st.integers(0, 3))
    bad = data.draw(st.sampled_from(["nan", "inf", "-inf"]))
    rows[row][column] = bad
    path = write_csv(tmp_path_factory.mktemp("log") / "run.csv", HEADER, rows)
    with pytest.raises(LogError, match=rf"run\.csv:{row + 2}: column '{HEADER[column]}' is "):
        load_log(path, lund_rig())


@settings(max_examples=25, deadline=None)
@given(period=st.sampled_from([0.001, 0.002, 0.004]), n=st.integers(3, 300))
def test_valid_logs_round_trip(tmp_path_factory, period, n):
    t = np.arange(n) * period
    theta, phi, torque = 0.3 * np.sin(5 * t), np.cumsum(np.full(n, 0.001)), 0.05 * np.cos(t)
    path = tmp_path_factory.mktemp("log") / "run.csv"
    np.savetxt(
        path,
        np.column_stack([t, theta, phi, torque]),
        delimiter=",",
        header="time,theta,phi,torque",
        comments="",
        fmt="%.12g",
    )
    log = load_log(path, lund_rig())
    assert log.sample_period == pytest.approx(period)
    np.testing.assert_allclose(log.theta, theta, atol=1e-11)
    np.testing.assert_allclose(log.torque_command, torque, atol=1e-11)
    assert log.input_kind == "torque" and log.name == "run.csv"


def test_the_shipped_real_logs_are_the_six_documented_runs():
    from furuta_drake.data import QUBE_REAL_DIR, qube_real_logs

    logs = qube_real_logs()
    assert [p.name for p in logs] == sorted(p.name for p in QUBE_REAL_DIR.glob("*.csv")) and len(logs) == 6
    assert all(p.read_text().splitlines()[0] == "time,voltage,theta,phi" for p in logs)
