"""The equation-error starts: the lag-L second difference is a tent-weighted mean of the accelerations held over the
samples around it, and the regression of a lab's 125 Hz bang-bang logs (an independent simulator's equations)
reads a drive gain well below 1, damping several times the back-EMF's, a cable and a sample of delay at once."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from benchmarks.diagnosis.lab_bang_bang import PERIOD, bang_bang
from benchmarks.independent import simulator as sim
from furuta_drake.diagnosis.logs.load import load_logs
from furuta_drake.diagnosis.selection.equation_error import equation_error_starts, tent
from furuta_drake.effects.vocabulary import rig_model
from furuta_drake.rig_file import load_rig


@settings(max_examples=25, deadline=None)
@given(lag=st.integers(1, 8), seed=st.integers(0, 1000))
def test_the_lag_second_difference_is_the_tent_mean_of_the_held_accelerations(lag, seed):
    """Positions of a motion whose acceleration a_i is held over each sample [i, i + 1) (exact kinematics)."""
    accelerations = np.random.default_rng(seed).normal(size=60)
    period = 0.01
    velocity = np.concatenate([[0.0], np.cumsum(accelerations * period)])
    position = np.concatenate([[0.0], np.cumsum(velocity[:-1] * period + 0.5 * accelerations * period**2)])
    k = 30
    second = (position[k + lag] - 2 * position[k] + position[k - lag]) / (lag * period) ** 2
    assert second == pytest.approx(tent(lag) @ accelerations[k - lag : k + lag], rel=1e-9)
    assert tent(lag).sum() == pytest.approx(1.0)


@pytest.fixture(scope="module")
def lab_folder(tmp_path_factory) -> Path:
    """A QUBE at 125 Hz, its drive at 0.7 of the rig file's gain, 3x the back-EMF's damping, a cable of 0.3 m g l
    per radian and one sample of delay: four 4 s trials of +-7 V bang-bang, from rest hanging."""
    folder = tmp_path_factory.mktemp("lab")
    rig = dataclasses.replace(sim.qube_like(), sample_period=PERIOD)
    back_emf = rig.motor.torque_constant * rig.motor.backemf_constant / rig.motor.resistance
    world = dataclasses.replace(
        sim.World(rig),
        gain=0.7,
        arm_viscous=3.0 * back_emf,
        spring_linear=0.3 * rig.bodies.d,
        delay_samples=1,
    )
    sim.write_rig_file(rig, folder / "rig.yaml")
    for k in range(4):
        sim.write_log(sim.play(world, bang_bang(100 + k, 500), 100 + k), folder / f"trial_{k}.csv")
    return folder


def test_a_lab_far_from_its_rig_file_is_read_by_the_regression(lab_folder):
    rig = load_rig(lab_folder / "rig.yaml")
    logs = load_logs(sorted(lab_folder.glob("trial_*.csv")), rig, lab_folder / "rig.yaml")
    model = rig_model(rig)
    starts = equation_error_starts(logs, model)
    back_emf = model.back_emf_damping
    assert starts["torque_gain_error"]["gain"] == pytest.approx(0.7, rel=0.05)
    assert starts["arm_viscous_friction"]["viscous"] == pytest.approx(3.0 * back_emf, rel=0.15)
    assert starts["arm_spring"]["stiffness"] == pytest.approx(0.3 * model.gravity_torque, rel=0.1)
    assert starts["input_delay"]["delay"] == pytest.approx(PERIOD)
