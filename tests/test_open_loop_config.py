"""``open_loop_config``: an identification run as a lab records one, open loop from rest."""

import math

import numpy as np
import pytest

from furuta_drake.config import SimulationConfig, open_loop_config
from furuta_drake.simulate import simulate


def test_a_zero_command_leaves_the_hanging_pendulum_at_rest():
    # The hanging pendulum at rest is an equilibrium: without a command nothing moves.
    config = open_loop_config("lund", np.zeros(500), duration=0.5, seed=3)
    assert config.controller.mode == "open_loop" and config.seed == 3 and config.monitor.theta_bound is None
    assert config.initial_state == [math.pi, 0.0, 0.0, 0.0]
    result = simulate(config)
    assert np.max(np.abs(result.state[:, 0] - math.pi)) < 1e-9
    assert np.max(np.abs(result.state[:, 1])) < 1e-9


def test_a_constant_torque_turns_the_arm_its_way_and_keeps_the_configs_other_sections():
    base = SimulationConfig.from_rig("lund")
    config = open_loop_config(base, np.full(200, 0.02), duration=0.2)
    assert config.rig == base.rig and config.friction == base.friction
    result = simulate(config)
    assert result.state[-1, 1] > 0.0  # a positive arm torque turns the arm the positive way
    assert config.excitation.command == pytest.approx([0.02] * 200)
