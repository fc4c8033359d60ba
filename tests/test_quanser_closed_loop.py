"""The closed loop of Quanser's swing-up on the simulated QUBE (controller.mode quanser_swingup): the diagram
wired as the rig runs (voltage through kt / R, the server's velocity filter, no computation delay), its config
read back, and the paper's observers linearised at the hanging equilibrium on a hanging run whose truth is known."""

import dataclasses
import math

import numpy as np
import pytest

from furuta_drake.config import ExcitationConfig, SimulationConfig, dump_config, quanser_swingup_config
from furuta_drake.controllers.quanser_swingup import quanser_command
from furuta_drake.controllers.swingup import catch_time, wrap_angle
from furuta_drake.data import QUBE_REAL_RIG
from furuta_drake.errors import ConfigError
from furuta_drake.linearization import observer_model
from furuta_drake.observers.filtered_derivative import FilteredDerivativeParameters, filtered_derivative
from furuta_drake.paper import reproduce
from furuta_drake.rig import encoder_resolution
from furuta_drake.rig_file import load_rig
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import loads_yaml_dataclass


@pytest.fixture(scope="module")
def rig():
    return load_rig(QUBE_REAL_RIG)


@pytest.fixture(scope="module")
def swingup(rig):
    config = quanser_swingup_config(
        SimulationConfig.from_rig(rig),
        initial_state=[math.pi - 0.006, 0.0, 0.0, 0.0],
        duration=4.0,
        velocity_filter=FilteredDerivativeParameters(corner=47.0),
    )
    return config, simulate(config)


def test_swings_up_from_hanging_and_balances_within_the_clip(rig, swingup):
    config, result = swingup
    kt_over_r = rig.motor.torque_constant / rig.motor.resistance
    voltage = result.torque / kt_over_r
    assert np.max(np.abs(voltage)) <= 4.0 + 1e-12
    assert math.isfinite(catch_time(result)) and result.signals["swingup_mode"][-1, 0] == 1.0
    assert np.max(np.abs(wrap_angle(result.state[-50:, 0]))) < 0.05  # balanced at the upright
    encoder = encoder_resolution(rig.counts_per_rev)
    assert np.allclose(result.measured / encoder, np.round(result.measured / encoder), atol=1e-6)


def test_command_of_each_sample_is_the_law_on_that_sample(rig, swingup):
    """Row k's voltage is the law on row k's encoder angles and their filtered derivative up to row k: no
    computation delay, as the real logs record the command."""
    config, result = swingup
    velocity = filtered_derivative(result.measured, config.control_period, 47.0)
    expected, _, _ = quanser_command(config.controller.quanser_swingup, np.column_stack([result.measured, velocity]))
    voltage = result.torque * rig.motor.resistance / rig.motor.torque_constant
    np.testing.assert_allclose(voltage, expected, atol=1e-9)


def test_config_round_trips_and_needs_a_motor(rig, swingup):
    config, _ = swingup
    assert loads_yaml_dataclass(dump_config(config), SimulationConfig) == config
    with pytest.raises(ConfigError, match="rig.motor"):
        dataclasses.replace(config, rig=rig.replace(motor=None)).validate()


def test_hanging_observers_follow_a_hanging_run(rig):
    """Open loop, hanging, a multisine torque: HG and VFE linearised at theta = pi (with the back-EMF) replayed on
    the run's encoder angles track the true velocities to a small fraction of them; the same observers carrying
    the upright linearisation (gravity of the wrong sign) do not, the model-based VFE least of all."""
    base = SimulationConfig.from_rig(rig)
    config = dataclasses.replace(
        base,
        duration=4.0,
        initial_state=[math.pi, 0.0, 0.0, 0.0],
        controller=dataclasses.replace(base.controller, mode="open_loop"),
        excitation=ExcitationConfig(torque_rms=0.0015, frequency_min=0.5, frequency_max=6.0),
        monitor=dataclasses.replace(base.monitor, theta_bound=None),
    )
    result = simulate(config)
    assert np.max(np.abs(result.state[:, 0] - math.pi)) < 0.5  # stays in the linear range
    shifted = dataclasses.replace(result, measured=result.measured - [math.pi, 0.0])
    replay_config = dataclasses.replace(
        config,
        initial_state=[0.0, 0.0, 0.0, 0.0],
        observers=dataclasses.replace(config.observers, start_at_initial_state=True),
    )
    keep = result.time > 0.5
    truth = result.state[keep, 2:]
    rms = {}
    for equilibrium in ("hanging", "upright"):
        estimates = reproduce.replay_observers(
            shifted,
            replay_config,
            model=observer_model(rig, equilibrium),
            hg=config.observers.hg,
            vfe=(config.observers.vfe, None),
        )
        for name in ("hg", "vfe"):
            rms[(equilibrium, name)] = np.sqrt(np.mean((estimates[name][keep, 2:] - truth) ** 2, axis=0))
    scale = np.sqrt(np.mean(truth**2, axis=0))
    for name in ("hg", "vfe"):
        assert np.all(rms[("hanging", name)] < 0.1 * scale), name
        assert rms[("upright", name)][0] > 3 * rms[("hanging", name)][0], name
    assert rms[("upright", "vfe")][0] > 10 * rms[("hanging", "vfe")][0]
