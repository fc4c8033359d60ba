"""The lab controller: the simulated loop's controller stepped one sample at a time replays that loop's commands
from its measured samples, observers, Dahl observer, K_sigma adaptation and compensation included."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from furuta_drake.config import SimulationConfig, swingup_config
from furuta_drake.errors import ConfigError
from furuta_drake.friction import FrictionParameters, JointFrictionParameters
from furuta_drake.lab_controller import LabController
from furuta_drake.observers.dahl import DahlAdaptation, DahlObserverParameters
from furuta_drake.observers.k_sigma import KSigmaAdaptationParameters
from furuta_drake.simulate import simulate


def balancing(source: str, compensate: bool) -> SimulationConfig:
    """The Lund rig with arm Coulomb friction and noisy encoders balancing from a pendulum angle of a whole number
    of counts (so that the first measured sample is the initial state the loop's observers start at)."""
    config = SimulationConfig.from_rig("lund")
    count = config.encoder.encoder_resolution
    dahl = DahlObserverParameters(
        coulomb_pos=0.012,
        coulomb_neg=0.012,
        sigma0=6.0,
        adaptation=DahlAdaptation(k_sigma=KSigmaAdaptationParameters(gamma=2000.0, initial=0.8)),
    )
    return dataclasses.replace(
        config,
        friction=FrictionParameters(arm=JointFrictionParameters(model="static", coulomb_pos=0.012, coulomb_neg=0.012)),
        encoder=dataclasses.replace(config.encoder, noise_std=0.3 * count, seed=5),
        controller=dataclasses.replace(config.controller, velocity_source=source, friction_compensation=compensate),
        observers=dataclasses.replace(config.observers, dahl=dahl, start_at_initial_state=True),
        initial_state=[12 * count, 0.0, 0.0, 0.0],
        duration=1.0,
    )


@pytest.mark.parametrize("source, compensate", [("hg", False), ("vfe", True)])
def test_the_lab_controller_replays_the_simulated_loops_commands(source, compensate):
    config = balancing(source, compensate)
    run = simulate(config)
    controller = LabController(config)
    commands = np.array([controller(measured) for measured in run.measured])
    assert np.abs(run.torque).max() > 0.01  # the loop did work: a replay of zeros would prove nothing
    np.testing.assert_array_equal(commands, run.torque)


def test_a_swing_up_is_not_a_lab_balancing_controller():
    with pytest.raises(ConfigError, match="mode 'lqr'"):
        LabController(swingup_config("lund"))
