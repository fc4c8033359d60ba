"""The surrogate's one call per batch of windows (:func:`~furuta_drake.effects.surrogate.predict_batch`) and the
hidden states it starts from (:func:`~furuta_drake.effects.surrogate.bristle_starts`,
:func:`~furuta_drake.effects.surrogate.twist_starts`): models side by side in one call predict as each alone, the
state slopes are the angles' derivatives, a Dahl arm's bristle read from a long slide sits at its saturation
Fc / sigma0, and a drive at rest under a steady torque T is twisted by b sign(T) + T / k.
"""

from __future__ import annotations

import numpy as np
import pytest

from furuta_drake.effects.surrogate import (
    HISTORY,
    Model,
    WindowInputs,
    bristle_starts,
    initial_states,
    predict_batch,
    twist_starts,
)
from furuta_drake.effects.vocabulary import rig_model
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.rig import geared_rig, lund_rig

PERIOD = 1e-3
HORIZON = 40


def inputs(windows: int, seed: int = 0) -> tuple[WindowInputs, np.ndarray]:
    rng = np.random.default_rng(seed)
    command = np.concatenate([np.zeros(HISTORY), 0.05 * np.sin(np.arange(2000) * 0.01) + 0.01 * rng.normal(size=2000)])
    starts = HISTORY + 200 * np.arange(windows)
    x0 = np.vstack([0.05 * rng.normal(size=(2, windows)), 0.3 * rng.normal(size=(2, windows))])
    return WindowInputs(command, starts, HORIZON, PERIOD, 1), x0


def test_models_side_by_side_predict_as_each_alone():
    nominal = Model.from_rig(lund_rig())
    models = [nominal, nominal.replace(gain=0.8, lag=0.004), nominal.replace(delay=0.003)]
    batch, x0 = inputs(5)
    together = predict_batch(models, np.tile(x0, (1, len(models))), batch).angles
    for k, model in enumerate(models):
        alone = predict_batch(model, x0, batch).angles
        np.testing.assert_allclose(together[:, :, 5 * k : 5 * (k + 1)], alone, rtol=0, atol=1e-14)
    # A different input chain is a different prediction: the lag and the delay each change the angles.
    assert np.max(np.abs(together[:, :, 5:10] - together[:, :, :5])) > 1e-6
    assert np.max(np.abs(together[:, :, 10:] - together[:, :, :5])) > 1e-6


@pytest.mark.parametrize("arm", ["static", "dahl"])
def test_state_slopes_are_the_angles_derivatives(arm):
    model = Model.from_rig(lund_rig())
    if arm == "dahl":
        model = model.replace(
            arm_friction=JointFrictionParameters(model="dahl", coulomb_pos=0.012, coulomb_neg=0.018, sigma0=10.0)
        )
    batch, x0 = inputs(4, seed=1)
    x = x0 if arm == "static" else np.vstack([x0, np.full((1, 4), 2e-4)])
    prediction = predict_batch(model, x, batch, states=True)
    assert prediction.slopes.shape == (HORIZON, 2, 4, x.shape[0])
    steps = [1e-7, 1e-7, 1e-5, 1e-5, 1e-7][: x.shape[0]]
    for i, step in enumerate(steps):
        shift = np.zeros_like(x)
        shift[i] = step
        up = predict_batch(model, x + shift, batch, prediction.torque).angles
        down = predict_batch(model, x - shift, batch, prediction.torque).angles
        np.testing.assert_allclose(prediction.slopes[..., i], (up - down) / (2 * step), rtol=1e-4, atol=1e-7)


def test_a_dahl_bristle_read_from_a_long_slide_is_saturated():
    friction = JointFrictionParameters(model="dahl", coulomb_pos=0.012, coulomb_neg=0.018, sigma0=10.0)
    model = Model.from_rig(lund_rig()).replace(arm_friction=friction)
    path = np.linspace(0.0, 1.0, 1001)  # 1 rad forward, thousands of presliding lengths (1.2 mrad)
    bristle = bristle_starts(model, path, PERIOD, np.array([500, 1000]))
    np.testing.assert_allclose(bristle, 0.012 / 10.0, rtol=1e-6)
    backwards = bristle_starts(model, path[::-1].copy(), PERIOD, np.array([1000]))
    np.testing.assert_allclose(backwards, -0.018 / 10.0, rtol=1e-6)


def test_a_drive_at_rest_under_a_steady_torque_twists_by_its_play_and_spring():
    rig = geared_rig()
    stiffness, backlash = 2.0, 0.01  # [N m/rad], [rad]
    model = rig_model(rig).replace(drive_backlash=backlash, drive_stiffness=stiffness, drive_damping=0.0)
    torque = 0.03  # [N m], below the geared rig's limit and past no dead zone or saturation
    samples = 500
    path = np.full(samples, 0.2)  # the arm at rest
    starts = np.array([100, 400])
    twist = twist_starts(model, path, np.full(samples, torque), PERIOD, starts)
    np.testing.assert_allclose(twist[0], backlash + torque * model.gain / stiffness, rtol=1e-9)
    np.testing.assert_allclose(twist[1], 0.0, atol=1e-12)
    # With the encoder on the motor, the logged angle is the rotor's: the arm's is that less the twist.
    smoothed = np.array([[0.0, 0.0], [0.2, 0.2], [0.0, 0.0], [0.0, 0.0]])
    motor = model.replace(drive_encoder="motor")
    x = initial_states(motor, smoothed, path, np.full(samples, torque), PERIOD, starts)
    assert x.shape == (6, 2)
    np.testing.assert_allclose(x[1], 0.2 - twist[0], rtol=1e-12)
    np.testing.assert_allclose(x[4:], twist, rtol=1e-12)
