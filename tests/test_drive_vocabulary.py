"""The vocabulary's drive effects: backlash and compliance are offered only for a rig file that states a drive (its
gear ratio and rotor inertia give the rotor's share of the arm's inertia); their search ranges are those of the
physics (a play of up to 0.2 rad; a coupling ringing between 0.5 Hz and a gear's tooth contact, 200 Hz, against the
reduced inertia of rotor and arm side); at zero backlash and at the stiffest coupling they vanish into the rigid
drive; the rig file's drive: section, not its effects: section, holds them; a drive candidate asked for on a rig
without a drive is refused."""

from __future__ import annotations

import math

import numpy as np
import pytest

from furuta_drake.diagnosis.logs.writers import write_log
from furuta_drake.diagnosis.pipeline import diagnose
from furuta_drake.diagnosis.selection.detection import INJECTIONS, _ringing_note
from furuta_drake.effects.corrected import fitted_rig
from furuta_drake.effects.surrogate import HISTORY, Model, predict_windows
from furuta_drake.effects.vocabulary import CANDIDATES, Effect, Scales, apply_effects, rig_effects, rig_model
from furuta_drake.errors import ConfigError
from furuta_drake.rig import geared_rig, lund_rig
from furuta_drake.yamlio import dump_yaml_dataclass

ROTOR = 1e-6 * 30.0**2  # [kg m^2] the geared rig's 1e-6 kg m^2 rotor through its 30:1 gear, as the arm feels it
ARM_SIDE = 3.2e-4 + 0.03 * 0.15**2  # [kg m^2] its arm with the pendulum's 30 g at the 0.15 m tip
MU = ROTOR * ARM_SIDE / (ROTOR + ARM_SIDE)  # the pair's reduced inertia


def scales(period: float = 0.01) -> Scales:
    model = rig_model(geared_rig())
    return Scales(
        torque=model.gravity_torque,
        command=0.2,
        arm_inertia=model.arm_inertia_total,
        pendulum_inertia=model.pendulum_inertia_total,
        period=period,
        drive_inertia=model.rotor_share * (1.0 - model.rotor_share) * model.arm_inertia_total,
    )


def ringing(stiffness: float) -> float:
    """[Hz] of a spring ``stiffness`` [N m/rad] between the rotor and the arm side, pendulum locked."""
    return math.sqrt(stiffness / MU) / (2.0 * math.pi)


def test_drive_effects_are_offered_only_with_a_drive():
    geared, direct = rig_model(geared_rig()), rig_model(lund_rig())
    for name in ("drive_backlash", "drive_compliance"):
        assert CANDIDATES[name].offered(geared)
        assert not CANDIDATES[name].offered(direct)
    assert all(c.offered(direct) for name, c in CANDIDATES.items() if not name.startswith("drive_"))


def test_the_scales_hold_the_reduced_inertia_of_rotor_and_arm_side():
    assert scales().drive_inertia == pytest.approx(MU, rel=1e-9)


def test_the_backlash_range_spans_no_play_to_eleven_degrees():
    form = CANDIDATES["drive_backlash"].forms[0]
    low, high = form.bounds(scales())
    assert low == [0.0] and high[0] == pytest.approx(math.radians(11.5), rel=0.01)
    assert all(low[0] < start[0] < high[0] for start in form.starts(scales()))


def test_the_compliance_range_rings_from_half_a_hertz_to_a_gears_tooth_contact():
    form = CANDIDATES["drive_compliance"].forms[0]
    (k_low, c_low), (k_high, c_high) = form.bounds(scales())
    assert ringing(k_low) == pytest.approx(0.5, rel=1e-9)
    assert ringing(k_high) == pytest.approx(200.0, rel=1e-9)
    assert c_low == 0.0
    assert c_high / (2.0 * math.sqrt(k_high * MU)) == pytest.approx(2.0, rel=1e-9)  # up to a damping ratio of 2
    for k, c in form.starts(scales()):
        assert k_low < k < k_high and 0.0 < c < c_high
        assert 0.05 <= c / (2.0 * math.sqrt(k * MU)) <= 1.0  # lightly to critically damped starts


def test_no_backlash_and_the_stiffest_coupling_are_the_rigid_drive():
    s, nominal = scales(), rig_model(geared_rig())
    backlash, compliance = CANDIDATES["drive_backlash"], CANDIDATES["drive_compliance"]
    assert backlash.is_null(Effect("", (0.0,)), s)
    assert not backlash.is_null(Effect("", (0.01,)), s)
    _, (k_high, c_high) = compliance.forms[0].bounds(s)
    assert compliance.is_null(Effect("", (k_high, 0.1 * c_high)), s)
    assert not compliance.is_null(Effect("", (0.01 * k_high, 0.1 * c_high)), s)
    assert compliance.nested_law("stiffness", "upper")
    assert not apply_effects(nominal, {"drive_backlash": Effect("", (0.0,))}).has_drive
    assert apply_effects(nominal, {"drive_backlash": Effect("", (0.01,))}).has_drive


