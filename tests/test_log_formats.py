"""Logs as labs write them: a column mapping, the angle unit, and Parquet and MCAP files read the same run as the
CSV; every format goes through the same checks; malformed mappings and files are refused naming what is wrong."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import QUBE_DATA
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.diagnosis.logs.format import LogFormat
from furuta_drake.diagnosis.logs.load import load_log, load_logs
from furuta_drake.diagnosis.logs.writers import write_log
from furuta_drake.errors import ConfigError, LogError
from furuta_drake.rig_file import load_rig

QUBE_RIG = QUBE_DATA / "rig.yaml"
SWINGUP = QUBE_DATA / "swingup_250Hz_5s_0414.csv"
QUANSER = LogFormat.parse("time=t,theta=alpha,phi=theta,voltage=vm", "deg")  # Quanser's names, in degrees


def read_csv(path) -> dict[str, np.ndarray]:
    data = np.genfromtxt(path, delimiter=",", names=True)
    return {name: data[name] for name in data.dtype.names}


def quanser_columns(raw: dict[str, np.ndarray], unit=np.degrees) -> dict[str, np.ndarray]:
    """The run with Quanser's column names (arm 'theta', pendulum 'alpha'), the angles through ``unit``."""
    return {
        "t": raw["time"],
        "vm": raw["voltage"],
        "alpha": unit(raw["theta"]),
        "theta": unit(raw["phi"]),
        "current": np.zeros_like(raw["time"]),
    }


def arrays(log) -> list[np.ndarray]:
    return [log.time, log.theta, log.phi, log.input]


@pytest.fixture(scope="module")
def rig():
    return load_rig(QUBE_RIG)


@pytest.fixture(scope="module")
def original(rig):
    return load_log(SWINGUP, rig, QUBE_RIG)


def test_renamed_degrees_csv_reads_the_same_run(tmp_path, rig, original):
    path = write_log(tmp_path / SWINGUP.name, quanser_columns(read_csv(SWINGUP)))
    log = load_log(path, rig, QUBE_RIG, QUANSER)
    for got, want in zip(arrays(log), arrays(original)):
        np.testing.assert_allclose(got, want, rtol=1e-14, atol=1e-15)  # degrees and back: an ulp at most
    assert (log.name, log.input_kind, log.sample_period) == (original.name, "voltage", original.sample_period)
    assert log.ignored_columns == ("current",)


@pytest.mark.parametrize(
    "suffix, log_format",
    [
        (".parquet", LogFormat.parse("time=t,theta=alpha,phi=theta,voltage=vm")),
        (".mcap", LogFormat.parse("theta=alpha,phi=theta,voltage=vm", topic="/qube/log")),  # time: log_time
        (".mcap", LogFormat.parse("time=t,theta=alpha,phi=theta,voltage=vm")),  # time: a field; the only channel
    ],
)
def test_parquet_and_mcap_read_the_same_run_exactly(tmp_path, rig, original, suffix, log_format):
    path = write_log(
        tmp_path / f"run{suffix}", quanser_columns(read_csv(SWINGUP), unit=lambda a: a), topic="/qube/log", time="t"
    )
    log = load_log(path, rig, QUBE_RIG, log_format)
    for got, want in zip(arrays(log), arrays(original)):
        np.testing.assert_array_equal(got, want)


def test_angles_in_encoder_counts_use_the_rig_resolution(tmp_path, rig, original):
    counts = rig.counts_per_rev / (2 * math.pi)
    path = write_log(tmp_path / "counts.csv", quanser_columns(read_csv(SWINGUP), unit=lambda a: a * counts))
    log = load_log(path, rig, QUBE_RIG, LogFormat(QUANSER.columns, angle_unit="counts"))
    np.testing.assert_allclose(log.theta, original.theta, rtol=1e-14, atol=1e-14)
    np.testing.assert_allclose(log.phi, original.phi, rtol=1e-14, atol=1e-14)


def test_the_sign_checks_read_mapped_logs(tmp_path, rig):
    """The pooled sign check sees the mapped, converted angles: a renamed chirp with the rig's theta_direction
    flipped is refused like the original."""
    chirp = QUBE_DATA / "chirp_10to0Hz_pos1p5V_250Hz_10s.csv"
    path = write_log(tmp_path / chirp.name, quanser_columns(read_csv(chirp)))
    flipped = tmp_path / "rig.yaml"
    flipped.write_text(QUBE_RIG.read_text().replace("theta_direction: -1", "theta_direction: 1"))
    with pytest.raises(LogError, match="theta_direction: 1 contradicts the logs"):
        load_logs([path], load_rig(flipped), flipped, QUANSER)


