"""The actuator chain, the arm disturbance and the DC motor against their formulas."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import (
    ConstantVectorSource,
    LogVectorOutput,
    PassThrough,
    TrajectorySource,
    ZeroOrderHold,
)
from pydrake.trajectories import PiecewisePolynomial

from furuta_drake.actuator import (
    ActuatorParameters,
    DisturbanceParameters,
    add_actuator,
    add_arm_disturbance,
    add_dc_motor,
)
from furuta_drake.errors import ConfigError
from furuta_drake.rig import MotorParameters

CONTROL_PERIOD = 1e-3  # [s]
RESOLUTION = CONTROL_PERIOD / 10  # the delay resolution the diagram uses [s]


def static_map(params):
    """The actuator chain as a function u_cmd -> u (valid for chains without delay or lag)."""
    builder = DiagramBuilder()
    input_port, output_port = add_actuator(builder, params, RESOLUTION)
    builder.ExportInput(input_port)
    builder.ExportOutput(output_port)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()

    def apply(u):
        diagram.get_input_port(0).FixValue(context, [u])
        return diagram.get_output_port(0).Eval(context)[0]

    return apply, diagram


def test_nominal_chain_is_a_single_pass_through():
    apply, diagram = static_map(ActuatorParameters())
    assert len(diagram.GetSystems()) == 1
    assert isinstance(diagram.GetSystems()[0], PassThrough)
    assert apply(0.137) == 0.137


@settings(max_examples=25, deadline=None)
@given(u=st.floats(-0.5, 0.5))
def test_dead_zone_then_gain_then_saturation(u):
    deadzone, gain, limit = 0.05, 2.0, 0.1
    apply, _ = static_map(ActuatorParameters(gain=gain, deadzone=deadzone, saturation=limit))
    shrunk = math.copysign(max(abs(u) - deadzone, 0.0), u)
    assert apply(u) == pytest.approx(min(max(gain * shrunk, -limit), limit), abs=1e-15)


def test_static_maps_at_chosen_points():
    dead, _ = static_map(ActuatorParameters(deadzone=0.015))
    assert [dead(u) for u in (-0.02, -0.01, 0.0, 0.01, 0.02)] == pytest.approx([-0.005, 0, 0, 0, 0.005])
    gain, _ = static_map(ActuatorParameters(gain=0.8))
    assert gain(-0.1) == pytest.approx(-0.08)
    saturated, _ = static_map(ActuatorParameters(saturation=0.15))
    assert [saturated(u) for u in (-0.3, 0.1, 0.3)] == pytest.approx([-0.15, 0.1, 0.15])
    # Order: the dead zone acts on the command, the gain before the limit: 2 (0.08 - 0.05) = 0.06, not
    # 2 * 0.08 - 0.05 = 0.11, and 2 * 0.08 = 0.16 is limited to 0.1, not 2 * 0.1 = 0.2.
    chain, _ = static_map(ActuatorParameters(gain=2.0, deadzone=0.05, saturation=0.1))
    assert chain(0.08) == pytest.approx(0.06)
    no_deadzone, _ = static_map(ActuatorParameters(gain=2.0, saturation=0.1))
    assert no_deadzone(0.08) == pytest.approx(0.1)


def run_chain(params, command, duration, log_period, accuracy=1e-4):
    """Feed ``command`` (an output-port factory on the builder) through the chain; return log times and values."""
    builder = DiagramBuilder()
    input_port, output_port = add_actuator(builder, params, RESOLUTION)
    builder.Connect(command(builder), input_port)
    logger = LogVectorOutput(output_port, builder, publish_period=log_period)
    simulator = Simulator(builder.Build())
    simulator.get_mutable_integrator().set_target_accuracy(accuracy)
    simulator.AdvanceTo(duration)
    log = logger.FindLog(simulator.get_context())
    return log.sample_times(), log.data()[0]


def held_staircase(builder):
    """A new command k at every t_k = k * CONTROL_PERIOD, held like the controller's output."""
    times = np.arange(0.0, 0.3, CONTROL_PERIOD)
    source = builder.AddSystem(
        TrajectorySource(PiecewisePolynomial.ZeroOrderHold(times, np.arange(len(times), dtype=float)[None, :]))
    )
    hold = builder.AddSystem(ZeroOrderHold(CONTROL_PERIOD, 1))
    builder.Connect(source.get_output_port(), hold.get_input_port())
    return hold.get_output_port()


