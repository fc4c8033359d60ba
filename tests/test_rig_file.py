"""Rig files: every required key must be present and physical, ``rig --template`` round-trips to the shipped rigs,
and ``rig --check`` prints the constants of the Lund rig that the paper's rig documentation gives, and a drive's."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

from furuta_drake.cli import main
from furuta_drake.config import load_config
from furuta_drake.errors import ConfigError
from furuta_drake.rig import RIGS, DriveParameters, MotorParameters, RigParameters, lund_rig
from furuta_drake.rig_file import load_rig, rig_check, rig_template

RIG_KEYS = [f.name for f in dataclasses.fields(RigParameters) if f.metadata.get("required")]
MOTOR_KEYS = [f.name for f in dataclasses.fields(MotorParameters)]
DRIVE_KEYS = [f.name for f in dataclasses.fields(DriveParameters)]
SECTION_REQUIRED = MOTOR_KEYS + [f.name for f in dataclasses.fields(DriveParameters) if f.metadata.get("required")]


def test_the_required_keys_are_those_the_rig_file_format_does_not_mark_optional():
    assert RIG_KEYS == [
        "arm_inertia",
        "arm_length",
        "pendulum_mass",
        "pendulum_com",
        "pendulum_inertia",
        "gravity",
        "counts_per_rev",
        "sample_period",
        "torque_limit",
    ]
    assert all(f.metadata.get("required") for f in dataclasses.fields(MotorParameters))
    assert SECTION_REQUIRED[len(MOTOR_KEYS) :] == ["gear_ratio", "rotor_inertia"]


def without_key(text: str, key: str) -> str:
    """``text`` with the line of ``key`` (at any indentation) removed."""
    kept = [line for line in text.splitlines() if not re.match(rf"\s*{key}:", line)]
    assert len(kept) == len(text.splitlines()) - 1, key
    return "\n".join(kept) + "\n"


@pytest.mark.parametrize("key", RIG_KEYS + SECTION_REQUIRED)
def test_a_missing_required_key_exits_2_naming_the_key_and_the_file(key, tmp_path, capsys):
    path = tmp_path / "my_rig.yaml"
    path.write_text(without_key(rig_template(RIGS["geared"](), "test"), key))
    assert main(["rig", "--check", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1
    # A rig key is missing from the file; a motor or drive key from its block, located at the block's line.
    section, schema = ("motor", MotorParameters) if key in MOTOR_KEYS else ("drive", DriveParameters)
    where = re.escape(f"{path}: ") if key in RIG_KEYS else re.escape(f"{path}:") + rf"\d+: {section}: "
    assert re.match(f"furuta-drake rig: error: {where}missing required key '{key}' ", err[0]), err[0]
    unit = dataclasses.fields(RigParameters if key in RIG_KEYS else schema)
    assert next(f for f in unit if f.name == key).metadata["unit"] in err[0]


def test_the_rig_section_of_a_simulate_config_needs_every_required_key(tmp_path):
    path = tmp_path / "sim.yaml"
    path.write_text("duration: 1.0\nrig:\n  arm_inertia: 1.274e-3\n  arm_length: 0.25\n")
    with pytest.raises(ConfigError, match=r"sim\.yaml:3: rig: missing required key 'pendulum_mass' \(.*\[kg\]\)"):
        load_config(path)


@pytest.mark.parametrize("name", sorted(RIGS))
def test_the_template_round_trips_to_the_shipped_rig(name, tmp_path, capsys):
    assert main(["rig", "--template", name]) == 0
    path = tmp_path / "my_rig.yaml"
    path.write_text(capsys.readouterr().out)
    assert load_rig(path) == RIGS[name]()  # what diagnose --rig reads
    assert main(["rig", "--check", str(path)]) == 0
    assert "alpha1" in capsys.readouterr().out
    # Every key's paragraph says whether it is required and how to measure it.
    paragraphs = {
        re.match(r"\s*(?:# )?(\w+): ", block.splitlines()[-1]).group(1): block
        for block in path.read_text().strip().split("\n\n")[1:]
    }
    sections = set(MOTOR_KEYS) | set(DRIVE_KEYS)
    assert set(paragraphs) == ({f.name for f in dataclasses.fields(RigParameters)} - {"motor", "drive"}) | sections
    for key, block in paragraphs.items():
        assert "How:" in block and ("; required." in block) == (key in RIG_KEYS + SECTION_REQUIRED), block


def test_check_gives_the_lund_rig_constants():
    # The Lund rig's linearization at the upright (the paper's rig documentation): alpha1 = 47.949,
    # alpha2 = -35.640 1/s^2, beta3..beta5 = 491.16, -365.07, 570.10 1/(kg m^2), open-loop poles 0, 0, +-6.925.
    c = rig_check(lund_rig())
    assert c["alpha1"] == pytest.approx(47.949, rel=1e-4)
    assert c["alpha2"] == pytest.approx(-35.640, rel=1e-4)
    assert (c["beta3"], c["beta4"], c["beta5"]) == pytest.approx((491.16, -365.07, 570.10), rel=1e-4)
    assert c["upright_poles"] == pytest.approx([-6.925, 0.0, 0.0, 6.925], abs=5e-4)
    # Lumped constants 0.0033472, 0.0038852, 0.0024879 kg m^2 and 0.097625 N m; hanging with the arm held:
    # a compound pendulum, sqrt(m g l / (J_p + m l^2)); arm free: sqrt(m g l a / (a b - c^2)).
    a, b, cc, mgl = 0.0033472, 0.0038852, 0.0024879, 0.097625
    assert (c["arm_inertia_total"], c["pendulum_inertia_total"], c["coupling"], c["gravity_torque"]) == pytest.approx(
        (a, b, cc, mgl), rel=1e-4
    )
    assert c["hanging_arm_held"] == pytest.approx(math.sqrt(mgl / b), rel=1e-4)
    assert c["hanging_arm_free"] == pytest.approx(math.sqrt(mgl * a / (a * b - cc**2)), rel=1e-4)
    # The free-arm hanging frequency equals the upright's unstable pole: both are sqrt(|alpha1|).
    assert c["hanging_arm_free"] == pytest.approx(math.sqrt(c["alpha1"]), rel=1e-12)


def test_check_prints_the_lund_constants_in_rad_per_s_hz_and_seconds(tmp_path, capsys):
    path = tmp_path / "lund.yaml"
    path.write_text(rig_template(lund_rig(), "test"))
    assert main(["rig", "--check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "alpha1 = 47.949 1/s^2" in out and "-6.925, 0, 0, +6.925 rad/s" in out
    held = math.sqrt(0.097625 / 0.0038852)
    assert f"arm held: {held:.4g} rad/s = {held / (2 * np.pi):.4g} Hz, period {2 * np.pi / held:.4g} s" in out


@pytest.mark.parametrize(
    "line, edited, message",
    [
        ("  gear_ratio: 30.0", "  gear_raito: 30.0", r"drive\.gear_raito unknown key 'gear_raito' in DriveParameters"),
        ("  gear_ratio: 30.0", "  gear_ratio: 0.5", r"drive\.gear_ratio must be a finite number >= 1 .*got 0\.5"),
        ("  rotor_inertia: 1.0e-06", "  rotor_inertia: -1.0e-06", r"drive\.rotor_inertia must be a positive finite"),
        ("  encoder: arm", "  encoder: shaft", r"drive\.encoder must be one of \['arm', 'motor'\], got 'shaft'"),
        ("  backlash: 0.0", "  backlash: -0.01", r"drive\.backlash must be a non-negative finite number"),
        ("  stiffness: null", "  stiffness: 0", r"drive\.stiffness must be a positive finite number, got 0"),
        ("  damping: 0.0", "  damping: 0.01", r"drive\.damping needs a stiffness"),
    ],
)
def test_a_non_physical_drive_key_exits_2_naming_the_key_and_its_line(line, edited, message, tmp_path, capsys):
    text = rig_template(RIGS["geared"](), "test")
    assert text.count(f"\n{line}\n") == 1
    path = tmp_path / "my_rig.yaml"
    path.write_text(text.replace(f"\n{line}\n", f"\n{edited}\n"))
    assert main(["rig", "--check", str(path)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    line_number = path.read_text().splitlines().index(edited) + 1
    assert len(err) == 1 and re.match(
        rf"furuta-drake rig: error: {re.escape(str(path))}:{line_number}: {message}", err[0]
    )


def test_check_gives_the_drives_reflected_inertia_and_resonance(tmp_path, capsys):
    """The geared rig (30:1, rotor 1e-6 kg m^2, arm 3.2e-4 kg m^2, pendulum 30 g at 0.15 m) with a belt of 8 N m/rad
    damped by 2e-3 N m s/rad, logged at 100 Hz."""
    rig = RIGS["geared"]()
    rig = rig.replace(drive=dataclasses.replace(rig.drive, stiffness=8.0, damping=2e-3, backlash=0.01))
    path = tmp_path / "belt.yaml"
    path.write_text(rig_template(rig, "test"))
    assert main(["rig", "--check", str(path)]) == 0
    out = capsys.readouterr().out
    J, Ja = 1e-6 * 30**2, 3.2e-4 + 0.03 * 0.15**2
    assert f"J_m N^2 = {J:.6g} kg m^2" in out and f"{J / (J + Ja):.0%} of J_arm + m r^2" in out
    w = math.sqrt(8.0 * (1 / J + 1 / Ja))
    zeta = 2e-3 / (2 * math.sqrt(8.0 * J * Ja / (J + Ja)))
    assert f"at {w:.4g} rad/s = {w / (2 * math.pi):.4g} Hz, damping ratio {zeta:.3g}" in out
    assert f"2 b = {0.02 / (2 * math.pi / 2400):.3g} counts" in out  # 2400-count encoders
    assert "Nyquist" not in out  # 20.7 Hz, below 50 Hz
    path.write_text(rig_template(rig.replace(sample_period=0.04), "test"))  # 25 Hz logs: Nyquist 12.5 Hz
    assert main(["rig", "--check", str(path)]) == 0
    assert f"logging above {2 * w / (2 * math.pi):.4g} Hz samples the ringing" in capsys.readouterr().out


def test_the_diagnosis_reads_a_drive_with_backlash_and_compliance_from_the_rig_file(tmp_path):
    from furuta_drake.effects.vocabulary import rig_model

    rig = RIGS["geared"]()
    drive = dataclasses.replace(rig.drive, backlash=0.01, stiffness=2.0, damping=0.01)
    path = tmp_path / "rig.yaml"
    path.write_text(rig_template(rig.replace(drive=drive), "test"))
    model = rig_model(load_rig(path))
    assert model.has_drive
    assert (model.drive_backlash, model.drive_stiffness, model.drive_damping) == (0.01, 2.0, 0.01)
    assert 0.0 < model.rotor_share < 1.0  # the rotor is a body of its own beside the arm
