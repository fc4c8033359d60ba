"""One Furuta world: the diagnosis' Drake replay of a model and the simulate diagram of the config the diagnosis
writes for that model (``fitted_model.yaml``) are the same plant, friction, spring, back-EMF and actuator."""

import dataclasses

import numpy as np
import pytest
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource, ZeroOrderHold
from pydrake.trajectories import PiecewisePolynomial

from furuta_drake.config import ExcitationConfig
from furuta_drake.diagnosis.gap.replay import REPLAY_INTEGRATOR, WindowReplayer
from furuta_drake.diagram import build_furuta_diagram
from furuta_drake.effects.corrected import model_config
from furuta_drake.effects.surrogate import REGULARIZATION_VELOCITY, Model
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.plant import plant_to_paper_permutation
from furuta_drake.rig import qube_servo2_rig
from furuta_drake.world import add_furuta_world

RIG = qube_servo2_rig()  # its DC motor puts the back-EMF damping kt ke / R on the arm
MGL = RIG.gravity_torque
PERIOD = RIG.sample_period


def model_with_every_effect() -> Model:
    """The QUBE with Dahl arm friction, Coulomb and viscous pendulum friction, an arm spring, a first-order lag,
    a dead zone and a torque gain error (all but the delay, which the replay applies as a time shift)."""
    return Model.from_rig(RIG).replace(
        arm_friction=JointFrictionParameters.dahl(0.10 * MGL, 0.15 * MGL, sigma0=0.10 * MGL / 2e-3),
        pendulum_friction=JointFrictionParameters.coulomb(
            0.004 * MGL, viscous=2e-6, regularization_velocity=REGULARIZATION_VELOCITY
        ),
        spring_stiffness=0.25 * MGL,
        spring_equilibrium=0.05,
        lag=0.006,
        deadzone=0.001,
        gain=1.2,
    )


def simulate_world_config(model: Model):
    """The simulate config the diagnosis writes for ``model``, open loop under an excitation torque."""
    config = model_config(RIG, model)
    return dataclasses.replace(
        config,
        duration=0.5,
        excitation=ExcitationConfig(torque_rms=0.3 * MGL),
        controller=dataclasses.replace(config.controller, mode="open_loop"),
    )


def test_the_fitted_config_states_the_models_effects():
    config = simulate_world_config(model_with_every_effect())
    assert config.rig.motor is not None and config.friction.arm.model == "dahl"
    assert config.actuator.lag_time_constant == 0.006 and config.disturbance.arm_spring_stiffness > 0


@pytest.mark.parametrize("seed", range(4))
def test_the_replay_and_the_simulate_diagram_have_the_same_dynamics(seed):
    """At random states, bristle, lag state and command, the time derivatives of every continuous state (plant,
    arm bristle, lag filter) of the simulate diagram equal the replay diagram's."""
    rng = np.random.default_rng(seed)
    model = model_with_every_effect()
    config = simulate_world_config(model)
    x = rng.uniform([-3.0, -2.0, -10.0, -10.0], [3.0, 2.0, 10.0, 10.0])
    z = rng.uniform(-1.0, 1.0) * 0.15 * MGL / model.arm_friction.sigma0
    lag, command = rng.uniform(-0.02, 0.02, 2)

    built = build_furuta_diagram(config)
    simulated = built.diagram.CreateDefaultContext()
    built.plant.SetPositionsAndVelocities(
        built.plant.GetMyMutableContextFromRoot(simulated), plant_to_paper_permutation(built.plant).T @ x
    )
    built.diagram.GetSubsystemByName("friction").GetMyMutableContextFromRoot(
        simulated
    ).get_mutable_continuous_state_vector().SetFromVector([z])
    built.diagram.GetSubsystemByName("actuator_lag").GetMyMutableContextFromRoot(
        simulated
    ).get_mutable_continuous_state_vector().SetFromVector([lag])
    built.diagram.GetSubsystemByName("torque_excitation_hold").GetMyMutableContextFromRoot(simulated).SetDiscreteState(
        [command]
    )

    time = np.arange(100) * PERIOD
    replayer = WindowReplayer(model, RIG, time, np.full(time.size, command))
    replayed = replayer.context
    replayed.SetTime(0.01)
    replayer.diagram.get_input_port().FixValue(replayed, [command])  # the held command, as the replay holds it
    replayed.get_mutable_continuous_state_vector().SetFromVector(np.concatenate([replayer.P.T @ x, [z, lag]]))

    expected = built.diagram.EvalTimeDerivatives(simulated).CopyToVector()
    got = replayer.diagram.EvalTimeDerivatives(replayed).CopyToVector()
    assert expected.size == got.size == 6
    np.testing.assert_allclose(got, expected, rtol=1e-12, atol=1e-12 * np.max(np.abs(expected)))