@pytest.mark.parametrize("delay, expected", [(1e-4, 1e-4), (3e-4, 3e-4), (2.5e-3, 2.5e-3), (2.34e-4, 2e-4)])
def test_delay_shifts_every_command_change_by_the_delay(delay, expected):
    """Each of 250 command changes reaches the output exactly ``delay`` later (rounded to the resolution),
    including the instants where k * 1e-3 and 10 k * 1e-4 differ in their last bit."""
    log_period = RESOLUTION / 4
    times, values = run_chain(ActuatorParameters(delay=delay), held_staircase, 0.29, log_period)
    # A logger at t shows the value updated at t - log_period at the latest (before the update at t itself).
    change_times = np.array([times[np.argmax(values == k)] - log_period for k in range(1, 260)])
    np.testing.assert_allclose(change_times - CONTROL_PERIOD * np.arange(1, 260), expected, atol=1e-9)


def test_lag_reaches_63_percent_of_a_step_at_the_time_constant():
    tau = 0.02

    def unit_step(builder):
        return builder.AddSystem(ConstantVectorSource([1.0])).get_output_port()

    times, values = run_chain(ActuatorParameters(lag_time_constant=tau), unit_step, 3 * tau, tau / 2, accuracy=1e-8)
    np.testing.assert_allclose(values[[2, 4, 6]], [1 - math.exp(-1), 1 - math.exp(-2), 1 - math.exp(-3)], rtol=1e-5)
    assert values[0] == 0.0


def test_dead_zone_acts_on_the_lagged_command():
    """Delay -> lag -> dead zone: a unit step delayed by 2 ms, lagged by tau, passes a 0.5 dead zone only
    after tau ln 2 more."""
    tau, delay = 0.02, 2e-3

    def held_step(builder):
        source = builder.AddSystem(
            TrajectorySource(PiecewisePolynomial.ZeroOrderHold([0.0, 0.005, 1.0], [[0.0, 1.0, 1.0]]))
        )
        hold = builder.AddSystem(ZeroOrderHold(CONTROL_PERIOD, 1))
        builder.Connect(source.get_output_port(), hold.get_input_port())
        return hold.get_output_port()

    params = ActuatorParameters(delay=delay, lag_time_constant=tau, deadzone=0.5)
    times, values = run_chain(params, held_step, 0.05, 1e-4, accuracy=1e-8)
    opening = 0.005 + delay + tau * math.log(2)
    assert np.all(values[times < opening - 1e-4] == 0)
    after = times > opening + 1e-3
    np.testing.assert_allclose(values[after], 0.5 - np.exp(-(times[after] - 0.005 - delay) / tau), atol=1e-5)


def disturbance_torque(params, phi):
    builder = DiagramBuilder()
    state = builder.AddSystem(ConstantVectorSource([0.02, phi, 1.0, -3.0]))
    port = add_arm_disturbance(builder, params, state.get_output_port())
    builder.ExportOutput(port)
    diagram = builder.Build()
    return diagram.get_output_port(0).Eval(diagram.CreateDefaultContext())[0]


def test_arm_spring_restores_towards_its_equilibrium():
    spring = DisturbanceParameters(arm_spring_stiffness=0.05, arm_spring_equilibrium=0.2)
    assert disturbance_torque(spring, 0.5) == pytest.approx(-0.015)
    assert disturbance_torque(spring, 0.0) == pytest.approx(0.01)
    assert disturbance_torque(spring, 0.2) == pytest.approx(0.0)