def test_the_stiffest_coupling_predicts_as_the_rigid_drive_to_within_a_fraction_of_a_count():
    """A coupling ringing at 200 Hz, damped at a ratio of 0.7, twists by T / k = u / (mu w^2) under a step of the
    command and settles within a few milliseconds: the angles of a hanging swing 0.5 s long under a step command
    differ from the rigid drive's by far less than an encoder count (2 pi / 2400 rad)."""
    nominal = rig_model(geared_rig())
    k = MU * (2.0 * math.pi * 200.0) ** 2
    stiff = nominal.replace(drive_stiffness=k, drive_damping=2.0 * 0.7 * math.sqrt(k * MU))
    period, n = 0.01, 50
    command = np.concatenate([np.zeros(HISTORY), np.where(np.arange(n) < 20, 0.1, -0.1)])
    x0 = np.array([[math.pi], [0.0], [0.0], [0.0]])
    starts = np.array([HISTORY])
    rigid = predict_windows(nominal, x0, command, starts, n, period, 10)
    coupled = predict_windows(stiff, x0, command, starts, n, period, 10, None, np.zeros((2, 1)))
    assert np.ptp(rigid[:, 1, 0]) > 0.2  # the arm swings
    assert np.abs(coupled - rigid).max() < 0.1 * 2.0 * math.pi / 2400


def test_the_fitted_rig_writes_the_drive_keys_not_effects():
    rig, nominal = geared_rig(), rig_model(geared_rig())
    fitted = fitted_rig(
        rig,
        {"drive_backlash": Effect("", (0.02,)), "drive_compliance": Effect("", (3.0, 0.01))},
        nominal,
    )
    assert (fitted.drive.backlash, fitted.drive.stiffness, fitted.drive.damping) == (0.02, 3.0, 0.01)
    assert (fitted.drive.gear_ratio, fitted.drive.rotor_inertia) == (30.0, 1e-6)
    assert not fitted.effects
    again = Model.from_rig(fitted)
    assert (again.drive_backlash, again.drive_stiffness, again.drive_damping) == (0.02, 3.0, 0.01)


def test_a_drive_effect_under_effects_is_refused_naming_the_drive_keys():
    rig = geared_rig().replace(effects={"drive_backlash": {"backlash": 0.01}})
    with pytest.raises(ConfigError, match=r"effects\.drive_backlash.*drive\.backlash"):
        rig_effects(rig)


def test_a_drive_candidate_on_a_rig_without_a_drive_is_refused(tmp_path):
    rig = lund_rig()
    (tmp_path / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    time = np.arange(400) * rig.sample_period
    zeros = np.zeros_like(time)
    write_log(tmp_path / "log.csv", {"time": time, "theta": zeros, "phi": zeros, "torque": zeros})
    with pytest.raises(ConfigError, match="drive_backlash.*drive: section"):
        diagnose(rig=tmp_path / "rig.yaml", train=[tmp_path / "log.csv"], candidates=["drive_backlash"])


def test_the_compliance_limit_says_where_the_ringing_lies_against_nyquist():
    """k = mu (2 pi f)^2 rings at f: 30 Hz is below a 100 Hz log's Nyquist frequency (50 Hz) and above a 50 Hz
    log's (25 Hz), which then sees the coupling as a lag; sampling the ringing needs twice its frequency."""
    k = MU * (2.0 * math.pi * 30.0) ** 2
    assert "below" in _ringing_note(k, scales(0.01)) and "30 Hz" in _ringing_note(k, scales(0.01))
    above = _ringing_note(k, scales(0.02))
    assert "above" in above and "lag" in above and "60 Hz" in above


def test_the_injected_compliance_rings_where_its_size_says():
    """Size s rings at 200 / (1 + s) Hz with a damping ratio of 0.1; the search range ends at the bound's 0.5 Hz."""
    injection, s = INJECTIONS["drive_compliance"], scales()
    low, high = injection.bracket(s, None)
    assert ringing(injection.value(low, s, None)) == pytest.approx(200.0 / (1.0 + low), rel=1e-9)
    assert ringing(injection.value(high, s, None)) == pytest.approx(0.5, rel=1e-9)
    k, c = injection.effect(3.0, s, None).values
    assert ringing(k) == pytest.approx(50.0, rel=1e-9)
    assert c / (2.0 * math.sqrt(k * MU)) == pytest.approx(0.1, rel=1e-9)
