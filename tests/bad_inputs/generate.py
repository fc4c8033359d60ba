"""Regenerate the log and rig files of this corpus: ``python tests/bad_inputs/generate.py`` (from the repo root).

Synthetic logs are a smooth 1 kHz torque run; the sign, unit and wrap cases are cut from the real QUBE-Servo 2
recordings in the repository's ``data/qube-servo2-real`` (BSD-3-Clause, see README.md). The hand-written YAML files
(``config_*.yaml``, ``sweep_*.yaml``) and ``manifest.yaml`` are not generated.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from furuta_drake.data import QUBE_REAL_DIR as QUBE_DATA
from furuta_drake.diagnosis.logs.writers import write_log

HERE = Path(__file__).resolve().parent
QUBE_RIG_TEXT = (QUBE_DATA / "rig.yaml").read_text()
THETA_MINUS = (
    "theta_direction: -1         # these logs count theta opposite to the paper's convention (checked on the data)"
)

LUND_RIG = """\
# The Lund pendulum of the paper (furuta_drake.rig.lund_rig) as a furuta-drake rig file.
arm_inertia: 1.274e-3
arm_length: 0.25
pendulum_mass: 0.033172
pendulum_com: 0.30
pendulum_inertia: 8.997e-4
gravity: 9.81
counts_per_rev: 4096
sample_period: 0.001
torque_limit: 0.2
"""


def synthetic_rows(n: int = 300, period: float = 1e-3) -> list[list[str]]:
    """time, theta, phi, torque of a quiet balancing-like run (too short for the sign checks to decide)."""
    rows = []
    for k in range(n):
        t = k * period
        rows.append(
            [
                f"{t:.3f}",
                f"{0.02 * math.sin(2 * math.pi * 1.5 * t):.6f}",
                f"{0.1 * math.sin(2 * math.pi * 0.5 * t):.6f}",
                f"{0.01 * math.cos(2 * math.pi * t):.6f}",
            ]
        )
    return rows


def write_rows(name: str, header: list[str], rows: list[list[str]]) -> None:
    (HERE / name).write_text(",".join(header) + "\n" + "".join(",".join(r) + "\n" for r in rows))


def read_qube(name: str) -> dict[str, np.ndarray]:
    data = np.genfromtxt(QUBE_DATA / name, delimiter=",", names=True)
    return {column: data[column] for column in data.dtype.names}


def write_qube(name: str, columns: dict[str, np.ndarray], rows: np.ndarray) -> None:
    table = np.column_stack([columns[c][rows] for c in columns])
    np.savetxt(HERE / name, table, delimiter=",", header=",".join(columns), comments="", fmt="%.7f")


def synthetic_logs() -> None:
    header = ["time", "theta", "phi", "torque"]
    rows = synthetic_rows()
    write_rows("good_torque.csv", header, rows)
    (HERE / "log_empty.csv").write_text("")
    write_rows("log_header_only.csv", header, [])
    write_rows("log_missing_theta.csv", ["time", "phi", "torque"], [[r[0], r[2], r[3]] for r in rows])
    write_rows("log_no_input.csv", ["time", "theta", "phi", "current"], rows)
    write_rows("log_torque_and_voltage.csv", header + ["voltage"], [r + ["0.5"] for r in rows])

    def edited(row: int, column: int, value: str) -> list[list[str]]:
        out = [list(r) for r in rows]
        out[row][column] = value
        return out

    write_rows("log_nan.csv", header, edited(120, 1, "nan"))  # file line 122
    write_rows("log_inf.csv", header, edited(200, 3, "inf"))  # file line 202
    write_rows("log_text_in_number.csv", header, edited(57, 2, "#VALUE!"))  # file line 59
    write_rows("log_duplicate_time.csv", header, edited(150, 0, rows[149][0]))  # file line 152
    write_rows("log_time_backwards.csv", header, edited(150, 0, rows[100][0]))  # file line 152
    write_rows("log_irregular_period.csv", header, edited(80, 0, "0.0802"))  # 1.2 ms then 0.8 ms; line 82
    write_rows("log_time_gap.csv", header, rows[:100] + rows[120:])  # 20 samples missing before line 102
    # The arm turned near +pi and logged wrapped into (-pi, pi]: it jumps to -pi at file line 139.
    write_rows(
        "log_wrapped_phi.csv",
        header,
        [[t, theta, f"{math.remainder(float(phi) + 3.1, 2 * math.pi):.6f}", u] for t, theta, phi, u in rows],
    )
    truncated = "".join(",".join(r) + "\n" for r in rows[:250])
    (HERE / "log_truncated.csv").write_text(
        ",".join(header) + "\n" + truncated + rows[250][0] + "," + rows[250][1][:3]
    )  # cut mid-row at line 252, no newline


def qube_logs() -> None:
    chirp = read_qube("chirp_10to0Hz_pos1p5V_250Hz_10s.csv")
    swing = (chirp["time"] >= 8.0) & (chirp["time"] < 9.2)  # 300 samples through the pendulum resonance
    write_qube("qube_chirp.csv", chirp, swing)
    wrapped = np.angle(np.exp(1j * chirp["theta"]))  # hanging at +pi: the swing wraps between +pi and -pi
    write_qube("log_wrapped_theta.csv", dict(chirp, theta=wrapped), swing)
    start = chirp["time"] < 1.2
    write_qube(
        "log_degrees_hanging.csv", dict(chirp, theta=np.degrees(chirp["theta"]), phi=np.degrees(chirp["phi"])), start
    )
    satbal = read_qube("swingup_250Hz_10s_satbal.csv")
    balancing = (satbal["time"] >= 4.0) & (satbal["time"] < 5.6)  # 400 samples, within 6 degrees of upright
    write_qube(
        "log_degrees_balancing.csv",
        dict(satbal, theta=np.degrees(satbal["theta"]), phi=np.degrees(satbal["phi"])),
        balancing,
    )
    swingup = read_qube("swingup_250Hz_10s_a.csv")
    kick = swingup["time"] < 2.0  # 500 samples of the energy swing-up: the arm answers the voltage clearly
    write_qube("log_phi_reversed.csv", dict(swingup, phi=-swingup["phi"]), kick)


def other_formats() -> None:
    """Parquet and MCAP copies of the synthetic torque log, one with a column missing, and files that are not
    Parquet or MCAP at all."""
    columns = {
        name: np.array([float(row[j]) for row in synthetic_rows()])
        for j, name in enumerate(["time", "theta", "phi", "torque"])
    }
    write_log(HERE / "good_torque.mcap", columns, topic="/furuta/log")
    write_log(HERE / "log_missing_theta.parquet", {k: v for k, v in columns.items() if k != "theta"})
    (HERE / "log_not_parquet.parquet").write_text("time,theta,phi,torque\n0,0,0,0\n")
    (HERE / "log_not_mcap.mcap").write_bytes(b"\x89MCAP0\r\n" + b"not an MCAP file, cut after its magic\n")


def rigs() -> None:
    assert THETA_MINUS in QUBE_RIG_TEXT
    (HERE / "rig_lund.yaml").write_text(LUND_RIG)
    (HERE / "rig_qube.yaml").write_text(QUBE_RIG_TEXT)
    (HERE / "rig_qube_theta_plus.yaml").write_text(
        QUBE_RIG_TEXT.replace(
            THETA_MINUS, "theta_direction: 1          # wrong for these logs (they count theta the other way)"
        )
    )
    edits = {
        "rig_misspelt_key.yaml": ("arm_length: 0.25", "arm_lenght: 0.25"),
        "rig_negative_mass.yaml": ("pendulum_mass: 0.033172", "pendulum_mass: -0.033172"),
        "rig_negative_inertia.yaml": ("pendulum_inertia: 8.997e-4", "pendulum_inertia: -8.997e-4"),
        "rig_zero_sample_period.yaml": ("sample_period: 0.001", "sample_period: 0"),
        "rig_zero_counts.yaml": ("counts_per_rev: 4096", "counts_per_rev: 0"),
        "rig_wrong_type.yaml": ("arm_length: 0.25", "arm_length: 25 cm"),
        "rig_missing_arm_inertia.yaml": ("arm_inertia: 1.274e-3\n", ""),
    }
    for name, (old, new) in edits.items():
        assert old in LUND_RIG, old
        (HERE / name).write_text(LUND_RIG.replace(old, new))
    (HERE / "rig_empty.yaml").write_text("")


if __name__ == "__main__":
    synthetic_logs()
    qube_logs()
    other_formats()
    rigs()
