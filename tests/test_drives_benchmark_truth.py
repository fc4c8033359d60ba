"""The drives benchmark's truth in the independent simulator (``benchmarks/diagnosis/drives.py --simulator
independent``) is stated in the diagnosis' units: the rig file the diagnosis reads is the rig the simulator
integrates, the belt of a compliance case rings at the frequency the case names, sqrt(k / mu) / 2 pi with mu the
rotor's and the arm side's reduced inertia, and the play, the friction level and the delay are the truth's."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from benchmarks.diagnosis.drives import CASES, DELAY, FRICTION, independent_world, lab_rig, sim
from furuta_drake.rig import geared_rig
from furuta_drake.rig_file import load_rig
from furuta_drake.yamlio import dump_yaml_dataclass

PERIOD = 0.02  # [s] 50 Hz


def test_the_rig_file_states_the_rig_the_independent_simulator_integrates(tmp_path):
    ours, theirs = tmp_path / "ours.yaml", tmp_path / "theirs.yaml"
    ours.write_text(dump_yaml_dataclass(lab_rig(PERIOD)))
    sim.write_rig_file(dataclasses.replace(sim.geared_like(), sample_period=PERIOD), theirs)
    ours, theirs = load_rig(ours), load_rig(theirs)
    assert theirs.torque_limit == pytest.approx(ours.torque_limit, rel=1e-12)  # 12 V kt / R, rounded apart
    assert theirs.replace(torque_limit=ours.torque_limit) == ours


def _ringing(world: sim.World) -> float:
    """The highest frequency [Hz] of the simulator's linearised plant at rest hanging (finite differences)."""
    plant = sim.Plant(world)
    x0, eps = plant.initial(math.pi), 1e-7
    jacobian = np.column_stack(
        [
            (np.array(plant.rhs(x0 + eps * e, 0.0)) - np.array(plant.rhs(x0 - eps * e, 0.0))) / (2 * eps)
            for e in np.eye(x0.size)
        ]
    )
    return float(np.max(np.abs(np.linalg.eigvals(jacobian).imag)) / (2 * math.pi))


@pytest.mark.parametrize(("name", "frequency"), [("compliance_soft", 8.0), ("compliance_stiff", 30.0)])
def test_the_belt_rings_at_the_cases_frequency(name, frequency):
    case = CASES[name]
    world = independent_world(case, PERIOD)
    plant = sim.Plant(world)
    assert plant.rotor_inertia == pytest.approx(geared_rig().rotor_inertia_reflected)
    assert (plant.contact_stiffness, plant.contact_damping) == (case.truth["stiffness"], case.drive["damping"])
    # The arm alone against the rotor (the pendulum's centre of mass on its joint: no coupling, no gravity), no
    # motor (no back-EMF), no damper: the pair's ringing, pendulum locked, is the case's.
    bodies = dataclasses.replace(world.rig.bodies, pendulum_com=0.0)
    undamped = dataclasses.replace(
        world,
        rig=dataclasses.replace(world.rig, motor=None),
        bodies=bodies,
        belt=dataclasses.replace(world.belt, damping=0.0),
    )
    assert bodies.a == pytest.approx(geared_rig().arm_inertia_total)
    assert _ringing(undamped) == pytest.approx(frequency, rel=1e-4)


def test_the_play_friction_and_delay_are_the_truths():
    for name in ("backlash_small", "backlash_large"):
        world = independent_world(CASES[name], PERIOD)
        assert sim.Plant(world).gap == CASES[name].truth["backlash"]
        assert world.backlash.rotor_share == pytest.approx(
            geared_rig().rotor_inertia_reflected / geared_rig().rigid_arm_inertia
        )
    world = independent_world(CASES["arm_friction"], PERIOD)
    assert world.arm_friction.coulomb_pos == world.arm_friction.coulomb_neg == pytest.approx(FRICTION)
    assert world.arm_friction.breakaway == pytest.approx(FRICTION)
    for period in (0.005, 0.02):
        assert independent_world(CASES["delay"], period).delay_samples * period == pytest.approx(DELAY)
    assert independent_world(CASES["none"], PERIOD) == sim.World(
        dataclasses.replace(sim.geared_like(), sample_period=PERIOD)
    )