def test_the_replay_follows_the_simulate_world_on_the_same_torque_sequence():
    """From the same initial state (arm bristle and lag filter included), driven by the same held torque
    sequence and integrated alike, the replay's plant states agree with the world the simulate diagram builds
    from the fitted config, its command held by Drake's discrete ZeroOrderHold (as the simulate diagram holds
    it), to 1e-12 over a quarter second of swinging with stick-slip friction."""
    model = model_with_every_effect()
    config = simulate_world_config(model)
    rng = np.random.default_rng(7)
    time = np.arange(125) * PERIOD
    command = 0.5 * MGL * np.sin(2 * np.pi * 3.0 * time) + 0.1 * MGL * rng.standard_normal(time.size)
    x0, z0 = np.array([2.5, 0.1, -3.0, 1.5]), 0.5 * 0.10 * MGL / model.arm_friction.sigma0

    replayer = WindowReplayer(model, RIG, time, command)
    replayed = replayer.replay(0.0, x0, command[0], time, bristle=z0)
    replayed_final = replayer.P @ replayer.plant.GetPositionsAndVelocities(replayer.plant_context)

    builder = DiagramBuilder()
    world = add_furuta_world(
        builder,
        rig=config.rig,
        friction=config.friction,
        actuator=config.actuator,
        disturbance=config.disturbance,
        control_period=config.control_period,
    )
    source = builder.AddSystem(  # command k from half a period before its sample on: sampled well inside
        TrajectorySource(
            PiecewisePolynomial.ZeroOrderHold(
                np.append(time - PERIOD / 2, time[-1] + PERIOD), np.append(command, command[-1]).reshape(1, -1)
            )
        )
    )
    hold = builder.AddSystem(ZeroOrderHold(PERIOD, 1))
    builder.Connect(source.get_output_port(), hold.get_input_port())
    builder.Connect(hold.get_output_port(), world.arm_torque_input)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    ApplySimulatorConfig(REPLAY_INTEGRATOR, simulator)
    context = simulator.get_mutable_context()
    world.plant.SetPositionsAndVelocities(world.plant.GetMyMutableContextFromRoot(context), world.to_paper.T @ x0)
    world.friction.GetMyMutableContextFromRoot(context).get_mutable_continuous_state_vector().SetFromVector([z0])
    diagram.GetSubsystemByName("actuator_lag").GetMyMutableContextFromRoot(
        context
    ).get_mutable_continuous_state_vector().SetFromVector([command[0]])
    hold.GetMyMutableContextFromRoot(context).SetDiscreteState([command[0]])
    plant_context = world.plant.GetMyContextFromRoot(context)
    simulated = [x0[:2]]
    for t in time[1:]:
        simulator.AdvanceTo(t)
        simulated.append((world.to_paper @ world.plant.GetPositionsAndVelocities(plant_context))[:2])

    assert np.ptp(np.asarray(simulated)[:, 0]) > 0.1  # a real swing, not a rest
    np.testing.assert_allclose(replayed, simulated, rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        replayed_final, world.to_paper @ world.plant.GetPositionsAndVelocities(plant_context), rtol=0, atol=1e-12
    )
