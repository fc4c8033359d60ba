"""The geared benchmark (``benchmarks/diagnosis/geared.py``): its rigs' rotors take the share of the arm side they
are said to, its belts ring at the frequencies they are said to (the simulator's own linearised plant, pendulum
locked), and its scoring holds a play to 15 % with a covering interval and a belt to 10 %, and blames no control
on the drive."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from benchmarks.diagnosis import geared


def _ringing(world) -> float:
    """The highest frequency [Hz] of the simulator's plant linearised at rest hanging (central differences)."""
    plant = geared.sim.Plant(world)
    x0, eps = plant.initial(math.pi), 1e-7
    columns = [
        (np.array(plant.rhs(x0 + eps * e, 0.0)) - np.array(plant.rhs(x0 - eps * e, 0.0))) / (2 * eps)
        for e in np.eye(x0.size)
    ]
    return float(np.max(np.abs(np.linalg.eigvals(np.column_stack(columns)).imag)) / (2 * math.pi))


@pytest.mark.parametrize("share", sorted(geared.SHARES.values()))
def test_the_rotor_takes_its_share_of_the_arm_side_the_arm_as_built(share):
    rig = geared.geared_rig(share, 0.001)
    built = geared.sim.geared_like()
    rotor = rig.rotor_inertia * rig.gear_ratio**2
    assert rotor / rig.bodies.arm_inertia == pytest.approx(share)
    assert rig.bodies.arm_inertia - rotor == pytest.approx(built.bodies.arm_inertia - built.rotor_inertia * 900.0)


@pytest.mark.parametrize("share", sorted(geared.SHARES.values()))
@pytest.mark.parametrize("frequency", [30.0, 60.0])
def test_the_belt_rings_at_its_frequency(share, frequency):
    world, effect = geared.belt(geared.sim.World(geared.geared_rig(share, 0.001)), frequency)
    assert effect.params["stiffness"] == world.belt.stiffness
    bodies = dataclasses.replace(world.rig.bodies, pendulum_com=0.0)  # the pendulum's mass on the arm's tip
    undamped = dataclasses.replace(
        world,
        rig=dataclasses.replace(world.rig, motor=None),
        bodies=bodies,
        belt=dataclasses.replace(world.belt, damping=0.0),
    )
    assert _ringing(undamped) == pytest.approx(frequency, rel=1e-4)


def _report(effects: list[str], params: dict, intervals: dict, verdict: str | None = None) -> dict:
    return {
        "verdict": verdict or (effects[0] if effects else "none"),
        "effects": effects,
        "ranking": [{"effect": "+".join(effects), "params": params, "params_ci": intervals}],
        "gap": {"heldout_reduction": 0.9},
    }


def _answer(*effects) -> dict:
    return {"case": "c", "effects": list(effects), "balance_fell": {}}


PLAY = {"name": "drive_backlash", "params": {"backlash": 0.02}}
BELT = {"name": "drive_compliance", "params": {"stiffness": 10.0, "damping": 0.01}}
DELAY = {"name": "input_delay", "params": {"delay": 0.005}}


@pytest.mark.parametrize(
    ("fitted", "interval", "right"),
    [(0.0199, [0.0197, 0.0201], True), (0.0199, [0.0198, 0.01995], False), (0.008, [0.007, 0.021], False)],
)
def test_a_play_is_right_within_15_percent_with_a_covering_interval(fitted, interval, right):
    report = _report(["drive_backlash"], {"backlash": fitted}, {"backlash": interval})
    assert geared.drive_row(_answer(PLAY), report)["right"] is right


@pytest.mark.parametrize(("stiffness", "right"), [(10.9, True), (11.2, False)])
def test_a_belt_beside_a_play_is_right_within_10_percent(stiffness, right):
    params = {"drive_backlash.backlash": 0.02, "drive_compliance.stiffness": stiffness}
    intervals = {"drive_backlash.backlash": [0.019, 0.021]}
    report = _report(["drive_backlash", "drive_compliance"], params, intervals)
    assert geared.drive_row(_answer(PLAY, BELT), report)["right"] is right
    alone = _report(["drive_backlash"], {"backlash": 0.02}, {"backlash": [0.019, 0.021]})
    assert geared.drive_row(_answer(PLAY, BELT), alone)["right"] is False  # the belt not named


def test_a_control_blamed_on_the_drive_and_a_null_not_none_are_wrong():
    blamed = geared.drive_row(_answer(DELAY), _report(["input_delay", "drive_backlash"], {}, {}))
    assert blamed["blamed_on_drive"] == ["drive_backlash"] and not blamed["right"]
    assert geared.drive_row(_answer(DELAY), _report(["input_delay"], {}, {}))["right"]
    assert not geared.drive_row(_answer(), _report(["drive_compliance"], {}, {}))["right"]
    assert geared.drive_row(_answer(), _report([], {}, {}))["right"]


def test_a_belt_stiffer_than_the_reports_limit_is_out_of_sight_and_none_is_right():
    """The report's own detection limit says a belt stiffer than 37.6 N m/rad could hide in these logs: a 60 N m/rad
    belt read as ``none`` is right, a 30 N m/rad one is not."""
    limits = [{"effect": "drive_compliance", "value": 37.6}, {"effect": "drive_backlash", "value": 4e-4}]
    report = {**_report([], {}, {}), "detection_limits": limits}
    stiff = {"name": "drive_compliance", "params": {"stiffness": 60.0, "damping": 0.03}}
    row = geared.drive_row(_answer(stiff), report)
    assert row["hidden"] == ["drive_compliance"] and row["right"]
    assert not geared.drive_row(_answer(BELT | {"params": {"stiffness": 30.0}}), report)["right"]
    assert not geared.drive_row(_answer(PLAY), report)["right"]  # a 20 mrad play is well above its 0.4 mrad limit
