"""Swing-up and catch: the energy-pumping law against the plant's own dynamics, the hand-over with hysteresis and
wrapping, the closed loop from hanging on the Lund rig within its torque limit, and the study's rows."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.config import ControllerConfig, SimulationConfig, dump_config, swingup_config
from furuta_drake.controllers.lqr import LqrParameters, design_lqr
from furuta_drake.controllers.swingup import (
    BALANCE,
    SWING,
    EnergySwingUpController,
    SwingUpParameters,
    catch_time,
    pendulum_energy,
    wrap_angle,
)
from furuta_drake.errors import ConfigError
from furuta_drake.plant import joint_indices, make_furuta_plant
from furuta_drake.rig import lund_rig, qube_servo2_rig
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import loads_yaml_dataclass

RIG = lund_rig()
PLANT = make_furuta_plant(RIG)
K = design_lqr(PLANT, LqrParameters(), period=1e-3)


def controller_step(x, params=None, mode=SWING, rig=RIG, limit=0.2):
    """One update of the controller at state estimate x (paper order): (torque, mode, energy)."""
    params = SwingUpParameters() if params is None else params
    controller = EnergySwingUpController(rig, K, params, period=1e-3, torque_limit=limit)
    context = controller.CreateDefaultContext()
    controller.GetInputPort("state_estimate").FixValue(context, np.asarray(x, dtype=float))
    context.SetDiscreteState(1, [mode])
    update = controller.EvalUniquePeriodicDiscreteUpdate(context)
    return update.get_vector(0).GetAtIndex(0), update.get_vector(1).GetAtIndex(0), update.get_vector(2).GetAtIndex(0)


def pendulum_acceleration(x, u):
    """theta_ddot of the MultibodyPlant at paper-order state x under arm torque u (no friction)."""
    context = PLANT.CreateDefaultContext()
    theta_index, phi_index = joint_indices(PLANT)
    nq = PLANT.num_positions()
    state = np.zeros(PLANT.num_multibody_states())
    state[theta_index], state[phi_index], state[nq + theta_index], state[nq + phi_index] = x
    PLANT.SetPositionsAndVelocities(context, state)
    PLANT.get_actuation_input_port().FixValue(context, [u])
    PLANT.get_applied_generalized_force_input_port().FixValue(context, np.zeros(PLANT.num_velocities()))
    return PLANT.EvalTimeDerivatives(context).CopyToVector()[nq + theta_index]


@settings(max_examples=25, deadline=None)
@given(theta=st.floats(2.0, 4.2), theta_dot=st.floats(-3.0, 3.0).filter(lambda v: abs(v) > 0.05))
def test_pumping_raises_a_low_energy(theta, theta_dot):
    """Below E_ref the command's own effect on the pendulum, J_p theta_dot * (theta_ddot(u) - theta_ddot(0)) from
    MultibodyPlant, is a positive energy rate; with k large it is saturated at the limit (arm at rest at 0)."""
    x = [theta, 0.0, theta_dot, 0.0]
    assert pendulum_energy(RIG, theta, theta_dot) < 0.1 * RIG.gravity_torque  # below E_ref on this range
    u, mode, _ = controller_step(x, SwingUpParameters(energy_gain=100.0))
    assert mode == SWING
    assert abs(u) == pytest.approx(0.2)
    rate = RIG.pendulum_inertia_total * theta_dot * (pendulum_acceleration(x, u) - pendulum_acceleration(x, 0.0))
    assert rate > 0


@settings(max_examples=25, deadline=None)
@given(theta=st.floats(2.5, 3.8), theta_dot=st.floats(11.0, 13.0), direction=st.sampled_from([-1.0, 1.0]))
def test_pumping_removes_an_excess_energy(theta, theta_dot, direction):
    """Above E_ref (a fast swing through the bottom) the command takes energy out of the pendulum."""
    x = [theta, 0.0, direction * theta_dot, 0.0]
    assert pendulum_energy(RIG, theta, theta_dot) > 0.1 * RIG.gravity_torque
    u, _, _ = controller_step(x)
    rate = RIG.pendulum_inertia_total * x[2] * (pendulum_acceleration(x, u) - pendulum_acceleration(x, 0.0))
    assert rate < 0


def test_energy_is_zero_upright_and_minus_two_mgl_hanging():
    assert pendulum_energy(RIG, 0.0, 0.0) == 0.0
    assert pendulum_energy(RIG, math.pi, 0.0) == pytest.approx(-2 * RIG.pendulum_mass * RIG.gravity * RIG.pendulum_com)
    _, _, energy = controller_step([math.pi, 0.0, 2.0, 0.0])
    assert energy == pytest.approx(0.5 * RIG.pendulum_inertia_total * 4.0 - 2 * RIG.gravity_torque)


def test_catch_uses_the_lqr_on_the_wrapped_angle():
    """Near the upright after whole turns the command is the LQR's u = -K x with theta wrapped."""
    x = np.array([0.05, 0.0, 0.1, 0.0])
    for turns in (-1, 0, 2):
        u, mode, _ = controller_step(x + [2 * math.pi * turns, 0, 0, 0])
        assert mode == BALANCE
        assert u == pytest.approx(float((-K @ x)[0]))


