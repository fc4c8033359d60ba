"""The compiled surrogate kernel against the laws it restates: each friction law against
:mod:`furuta_drake.friction` (the one the Drake systems use), the bristle step against the Dahl law's exact
solution, and the lag filter against the first-order lag's closed form."""

import math
import subprocess
import sys

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.effects import surrogate_kernel as kernel
from furuta_drake.friction import (
    JointFrictionParameters,
    bristle_friction_torque,
    dahl_exact_step,
    static_friction_torque,
    stribeck_curve,
)

levels = st.floats(1e-4, 1e-2)
velocities = st.floats(-20.0, 20.0)


@st.composite
def joints(draw, model):
    coulomb_pos, coulomb_neg = draw(levels), draw(levels)
    stribeck = model != "dahl" and draw(st.booleans())
    return JointFrictionParameters(
        model=model,
        coulomb_pos=coulomb_pos,
        coulomb_neg=coulomb_neg,
        static_pos=coulomb_pos * draw(st.floats(1.0, 3.0)) if stribeck else None,
        static_neg=coulomb_neg * draw(st.floats(1.0, 3.0)) if stribeck else None,
        stribeck_velocity=draw(st.floats(0.01, 1.0)),
        viscous=draw(st.floats(0.0, 1e-3)),
        sigma0=draw(st.floats(0.1, 50.0)),
        sigma1=draw(st.floats(0.0, 0.05)) if model == "lugre" else 0.0,
        regularization_velocity=draw(st.floats(1e-3, 0.1)),
    )


@settings(max_examples=200, deadline=None)
@given(joints("static"), velocities)
def test_static_law_is_the_friction_modules(p, v):
    row = kernel.pack_friction(p)
    assert kernel.stribeck_level(v, row) == pytest.approx(stribeck_curve(v, p), rel=1e-12)
    assert kernel.static_torque(v, row) == pytest.approx(static_friction_torque(v, p), rel=1e-12, abs=1e-18)


@settings(max_examples=200, deadline=None)
@given(st.sampled_from(["dahl", "lugre"]).flatmap(joints), velocities, st.floats(-1.0, 1.0))
def test_bristle_torque_is_the_friction_modules(p, v, fraction):
    z = fraction * p.bristle_bound
    assert kernel.bristle_torque(z, v, kernel.pack_friction(p)) == pytest.approx(
        bristle_friction_torque(z, v, p), rel=1e-12, abs=1e-18
    )


@settings(max_examples=200, deadline=None)
@given(joints("dahl"), st.floats(-0.5, 0.5), st.floats(-1.0, 1.0))
def test_dahl_bristle_step_is_the_exact_solution_over_the_path(p, displacement, fraction):
    """Dahl's law is rate independent: over a monotone move the bristle is the exact solution at frozen
    direction, whatever the speed."""
    z = fraction * p.bristle_bound
    level = p.coulomb_pos if displacement > 0 else p.coulomb_neg
    expected = dahl_exact_step(z, displacement, 1.0, p.sigma0, level)
    row = kernel.pack_friction(p)
    for speed in (0.1, 10.0):
        assert kernel.bristle_step(z, displacement, speed, row) == pytest.approx(expected, rel=1e-12, abs=1e-18)
    assert abs(kernel.bristle_step(z, displacement, 1.0, row)) <= p.bristle_bound * (1 + 1e-12)


def test_lag_filter_is_the_first_order_lags_closed_form():
    """A step from 0 to 1 into a lag of 5 ms from rest, in 1 ms substeps: each substep's output is the mean of
    1 - exp(-t / T) over it, and the final state is 1 - exp(-t_end / T)."""
    time_constant, dt, steps = 5e-3, 1e-3, 20
    filtered, state = kernel.lag_filter(np.ones((steps, 1)), np.zeros(1), time_constant, dt)
    for i in range(steps):
        start, end = i * dt, (i + 1) * dt
        mean = 1.0 - time_constant / dt * (math.exp(-start / time_constant) - math.exp(-end / time_constant))
        assert filtered[i, 0] == pytest.approx(mean, rel=1e-12)
    assert state[0] == pytest.approx(1.0 - math.exp(-steps * dt / time_constant), rel=1e-12)


