"""Quanser's swing-up and balance controller (controllers/quanser_swingup.py) on hand-computed states, against the
published law in its own variables, as a Drake block, and the filtered derivative that feeds it."""

import math

import numpy as np
import pytest

from furuta_drake.controllers.quanser_swingup import (
    BALANCE,
    SWING,
    QuanserSwingUpController,
    QuanserSwingUpParameters,
    quanser_command,
)
from furuta_drake.errors import ConfigError
from furuta_drake.observers.filtered_derivative import (
    FilteredDerivative,
    FilteredDerivativeParameters,
    filtered_derivative,
)

P = QuanserSwingUpParameters()
VOLTS_PER_ACCELERATION = 8.4 / 0.042 * 0.095 * 0.085  # R / k_m * m_r * L_r = 1.615 V s^2/m


def command(state, params=P):
    voltage, mode, energy = quanser_command(params, np.asarray(state, dtype=float))
    return float(voltage), float(mode), float(energy)


def test_first_kick_from_rest_hanging():
    """At rest hanging E = 0: a = 50 (0 - 0.025) s - 0.4 phi, s the rest direction; V = 1.615 a."""
    voltage, mode, energy = command([math.pi, 0.1, 0.0, 0.0])
    assert mode == SWING and energy == pytest.approx(0.0, abs=1e-15)
    assert voltage == pytest.approx(VOLTS_PER_ACCELERATION * (-1.25 - 0.04)) == pytest.approx(-2.08335, abs=1e-5)
    other, _, _ = command([math.pi, 0.1, 0.0, 0.0], QuanserSwingUpParameters(rest_direction=-1))
    assert other == pytest.approx(VOLTS_PER_ACCELERATION * (1.25 - 0.04))


def test_swing_pumps_energy_with_the_sign_of_theta_dot_cos_theta():
    """theta = 2 rad, theta_dot = 4 rad/s: E = 1/2 (m L^2 / 12) theta_dot^2 + 1/2 m g L (1 + cos theta)."""
    theta, phi, theta_dot = 2.0, -0.5, 4.0
    m, length, g = 0.024, 0.129, 9.81
    energy = 0.5 * (m * length**2 / 12) * theta_dot**2 + 0.5 * m * g * length * (1 + math.cos(theta))
    acceleration = 50.0 * (energy - 0.025) * (-1.0) - 0.4 * phi  # theta_dot cos(theta) < 0
    voltage, mode, got_energy = command([theta, phi, theta_dot, 1.0])
    assert mode == SWING and got_energy == pytest.approx(energy, rel=1e-12)
    assert voltage == pytest.approx(VOLTS_PER_ACCELERATION * acceleration) == pytest.approx(1.60429, abs=1e-4)


def test_balance_law_and_clips():
    """Within 20 deg of the upright: V = 35 theta_w + 2 phi + 3 theta_dot + 1.5 phi_dot, clipped at 4 V; the
    acceleration of the swing law is clipped at 5 m/s^2 first."""
    assert command([0.1, 0.2, 0.5, -1.0]) == pytest.approx((3.9, BALANCE, command([0.1, 0.2, 0.5, -1.0])[2]))
    assert command([2 * math.pi + 0.1, 0.2, 0.5, -1.0])[0] == pytest.approx(3.9)  # one turn later, same law
    assert command([-0.3, 0.0, 0.0, 0.0])[0] == -4.0
    assert command([math.radians(21), 0.0, 0.0, 0.0])[1] == SWING
    small_limit = QuanserSwingUpParameters(voltage_limit=100.0)
    assert command([math.pi, -20.0, 0.0, 0.0], small_limit)[0] == pytest.approx(VOLTS_PER_ACCELERATION * 5.0)


def test_balance_voltage_opposes_a_fall():
    """Near the upright a positive arm torque gives a negative pendulum acceleration (beta4 < 0): a pendulum
    falling towards +theta gets a positive voltage."""
    assert command([0.05, 0.0, 0.2, 0.0])[0] > 0 > command([-0.05, 0.0, -0.2, 0.0])[0]


