"""The Drake drive and the independent simulator's (``benchmarks/independent/simulator.py``: its own equations of the
rotor and the arm, scipy's ``solve_ivp``) agree on the same command: the geared rig, hanging, under a 50 Hz square-wave
voltage of 0.6 V that swings the pendulum through +-1.2 rad, with an elastic coupling, with backlash (the
simulator's tooth contact set to the package's), and with both, to within half an encoder count over 4 s."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import benchmarks.independent.simulator as sim
from furuta_drake.config import ExcitationConfig, MonitorConfig, SimulationConfig
from furuta_drake.drive import drive_coupling
from furuta_drake.rig import geared_rig
from furuta_drake.simulate import simulate

PERIOD = 0.02  # [s] 50 Hz
STIFFNESS, DAMPING, BACKLASH = 4.0, 0.004, 0.02  # [N m/rad], [N m s/rad], [rad]
RUN = sim.RunSpec("square", 4.0, 1, level=0.05, square_period=1.0)  # +-0.6 V
COUNT = 2 * math.pi / 2400  # [rad]


def tooth_contact(rotor_share: float) -> sim.Backlash:
    """The simulator's backlash with the package's tooth contact (its contact frequency is the rotor's alone against
    a held arm, sqrt(k / J_r), and its damping ratio c / (2 J_r w))."""
    rig = geared_rig()
    arm_side = rig.arm_inertia_total - rig.rotor_inertia_reflected
    coupling = drive_coupling(dataclasses.replace(rig.drive, backlash=BACKLASH), arm_side)
    rotor = rotor_share * sim.geared_like().bodies.arm_inertia
    w = math.sqrt(coupling.stiffness / rotor)
    return sim.Backlash(
        BACKLASH, rotor_share, contact_frequency=w / (2 * math.pi), contact_damping=coupling.damping / (2 * rotor * w)
    )


def drake_run(command: np.ndarray, **drive):
    """The package's simulate of the geared rig at 50 Hz with ``drive``'s changes, open loop from rest hanging under
    the voltage ``command`` as torque-equivalents kt V / R."""
    rig = geared_rig().replace(sample_period=PERIOD)
    rig = rig.replace(drive=dataclasses.replace(rig.drive, **drive))
    base = SimulationConfig.from_rig(rig)
    config = dataclasses.replace(
        base,
        duration=RUN.duration,
        initial_state=[math.pi, 0.0, 0.0, 0.0],
        controller=dataclasses.replace(base.controller, mode="open_loop"),
        excitation=ExcitationConfig(command=(command * rig.motor.torque_constant / rig.motor.resistance).tolist()),
        monitor=MonitorConfig(theta_bound=None),
    )
    return simulate(config)


@pytest.mark.parametrize("drive", ["belt", "backlash", "backlash and belt"])
@pytest.mark.parametrize("encoder", ["arm", "motor"])
def test_the_drake_drive_and_the_independent_one_agree(drive, encoder):
    srig = dataclasses.replace(sim.geared_like(), sample_period=PERIOD)
    share = srig.rotor_share
    belt = sim.Belt(STIFFNESS, DAMPING, share) if "belt" in drive else None
    backlash = sim.Backlash(BACKLASH, share) if "backlash" in drive else None
    if drive == "backlash":
        backlash = tooth_contact(share)
    world = sim.World(srig, backlash=backlash, belt=belt, encoder_on_rotor=encoder == "motor")
    log = sim.simulate(world, RUN)
    changes = {"backlash": BACKLASH if backlash else 0.0, "encoder": encoder}
    if belt:
        changes |= {"stiffness": STIFFNESS, "damping": DAMPING}
    result = drake_run(log.command, **changes)
    assert result.state.shape == log.state.shape
    assert np.ptp(log.state[:, 0]) > 2.0  # the pendulum swings widely
    assert np.abs(result.state[:, :2] - log.state[:, :2]).max() < 0.5 * COUNT
    # The encoders read the same counts (a true angle within a rounding error of a count's edge may round either way).
    assert np.abs(result.measured - log.measured).max() <= COUNT * 1.001
    if encoder == "motor" and backlash:  # the motor's encoder reads the rotor, up to the play away from the arm
        assert np.abs(log.measured[:, 1] - log.state[:, 1]).max() > 0.5 * BACKLASH