@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".mcap"])
def test_every_format_gets_the_same_checks(tmp_path, rig, suffix):
    """A time gap of 10 samples and a wrapped pendulum angle are refused whatever the file format."""
    raw = read_csv(QUBE_DATA / "chirp_10to0Hz_pos1p5V_250Hz_10s.csv")
    keep = np.r_[0:100, 110:400]
    gap = write_log(tmp_path / f"gap{suffix}", {k: v[keep] for k, v in raw.items()})
    with pytest.raises(LogError, match=r"column 'time': gap of 0\.044 s from t = 0\.396 to t = 0\.44 s"):
        load_log(gap, rig, QUBE_RIG, LogFormat(topic=None))
    swing = slice(2000, 2300)  # t in [8.0, 9.2) s: through the resonance, across theta = pi
    wrapped = dict({k: v[swing] for k, v in raw.items()}, theta=np.angle(np.exp(1j * raw["theta"][swing])))
    with pytest.raises(LogError, match=r"column 'theta' jumps by [-+]6\.\d+ rad .* the angle is wrapped"):
        load_log(write_log(tmp_path / f"wrapped{suffix}", wrapped), rig, QUBE_RIG)


def test_a_log_that_matches_no_mapping_lists_its_columns_and_the_expected_ones(tmp_path, rig):
    path = write_log(tmp_path / "quanser.csv", quanser_columns(read_csv(SWINGUP)))
    with pytest.raises(LogError) as err:
        load_log(path, rig, QUBE_RIG, LogFormat.parse("theta=alpha,phi=theta,voltage=vm", "deg"))
    assert str(err.value) == (
        f"{path}:1: missing column 'time' (the file has: t, vm, alpha, theta, current; expected 'time', "
        f"'alpha' (theta), 'theta' (phi) and 'torque' or 'vm' (voltage); mapping in force: --columns "
        f"theta=alpha,phi=theta,voltage=vm --angle-unit deg; --columns maps other names)"
    )
    with pytest.raises(
        LogError,
        match=r"no input column: expected 'torque' \[N m\] or 'voltage' \[V\] \(the file "
        r"has: t, vm, alpha, theta, current; mapping in force: --columns time=t",
    ):
        load_log(path, rig, QUBE_RIG, LogFormat.parse("time=t,theta=alpha,phi=theta"))


@pytest.mark.parametrize(
    "columns, unit, message",
    [
        (
            "thta=alpha",
            None,
            "--columns: unknown column name 'thta' (furuta-drake's names: time, theta, phi, torque, "
            "voltage; write NAME=FILE_COLUMN)",
        ),
        ("theta=alpha,theta=a2", None, "--columns: 'theta' is mapped twice ('alpha' and 'a2')"),
        ("theta=alpha,phi=alpha", None, "--columns: the file's column 'alpha' is mapped to both 'theta' and 'phi'"),
        (
            "phi=theta",
            None,
            "--columns: the file's column 'theta' is read as 'phi', so 'theta' needs a column of its own (theta=...)",
        ),
        ("theta", None, "--columns: 'theta' is not NAME=FILE_COLUMN (e.g. theta=alpha)"),
        ("theta=", None, "--columns: theta= names no file column"),
        (None, "grad", "--angle-unit: unknown unit 'grad' (rad, deg or counts)"),
    ],
)
def test_a_malformed_format_names_the_flag(columns, unit, message):
    with pytest.raises(ConfigError) as err:
        LogFormat.parse(columns, unit)
    assert str(err.value) == message


def test_mcap_channel_choice_and_encoding(tmp_path, rig):
    from mcap.writer import Writer

    path = tmp_path / "two.mcap"
    with open(path, "wb") as stream:
        writer = Writer(stream)
        writer.start()
        for topic, encoding in (("/camera", "cdr"), ("/qube", "cdr")):
            channel = writer.register_channel(topic=topic, message_encoding=encoding, schema_id=0)
            writer.add_message(channel, log_time=0, data=b"\x00", publish_time=0)
        writer.finish()
    with pytest.raises(LogError, match=r"two\.mcap: 2 channels \(/camera, /qube\): name the run's with --topic"):
        load_log(path, rig, QUBE_RIG)
    with pytest.raises(
        LogError,
        match=r"two\.mcap: no channel with topic '/qbe' \(--topic\); the file has: "
        r"/camera, /qube",
    ):
        load_log(path, rig, QUBE_RIG, LogFormat(topic="/qbe"))
    with pytest.raises(LogError, match=r"topic '/qube': messages are 'cdr'-encoded; furuta-drake reads JSON"):
        load_log(path, rig, QUBE_RIG, LogFormat(topic="/qube"))


