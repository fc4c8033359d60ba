"""The drive's tangent model (:mod:`furuta_drake.effects.drive_tangent`): the same angles as the drive kernel to the
last bit, and slopes in the initial state that are the flow's, checked against central differences of the kernel.

Where the teeth engage, the contact's damper switches on and the flow's sensitivity jumps (the saltation matrix);
a fixed-step scheme moves the engagement within a step and its differences only see that jump when the steps are
short against the time a perturbation moves the engagement by. So the play's slopes are checked on finely stepped
windows with differences of a few micro-radians, and a coupling without play (smooth) on the diagnosis' own steps.
"""

import numpy as np
import pytest

from furuta_drake.effects.surrogate import integrate_windows, state_sensitivities
from furuta_drake.effects.vocabulary import Effect, apply_effects, rig_model
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.rig import geared_rig

DRIVES = {
    "play": {"drive_backlash": Effect("", (0.02,))},
    "belt": {"drive_compliance": Effect("", (5.0, 0.05))},
    "play and belt": {"drive_backlash": Effect("", (0.01,)), "drive_compliance": Effect("", (5.0, 0.05))},
}
DAHL = JointFrictionParameters.dahl(5e-3, 4e-3, sigma0=5.0)


def _model(drive: str, dahl: bool):
    model = apply_effects(rig_model(geared_rig()), DRIVES[drive])
    return model.replace(arm_friction=DAHL) if dahl else model


def _windows(seed: int, width: int, samples: int, substeps: int, dahl: bool):
    """Windows hanging and swinging, the twist anywhere across a 0.03 rad play at up to a few rad/s."""
    rng = np.random.default_rng(seed)
    x = np.vstack([rng.normal(np.pi, 0.1, width), rng.normal(0, 0.1, width), rng.normal(0, 1.0, (2, width))])
    twist = np.vstack([rng.uniform(-0.03, 0.03, width), rng.normal(0, 3.0, width)])
    bristle = rng.uniform(-5e-4, 5e-4, width) if dahl else None
    torque = np.repeat(rng.normal(0, 0.2, (samples - 1, width)), substeps, axis=0)
    return x, twist, bristle, torque


def _central_differences(model, x, twist, bristle, torque, period, substeps, steps):
    """The angles' central differences (horizon, 2, W, n) in theta, phi, theta', phi', (z), delta, delta'."""
    every = np.vstack([x] + ([bristle[None, :]] if bristle is not None else []) + [twist])
    columns = []
    for i, step in enumerate(steps):
        ends = []
        for sign in (1.0, -1.0):
            moved = every.copy()
            moved[i] += sign * step
            z = moved[4] if bristle is not None else None
            ends.append(integrate_windows([model], moved[:4], torque, period, substeps, z, moved[-2:]))
        columns.append((ends[0] - ends[1]) / (2.0 * step))
    return np.stack(columns, axis=-1)


def _steps(scale: float, dahl: bool) -> list[float]:
    bristle = [1e-3 * DAHL.bristle_bound] if dahl else []
    return [scale, scale, 100 * scale, 100 * scale, *bristle, scale, 100 * scale]


@pytest.mark.parametrize("dahl", [False, True])
@pytest.mark.parametrize("drive", sorted(DRIVES))
def test_the_angles_are_the_drive_kernels_to_the_last_bit(drive, dahl):
    model = _model(drive, dahl)
    x, twist, bristle, torque = _windows(1, 60, 40, 2, dahl)
    angles, slopes = state_sensitivities(model, x, torque, 0.002, 2, bristle, twist)
    assert np.array_equal(angles, integrate_windows([model], x, torque, 0.002, 2, bristle, twist))
    assert slopes.shape == (40, 2, 60, 7 if dahl else 6)


@pytest.mark.parametrize("dahl", [False, True])
@pytest.mark.parametrize("drive", ["play", "play and belt"])
def test_with_a_play_the_slopes_are_the_flows_through_the_engagements(drive, dahl):
    """Stepped at 5 us, the flow's differences over 30 urad (3 mrad/s) resolve each engagement's move in time: the
    tangents agree within 2 % per state (norm over every window and sample), the twist's included, whose slopes the
    engagement's jump dominates. (The Dahl bristle's own column is left out: an arm turning inside the play
    reverses its bristle, an event of the friction law whose two sides the tangent averages as the rigid kernel's
    does, and these differences do not settle on it.)"""
    model, period, substeps = _model(drive, dahl), 0.001, 200
    x, twist, bristle, torque = _windows(2, 40, 15, substeps, dahl)
    _, slopes = state_sensitivities(model, x, torque, period, substeps, bristle, twist)
    reference = _central_differences(model, x, twist, bristle, torque, period, substeps, _steps(3e-5, dahl))
    mechanical = [0, 1, 2, 3, -2, -1]
    slopes, reference = slopes[..., mechanical], reference[..., mechanical]
    error = np.linalg.norm((slopes - reference).reshape(-1, 6), axis=0)
    assert np.all(error <= 0.02 * np.linalg.norm(reference.reshape(-1, 6), axis=0))


@pytest.mark.parametrize("dahl", [False, True])
def test_without_a_play_the_slopes_are_the_kernels_central_differences(dahl):
    """A belt alone is smooth: on the diagnosis' own steps (1 kHz, 2 substeps) the tangents are the kernel's
    central differences to their truncation error."""
    model = _model("belt", dahl)
    x, twist, bristle, torque = _windows(3, 60, 60, 2, dahl)
    _, slopes = state_sensitivities(model, x, torque, 0.002, 2, bristle, twist)
    reference = _central_differences(model, x, twist, bristle, torque, 0.002, 2, _steps(1e-6, dahl))
    assert np.max(np.abs(slopes - reference)) <= 1e-5 * np.max(np.abs(reference))