def test_a_windows_lag_state_is_the_filtered_command_history():
    """A 12 ms lag on a 1 kHz chirp: the lag's state at each window start is the first-order filter of the whole
    command up to there (scipy's lsim of 1 / (T s + 1) on the held command, from rest at the log's start) to
    within the e^-5 of the pre-roll's truncation, where the command at the start is far off."""
    from scipy.signal import lsim

    from furuta_drake.effects.surrogate import Model, lag_states
    from furuta_drake.rig import qube_servo2_rig

    period, lag = 1e-3, 0.012
    time = np.arange(3000) * period
    command = 0.02 * np.sin(2 * np.pi * (1.0 + 4.0 * time) * time)
    starts = np.array([400, 1100, 1800, 2500])
    model = Model.from_rig(qube_servo2_rig()).replace(lag=lag)
    fine = np.arange(0, time[-1], period / 50)
    _, exact, _ = lsim(([1.0], [lag, 1.0]), command[np.floor(fine / period + 1e-9).astype(int)], fine)
    expected = np.interp(time[starts], fine, exact)
    states = lag_states(model, command, starts, period, 1)
    np.testing.assert_allclose(states, expected, atol=math.exp(-5) * np.ptp(command))
    assert np.max(np.abs(command[starts] - expected)) > 10 * math.exp(-5) * np.ptp(command)


def _rows(arm: JointFrictionParameters, rigid=(1.0e-3, 1.2e-4, 8.0e-5, 0.0147, 0.0, 0.0, 0.0, 0.0)):
    pendulum = JointFrictionParameters(model="static", coulomb_pos=1e-5, coulomb_neg=1e-5)
    return (
        np.array([rigid]),
        kernel.pack_friction(arm)[None],
        kernel.pack_friction(pendulum)[None],
        np.zeros((1, 0, 3)),
    )


@settings(max_examples=20, deadline=None)
@given(model=st.sampled_from(["static", "dahl", "lugre"]), data=st.data(), seed=st.integers(0, 2**16))
def test_integrate_without_division_checks_equals_the_checked_kernel_bitwise(model, data, seed):
    """The kernel run without division checks gives the checked compilation's numbers to the last bit, diverging
    windows (torques of 1e6 N m overflow to inf and nan) included."""
    rng = np.random.default_rng(seed)
    x0 = np.ascontiguousarray(rng.normal(size=(4, 12)))
    z0 = 1e-4 * rng.normal(size=12)
    torque = 0.01 * rng.normal(size=(40, 12))
    torque[:, :3] = 1e6
    rows = _rows(data.draw(joints(model)))
    fast = kernel.integrate(x0, z0, torque, 1e-3, 2, *rows)
    checked = kernel._checked(x0, z0, torque, 1e-3, 2, *rows)
    assert not np.isfinite(checked[0][:, :, :3]).all()
    for a, b in zip(fast, checked):
        assert np.array_equal(a, b, equal_nan=True)


def test_integrate_raises_at_a_division_by_zero_as_the_checked_kernel():
    """A singular mass matrix (a b = c^2 with the pendulum upright: det = a b - c^2 = 0) and a zero regularisation
    velocity of a static friction law raise ZeroDivisionError, as Python's division does."""
    x0, z0, torque = np.zeros((4, 2)), np.zeros(2), np.zeros((5, 2))
    arm = JointFrictionParameters(model="static", coulomb_pos=1e-3, coulomb_neg=1e-3, regularization_velocity=0.02)
    with pytest.raises(ZeroDivisionError):
        kernel.integrate(x0, z0, torque, 1e-3, 1, *_rows(arm, rigid=(1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0)))
    arm = JointFrictionParameters(model="static", coulomb_pos=1e-3, coulomb_neg=1e-3, regularization_velocity=0.0)
    with pytest.raises(ZeroDivisionError):
        kernel.integrate(x0, z0, torque, 1e-3, 1, *_rows(arm))


def test_load_kernel_leaves_every_variant_the_fits_call_in_the_process():
    """A fresh process that called load_kernel holds the kernels compiled, their checked variants (a diverging
    window runs checked) included, so that worker processes forked from it compile nothing mid-run."""
    script = (
        "from furuta_drake.effects import surrogate, surrogate_kernel, surrogate_tangent\n"
        "surrogate.load_kernel()\n"
        "kernels = (surrogate_kernel._unchecked, surrogate_kernel._checked, surrogate_tangent._unchecked,\n"
        "           surrogate_tangent._checked, surrogate_kernel.bristle_path)\n"
        "print([len(kernel.overloads) for kernel in kernels])\n"
    )
    out = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, check=True).stdout
    assert out.split("\n")[-2] == "[1, 1, 1, 1, 1]"