@settings(max_examples=25, deadline=None)
@given(
    suffix=st.sampled_from([".parquet", ".mcap"]),
    magic=st.sampled_from([b"", b"PAR1", b"\x89MCAP0\r\n"]),
    data=st.binary(max_size=300),
)
def test_random_bytes_under_a_parquet_or_mcap_name_raise_log_error(tmp_path_factory, rig, suffix, magic, data):
    path = tmp_path_factory.mktemp("log") / f"run{suffix}"
    path.write_bytes(magic + data + magic)
    with pytest.raises(LogError) as err:
        load_log(path, rig, QUBE_RIG)
    assert str(err.value).startswith(str(path)) and "\n" not in str(err.value)


def test_a_bad_value_is_located_by_row_or_message(tmp_path, rig):
    raw = {k: v[:50] for k, v in read_csv(SWINGUP).items()}
    raw["phi"] = raw["phi"].copy()
    raw["phi"][7] = np.nan
    with pytest.raises(LogError, match=r"nan\.parquet: row 8: column 'phi' is nan"):
        load_log(write_log(tmp_path / "nan.parquet", raw), rig, QUBE_RIG)
    with pytest.raises(LogError, match=r"nan\.mcap: topic '/furuta/log': message 8: column 'phi' is nan"):
        load_log(write_log(tmp_path / "nan.mcap", raw), rig, QUBE_RIG)


@pytest.mark.slow
def test_diagnose_on_a_renamed_degrees_copy_gives_the_same_report(tmp_path, fast_cli_diagnoses):
    """The end-to-end check: two real QUBE logs as a lab might write them (Quanser's names, degrees, an extra
    column) give the same report.json and figures as the same data in radians under furuta-drake's names, and
    config.yaml records the mapping. Both diagnoses run with the same brief sizes: the equality is of the data
    read, which every fitted figure of the report depends on whatever the sizes."""
    import json

    import yaml

    from furuta_drake.cli import main

    # The lab's file holds the angles in degrees; the reference file holds what they are in radians (the
    # loader's conversion), under furuta-drake's names: the same data, so the same report to the last digit.
    scale = math.pi / 180.0
    (tmp_path / "lab").mkdir()
    (tmp_path / "ref").mkdir()
    lab, ref = [], []
    for path, first in ((SWINGUP, 0.0), (QUBE_DATA / "chirp_10to0Hz_pos1p5V_250Hz_10s.csv", 6.0)):
        raw = read_csv(path)
        raw = {name: values[raw["time"] >= first] for name, values in raw.items()}  # the chirp's last 4 s
        degrees = {name: np.degrees(raw[name]) for name in ("theta", "phi")}
        lab.append(write_log(tmp_path / "lab" / path.name, quanser_columns(raw)))
        ref.append(
            write_log(
                tmp_path / "ref" / path.name, dict(raw, theta=degrees["theta"] * scale, phi=degrees["phi"] * scale)
            )
        )
    common = ["diagnose", "--rig", str(QUBE_RIG), "--workers", "1", "--train"]
    assert main(common + [str(p) for p in ref] + ["--out", str(tmp_path / "a")]) == 0
    assert (
        main(
            common
            + [str(p) for p in lab]
            + [
                "--columns",
                "time=t,theta=alpha,phi=theta,voltage=vm",
                "--angle-unit",
                "deg",
                "--out",
                str(tmp_path / "b"),
            ]
        )
        == 0
    )
    a, b = (json.loads((tmp_path / d / "report.json").read_text()) for d in ("a", "b"))
    assert any("extra" in note for note in b.pop("notes")) and a.pop("notes") == []  # the lab's extra column
    assert a == b
    assert sorted(p.name for p in (tmp_path / "a").glob("*.png")) == sorted(
        p.name for p in (tmp_path / "b").glob("*.png")
    )
    record = yaml.safe_load((tmp_path / "b" / "config.yaml").read_text())["options"]["log_format"]
    assert record == {
        "columns": {"time": "t", "theta": "alpha", "phi": "theta", "torque": "torque", "voltage": "vm"},
        "angle_unit": "deg",
        "topic": None,
        "run_column": None,
    }
