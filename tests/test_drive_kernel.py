"""The diagnosis' surrogate with a drive of its own state (:mod:`furuta_drake.effects.drive_kernel`) against the Drake
world with the same drive: the geared rig's hanging pendulum swung for a second by a step command that reverses the
arm twice, each of the diagnosis' windows along it (its horizon for this rig, about 0.17 s) started from Drake's
state (the rotor's twist included) predicts the angles Drake's run reads to within a tenth of an encoder count
(2 pi / 2400 rad): far below the rounding the diagnosis' floor holds (a count / sqrt(12)), so its fits see the
drive's physics, not the integrators' differences. (Over longer spans the two drift apart by a fraction of a count
more: an engagement of the teeth is a near-discontinuity whose timing both integrators resolve only to their step.)"""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from furuta_drake.diagnosis.gap.metric import horizon_seconds
from furuta_drake.effects.surrogate import HISTORY, predict_windows
from furuta_drake.effects.vocabulary import rig_model
from furuta_drake.rig import geared_rig
from furuta_drake.world import add_furuta_world

PERIOD = 0.005  # [s] 200 Hz
COUNT = 2.0 * math.pi / 2400  # [rad]
SAMPLES = 200  # 1 s
LEVEL = 1.0 * 0.3 / 2.2  # [N m] 1 V through the geared rig's motor, torque-equivalent


def drake_run(rig, command: np.ndarray, state: np.ndarray, twist: np.ndarray):
    """(the true states (n, 4), the rotor's states [psi, psi'] (n, 2)) of ``rig``'s world every PERIOD from
    ``state`` with the rotor at ``twist`` [delta, delta'] from the arm, under ``command`` held over each period,
    integrated by RK5 at accuracy 1e-10."""
    builder = DiagramBuilder()
    world = add_furuta_world(builder, rig=rig, control_period=PERIOD)
    times = np.arange(command.size + 1) * PERIOD
    held = PiecewisePolynomial.ZeroOrderHold(times, np.append(command, command[-1])[None, :])
    source = builder.AddSystem(TrajectorySource(held))
    builder.Connect(source.get_output_port(0), world.arm_torque_input)
    loggers = [
        LogVectorOutput(port, builder, publish_period=PERIOD)
        for port in (world.true_state, world.drive.get_output_port())
    ]
    simulator = Simulator(builder.Build())
    ApplySimulatorConfig(
        SimulatorConfig(integration_scheme="runge_kutta5", accuracy=1e-10, max_step_size=1e-4), simulator
    )
    context = simulator.get_mutable_context()
    world.set_state(context, state)
    rotor = world.drive.GetMyMutableContextFromRoot(context).get_mutable_continuous_state_vector()
    rotor.SetFromVector([state[1] + twist[0], state[3] + twist[1]])
    simulator.AdvanceTo((command.size - 1) * PERIOD)
    arm, rotor_log = (logger.FindLog(context) for logger in loggers)
    return arm.data().T, rotor_log.data().T


DRIVES = {
    "backlash": dict(backlash=0.03),  # a gear's play, its teeth touching through the tooth contact
    "belt": dict(stiffness=1.2, damping=0.005),  # a belt ringing at 8 Hz against the arm, damping ratio 0.1
    "backlash and belt": dict(backlash=0.02, stiffness=1.2, damping=0.005),
}


@pytest.mark.parametrize("encoder", ["arm", "motor"])
@pytest.mark.parametrize("drive", list(DRIVES))
def test_the_surrogate_with_a_drive_predicts_the_drake_world(drive, encoder):
    rig = geared_rig().replace(sample_period=PERIOD)
    rig = rig.replace(drive=dataclasses.replace(rig.drive, encoder=encoder, **DRIVES[drive]))
    command = LEVEL * np.where((np.arange(SAMPLES) // 70) % 2 == 0, 1.0, -1.0)  # reverses at 0.35 s and 0.7 s
    state = np.array([math.pi, 0.0, 0.0, 0.0])
    arm, rotor = drake_run(rig, command, state, np.zeros(2))
    # The angles the encoders read: the rotor's (over the gear ratio) for an encoder on the motor.
    read = np.column_stack([arm[:, 0], rotor[:, 0] if encoder == "motor" else arm[:, 1]])
    twist = (rotor - arm[:, [1, 3]]).T
    assert np.ptp(arm[:, 1]) > 0.5  # the arm swings and turns back
    assert np.abs(twist[0]).max() > 0.5 * DRIVES[drive].get("backlash", 0.01)  # the drive twists
    horizon = round(horizon_seconds(rig) / PERIOD)
    starts = np.arange(0, SAMPLES - horizon, horizon // 2)
    model = rig_model(rig)
    assert model.has_drive
    predicted = predict_windows(
        model,
        arm[starts].T,
        np.concatenate([np.zeros(HISTORY), command]),
        HISTORY + starts,
        horizon,
        PERIOD,
        5,
        None,
        twist[:, starts],
    )
    for w, start in enumerate(starts):
        assert np.abs(predicted[:, :, w] - read[start : start + horizon]).max() < 0.1 * COUNT, start