def published_law(theta, phi, theta_dot, phi_dot):
    """The law as SimuRLacra writes it, in its own variables: alpha = pi - theta (0 hanging, counted the other way),
    the arm angle th = phi."""
    th, thd, al, ald = phi, phi_dot, (math.pi - theta) % (2 * math.pi), -theta_dot
    if abs(1 + math.cos(al)) < 1 + math.cos(math.pi - math.radians(20.0)):
        return float(
            np.clip(
                np.dot([-2.0, 35.0, -1.5, 3.0], np.array([0.0, math.pi, 0.0, 0.0]) - np.array([th, al, thd, ald])),
                -4,
                4,
            )
        )
    m, length, g = 0.024, 0.129, 9.81
    energy = 0.5 * m * length**2 / 12 * ald**2 + 0.5 * m * g * length * (1 - math.cos(al))
    acceleration = np.clip(50.0 * (energy - 0.025) * np.sign(ald * math.cos(al)) - 0.4 * th, -5, 5)
    return float(np.clip(8.4 / 0.042 * 0.095 * 0.085 * acceleration, -4, 4))


def test_package_convention_law_is_the_published_law():
    rng = np.random.default_rng(3)
    states = np.column_stack(
        [rng.uniform(-7, 7, 400), rng.uniform(-1.5, 1.5, 400), rng.uniform(-15, 15, 400), rng.uniform(-10, 10, 400)]
    )
    states[:100, 0] = rng.uniform(-0.4, 0.4, 100)  # many within the balance window
    voltage, _, _ = quanser_command(P, states)
    np.testing.assert_allclose(voltage, [published_law(*state) for state in states], atol=1e-12)


def test_drake_block_gives_the_law_with_direct_feedthrough():
    block = QuanserSwingUpController()
    context = block.CreateDefaultContext()
    for state in ([0.1, 0.2, 0.5, -1.0], [2.0, -0.5, 4.0, 1.0], [math.pi, 0.1, 0.0, 0.0]):
        block.GetInputPort("state_estimate").FixValue(context, state)
        expected = command(state)
        got = [
            block.GetOutputPort(name).Eval(context)[0] for name in ("voltage_V", "swingup_mode", "pendulum_energy_J")
        ]
        assert got == pytest.approx(expected)
    assert block.HasDirectFeedthrough(0, 0)


def test_bad_parameters_name_the_key():
    with pytest.raises(ConfigError, match="controller.quanser_swingup.rest_direction"):
        QuanserSwingUpParameters(rest_direction=0).validate()
    with pytest.raises(ConfigError, match="controller.quanser_swingup.balance_gains"):
        QuanserSwingUpParameters(balance_gains=[1.0, 2.0]).validate()


def test_filtered_derivative_follows_a_ramp_and_the_block_matches_the_arrays():
    """v_k = (1 - wc h) v_k-1 + wc (y_k - y_k-1): a ramp's slope after the transient, the same in Drake."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
    from pydrake.trajectories import PiecewisePolynomial

    h, corner = 0.004, 50.0
    time = np.arange(0, 1.0, h)
    angles = np.column_stack([0.3 * time, np.sin(2 * np.pi * time)])
    velocity = filtered_derivative(angles, h, corner)
    assert velocity[-1, 0] == pytest.approx(0.3, rel=1e-9) and np.all(velocity[0] == 0)
    builder = DiagramBuilder()
    source = builder.AddSystem(
        TrajectorySource(
            PiecewisePolynomial.ZeroOrderHold(  # held from each sample on
                np.append(time, time[-1] + h), np.vstack([angles, angles[-1]]).T
            )
        )
    )
    block = builder.AddSystem(FilteredDerivative(FilteredDerivativeParameters(corner=corner), period=h))
    builder.Connect(source.get_output_port(), block.GetInputPort("measured_angles_rad"))
    logger = LogVectorOutput(block.GetOutputPort("state_estimate"), builder, h)
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(time[-1] + 1e-9)
    logged = logger.FindLog(simulator.get_context()).data().T
    np.testing.assert_allclose(logged[:, 2:], velocity, atol=1e-12)
    with pytest.raises(ConfigError, match="corner"):
        filtered_derivative(angles, h, 600.0)