def test_cogging_and_spring_add_up():
    cogging = DisturbanceParameters(cogging_amplitude=0.003, cogging_periods=6, cogging_phase=0.4)
    assert disturbance_torque(cogging, 0.3) == pytest.approx(0.003 * math.sin(6 * 0.3 + 0.4))
    # Period 2 pi / N in phi.
    assert disturbance_torque(cogging, 0.3 + 2 * math.pi / 6) == pytest.approx(disturbance_torque(cogging, 0.3))
    both = DisturbanceParameters(arm_spring_stiffness=0.05, cogging_amplitude=0.003, cogging_periods=6)
    assert disturbance_torque(both, 0.3) == pytest.approx(-0.015 + 0.003 * math.sin(1.8))


def test_no_disturbance_adds_no_system():
    builder = DiagramBuilder()
    state = builder.AddSystem(ConstantVectorSource(np.zeros(4)))
    assert add_arm_disturbance(builder, DisturbanceParameters(), state.get_output_port()) is None
    assert len(builder.GetSystems()) == 1


def motor_torque(motor, voltage, phi_dot):
    builder = DiagramBuilder()
    volts = builder.AddSystem(ConstantVectorSource([voltage]))
    state = builder.AddSystem(ConstantVectorSource([0.1, -0.4, 2.0, phi_dot]))
    builder.ExportOutput(add_dc_motor(builder, motor, volts.get_output_port(), state.get_output_port()))
    diagram = builder.Build()
    return diagram.get_output_port(0).Eval(diagram.CreateDefaultContext())[0]


def test_dc_motor_stall_torque_and_no_load_speed():
    motor = MotorParameters(resistance=8.4, torque_constant=0.042, backemf_constant=0.042)
    assert motor_torque(motor, 5.0, 0.0) == pytest.approx(0.042 * 5.0 / 8.4)  # stall: kt V / R = 0.025 N m
    assert motor_torque(motor, 5.0, 5.0 / 0.042) == pytest.approx(0.0, abs=1e-15)  # no-load speed V / ke
    assert motor_torque(motor, 5.0, 2.5 / 0.042) == pytest.approx(0.0125)  # linear torque-speed line
    assert motor_torque(motor, 0.0, 10.0) == pytest.approx(-(0.042**2) / 8.4 * 10.0)  # back-EMF braking


@pytest.mark.parametrize(
    "params, field",
    [
        (ActuatorParameters(gain=0.0), "actuator.gain"),
        (ActuatorParameters(gain=math.nan), "actuator.gain"),
        (ActuatorParameters(deadzone=-0.01), "actuator.deadzone"),
        (ActuatorParameters(delay=-1e-3), "actuator.delay"),
        (ActuatorParameters(lag_time_constant=math.inf), "actuator.lag_time_constant"),
        (ActuatorParameters(saturation=0.0), "actuator.saturation"),
    ],
)
def test_invalid_actuator_parameters_are_rejected_with_the_field_named(params, field):
    with pytest.raises(ConfigError, match=field):
        add_actuator(DiagramBuilder(), params, RESOLUTION)


@pytest.mark.parametrize(
    "changes, field",
    [
        ({"arm_spring_stiffness": -0.1}, "arm_spring_stiffness"),
        ({"arm_spring_equilibrium": math.nan}, "arm_spring_equilibrium"),
        ({"cogging_amplitude": -1e-3}, "cogging_amplitude"),
        ({"cogging_periods": 1.5}, "cogging_periods"),
        ({"cogging_amplitude": 1e-3}, "cogging_periods"),
        ({"cogging_phase": math.inf}, "cogging_phase"),
    ],
)
def test_invalid_disturbance_parameters_are_rejected_with_the_field_named(changes, field):
    with pytest.raises(ConfigError, match=f"disturbance.{field}"):
        DisturbanceParameters(**changes).validate()