def test_hand_over_has_hysteresis():
    between = [0.5, 0.0, 0.0, 0.0]  # catch_angle 0.3 < 0.5 < release_angle 0.8
    assert controller_step(between, mode=SWING)[1] == SWING
    assert controller_step(between, mode=BALANCE)[1] == BALANCE
    assert controller_step([0.9, 0.0, 0.0, 0.0], mode=BALANCE)[1] == SWING
    fast = [0.1, 0.0, 5.0, 0.0]  # in the angle window but with E = 1.2 m g l: no catch
    assert controller_step(fast, mode=SWING)[1] == SWING


def test_validate_names_the_field():
    with pytest.raises(ConfigError, match="swingup.energy_gain"):
        EnergySwingUpController(RIG, K, SwingUpParameters(energy_gain=-1.0), period=1e-3, torque_limit=0.2)
    with pytest.raises(ConfigError, match="catch_angle < release_angle"):
        SwingUpParameters(catch_angle=0.9, release_angle=0.8).validate()
    assert wrap_angle(3 * math.pi / 2) == pytest.approx(-math.pi / 2)


def test_lund_rig_is_swung_up_caught_and_balanced_within_the_torque_limit():
    result = simulate(swingup_config("lund", duration=4.0))
    assert catch_time(result) < 3.0
    last = result.time > result.time[-1] - 1.0
    assert np.max(np.abs(wrap_angle(result.state[last, 0]))) < 0.1
    assert np.max(np.abs(result.torque)) <= RIG.torque_limit + 1e-12
    assert result.state[0, 0] == pytest.approx(math.pi)


def test_qube_swing_up_respects_its_smaller_limit():
    qube = qube_servo2_rig()
    result = simulate(swingup_config("qube_servo2", duration=2.0))
    assert np.max(np.abs(result.torque)) <= qube.torque_limit + 1e-12
    assert np.max(np.abs(result.torque)) == pytest.approx(qube.torque_limit)  # the pumping saturates


def test_a_swing_up_config_round_trips_and_reruns_identically():
    """The swing-up is a simulate config (``controller.mode: swingup``): its YAML gives the same run."""
    config = swingup_config("lund", duration=1.0)
    again = loads_yaml_dataclass(dump_config(config), SimulationConfig)
    assert again == config
    np.testing.assert_array_equal(simulate(config).state, simulate(again).state)


def test_the_kinematic_observer_is_the_swing_ups_alone():
    with pytest.raises(ConfigError, match="velocity_source 'kinematic_hg' is the swing-up's observer"):
        ControllerConfig(velocity_source="kinematic_hg").validate()


def test_study_small_returns_rows():
    from furuta_drake.paper.studies.swingup_study import study

    outcome = study(small=True)
    metrics = [row["metric"] for row in outcome.rows]
    assert metrics[0] == "time to catch from hanging"
    assert outcome.rows[0]["extension"] is not None
    assert all(set(row) == {"metric", "paper", "extension", "unit", "note"} for row in outcome.rows)
    assert set(outcome.figures) == {"swingup_states", "swingup_energy"}
    assert outcome.logs["swingup"].signals["swingup_mode"][-1, 0] == BALANCE
