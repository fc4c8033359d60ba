"""The surrogate's exact forward sensitivities (:mod:`furuta_drake.effects.surrogate_tangent`) against central
finite differences of the kernel they differentiate, at the kernel (every initial-state, packed-parameter and
torque direction, for every friction kind, spring, back-EMF damping and unmodelled terms on both joints) and at
the diagnosis (the parameter columns of the fit's Jacobian through the input chain, and a small fit)."""

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.diagnosis.gap.metric import (
    fixed_state_residuals_of,
    make_windows,
    parameter_slopes_of,
    projected_residuals,
    state_jacobians,
)
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.diagnosis.selection import fit
from furuta_drake.diagnosis.selection.fit import FitTask, _least_squares
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects import surrogate_kernel as kernel
from furuta_drake.effects import surrogate_tangent as tangent
from furuta_drake.effects.surrogate import HISTORY, Model, predict_windows, same_branches
from furuta_drake.effects.vocabulary import Effect, apply_effects, rig_model
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.rig import geared_rig, qube_servo2_rig

ARMS = {
    "none": JointFrictionParameters(),
    "static": JointFrictionParameters(
        model="static",
        coulomb_pos=2e-3,
        coulomb_neg=2e-3,
        static_pos=3.5e-3,
        static_neg=3.5e-3,
        stribeck_velocity=0.1,
        viscous=1e-4,
        regularization_velocity=0.02,
    ),
    # a static law without a level (the nominal rig's): viscous alone, its levels' slopes still wanted by a fit
    "viscous alone": JointFrictionParameters(model="static", viscous=1e-4, regularization_velocity=0.02),
    "dahl": JointFrictionParameters.dahl(1.5e-3, 1.1e-3, sigma0=1.5, viscous=1e-4),
    "lugre": JointFrictionParameters(
        model="lugre",
        coulomb_pos=1.5e-3,
        coulomb_neg=1.5e-3,
        static_pos=3e-3,
        static_neg=3e-3,
        stribeck_velocity=0.1,
        sigma0=1.5,
        sigma1=0.01,
        viscous=1e-4,
    ),
}
PENDULUM = JointFrictionParameters(
    model="static",
    coulomb_pos=5e-5,
    coulomb_neg=5e-5,
    static_pos=8e-5,
    static_neg=8e-5,
    stribeck_velocity=0.2,
    viscous=1e-6,
    regularization_velocity=0.02,
)
# (joint, term of torque_library.TERMS, coefficient [N m]): on the arm a constant, sin(3 phi), a rate of the
# pendulum and one of the arm times cos(phi); on the pendulum sin(theta), a smoothed sign times cos(phi), quadratic
# drag times sin(phi)
TERMS = ((0, 0, 1e-3), (0, 3, 2e-3), (0, 55, 1e-4), (0, 62, 2e-4), (1, 49, 1e-3), (1, 60, 5e-4), (1, 71, 3e-4))
# (theta, phi, theta', phi') [rad, rad/s] and the bristle's share of its bound: upright and hanging, moving and at
# rest, and near a stick (the arm slowly reversing against the torque with its bristle near saturation)
STATES = {
    "upright moving": (0.1, 0.3, 1.5, -2.0, 0.2),
    "hanging moving": (math.pi - 0.2, -0.5, -1.0, 1.5, -0.5),
    "upright at rest": (0.05, 0.2, 0.0, 0.0, 0.3),
    "hanging at rest": (math.pi, 0.0, 0.0, 0.0, 0.0),
    "near a stick": (math.pi - 0.05, 0.1, 0.05, 0.01, 0.9),
}
STEPS, DT = 24, 1e-3


def _model(arm: str, spring: str = "cubic", terms=TERMS) -> Model:
    return Model.from_rig(qube_servo2_rig()).replace(
        arm_friction=ARMS[arm],
        pendulum_friction=PENDULUM,
        back_emf_damping=1e-3,
        spring_stiffness=0.01,
        spring_cubic=0.05 if spring == "cubic" else 0.0,
        spring_equilibrium=0.1,
        unmodelled_terms=terms,
    )


def _problem(model: Model, states=STATES, seed: int = 0):
    """Initial states (4, W), bristles (W,) and torques (STEPS, W) [N m] of the windows of ``states``: a random
    torque about a level below the arm's friction (a stick) in the last window."""
    rows = np.array(list(states.values())).T
    bound = model.arm_friction.bristle_bound if model.arm_friction.has_bristles else 0.0
    rng = np.random.default_rng(seed)
    torque = 2e-3 * rng.standard_normal((STEPS, rows.shape[1]))
    torque[:, -1] = -1e-3 + 1e-4 * rng.standard_normal(STEPS)
    return np.ascontiguousarray(rows[:4]), rows[4] * bound, torque


def _integrate(x0, z0, torque, substeps, values, terms):
    """The kernel's angles with the flat parameters ``values`` (:func:`~.surrogate_tangent.flat`)."""
    a, p = tangent.ARM, tangent.PENDULUM
    terms = np.array(terms, dtype=float).reshape(-1, 3)
    terms[:, 2] = values[tangent.TERMS :]
    rows = (values[None, :a], values[None, a:p], values[None, p : tangent.TERMS], terms[None])
    return kernel.integrate(x0, z0, torque, DT, substeps, *rows)[0]


def _fixed_entries(model: Model) -> list[int]:
    """Flat entries that select a branch of the kernel (kinds, Stribeck flags, a zero bristle damping): no
    direction to differentiate along."""
    fixed = [tangent.ARM + kernel.F_KIND, tangent.ARM + kernel.F_STRIBECK]
    fixed += [tangent.PENDULUM + kernel.F_KIND, tangent.PENDULUM + kernel.F_STRIBECK]
    return fixed + [tangent.ARM + kernel.F_SIGMA1] * (model.arm_friction.sigma1 == 0.0)


def _difference(angles_at, step: float) -> tuple[np.ndarray, float]:
    """The derivative at 0 of ``angles_at(offset)`` by the five-point central difference of ``step`` (fourth
    order: near a stick the bristle's curvature makes a second-order one need steps below its roundoff), and the
    size of its roundoff."""
    near, far = angles_at(step) - angles_at(-step), angles_at(2 * step) - angles_at(-2 * step)
    return (8.0 * near - far) / (12.0 * step), 1e-14 * np.max(np.abs(angles_at(0.0))) / step


def _compare(exact: np.ndarray, difference: tuple[np.ndarray, float], rtol: float = 1e-6) -> float:
    """Asserts that a column is its finite difference to ``rtol`` of the column's size (or to the difference's
    roundoff); returns the relative difference."""
    differenced, roundoff = difference
    scale = np.max(np.abs(differenced))
    error = np.max(np.abs(exact - differenced))
    assert error <= rtol * scale + roundoff, (error, scale, roundoff)
    return error / max(scale, 1e-300)


def _state_columns(model, x0, z0, torque, substeps, relative: float = 1e-5):
    """Every initial-state column (exact, its finite difference of steps ``relative`` [rad, rad/s, share of the
    bristle's bound])."""
    n = 5 if model.arm_friction.has_bristles else 4
    slopes = tangent.tangents(x0, z0, torque, DT, substeps, kernel.pack(model), np.eye(n, 5))[1]
    values, terms = tangent.flat(model), model.unmodelled_terms
    size = [relative] * 4 + [relative * model.arm_friction.bristle_bound if n == 5 else 0.0]
    for i in range(n):
        unit = np.eye(5)[:, [i]]

        def angles_at(offset, unit=unit):
            return _integrate(x0 + offset * unit[:4], z0 + offset * unit[4], torque, substeps, values, terms)

        yield slopes[..., i], _difference(angles_at, size[i])


@pytest.mark.parametrize("substeps", [1, 3])
@pytest.mark.parametrize("spring", ["linear", "cubic"])
@pytest.mark.parametrize("arm", sorted(ARMS))
def test_every_column_is_the_kernels_central_difference(arm, spring, substeps):
    """Every initial-state, packed-parameter and torque column at upright and hanging states, moving, at rest and
    near a stick, against central differences of the kernel; the angles are the kernel's to the last bit."""
    model = _model(arm, spring)
    x0, z0, torque = _problem(model)
    for exact, differenced in _state_columns(model, x0, z0, torque, substeps):
        _compare(exact, differenced)
    values, terms = tangent.flat(model), model.unmodelled_terms
    entries = [j for j in range(values.size) if j not in _fixed_entries(model)]
    rng = np.random.default_rng(1)
    change = 1e-3 * rng.standard_normal(torque.shape)
    rows = np.zeros((len(entries) + 1, values.size))
    rows[np.arange(len(entries)), entries] = 1.0
    seeds = np.zeros((len(entries) + 1, 5))
    torques = [None] * len(entries) + [change]
    angles, slopes = tangent.tangents(x0, z0, torque, DT, substeps, kernel.pack(model), seeds, rows, torques)
    assert np.array_equal(angles, _integrate(x0, z0, torque, substeps, values, terms))
    for k, j in enumerate(entries):

        def angles_at(offset, j=j):
            return _integrate(x0, z0, torque, substeps, values + offset * np.eye(values.size)[j], terms)

        _compare(slopes[..., k], _difference(angles_at, 1e-4 * max(abs(values[j]), 1e-3)))
    _compare(
        slopes[..., -1],
        _difference(lambda offset: _integrate(x0, z0, torque + offset * change, substeps, values, terms), 1e-2),
    )


joint_kinds = st.sampled_from(["none", "static", "dahl", "lugre"])
# Initial rates [rad/s]: zero, or off it by more than a difference's step (a bristle's step turns at zero
# displacement: exactly there its slope is the mean of its sides', as a central difference sees it)
rates = st.floats(-3, 3).map(lambda v: 0.0 if abs(v) < 1e-3 else v)


@st.composite
def arms(draw):
    """An arm friction row of any kind; Dahl's asymmetric. (An asymmetric static law's slope jumps at zero velocity,
    where an arm creeping at a stick stays: there a central difference straddles the jump.)"""
    kind = draw(joint_kinds)
    coulomb_pos, coulomb_neg = draw(st.floats(2e-4, 5e-3)), draw(st.floats(2e-4, 5e-3))
    if kind != "dahl":
        coulomb_neg = coulomb_pos
    stribeck = kind in ("static", "lugre") and draw(st.booleans())
    return JointFrictionParameters(
        model=kind,
        coulomb_pos=coulomb_pos,
        coulomb_neg=coulomb_neg,
        static_pos=coulomb_pos * draw(st.floats(1.0, 3.0)) if stribeck else None,
        static_neg=coulomb_neg * draw(st.floats(1.0, 3.0)) if stribeck else None,
        stribeck_velocity=draw(st.floats(0.02, 1.0)),
        viscous=draw(st.floats(0.0, 1e-3)),
        sigma0=draw(st.floats(0.5, 20.0)),
        sigma1=draw(st.floats(0.0, 0.05)) if kind == "lugre" else 0.0,
        regularization_velocity=draw(st.floats(5e-3, 0.1)),
    )


@settings(max_examples=25, deadline=None, derandomize=True)
@given(
    arm=arms(),
    state=st.tuples(st.floats(-3.1, 3.1), st.floats(-1, 1), rates, rates, st.floats(-1, 1)),
    substeps=st.integers(1, 3),
    seed=st.integers(0, 2**16),
)
def test_state_and_torque_columns_are_central_differences_for_any_state_and_friction(arm, state, substeps, seed):
    """Drawn friction rows, initial states and torques: every initial-state column and a torque column against
    the kernel's finite differences (of small steps: a regularisation velocity of a few mrad/s bends the static
    law sharply where an arm creeps at a stick)."""
    model = _model("none").replace(arm_friction=arm)
    x0, z0, torque = _problem(model, {"drawn": state}, seed)
    for exact, differenced in _state_columns(model, x0, z0, torque, substeps, relative=1e-6):
        _compare(exact, differenced, rtol=1e-5)
    change = np.random.default_rng(seed).standard_normal(torque.shape)
    slopes = tangent.tangents(x0, z0, torque, DT, substeps, kernel.pack(model), np.zeros((1, 5)), None, [change])[1]
    values, terms = tangent.flat(model), model.unmodelled_terms

    def angles_at(offset):
        return _integrate(x0, z0, torque + offset * change, substeps, values, terms)

    _compare(slopes[..., 0], _difference(angles_at, 1e-7), rtol=1e-5)


def _log(model: Model, seed: int, period: float = 2e-3, duration: float = 2.0) -> RunLog:
    """A log of ``model`` hanging under a multisine, simulated by the surrogate itself, its angles rounded to the
    encoder's counts."""
    rng = np.random.default_rng(seed)
    time = np.arange(int(duration / period)) * period
    frequencies, phases = rng.uniform(0.5, 6.0, 6), rng.uniform(0, 2 * np.pi, 6)
    command = 0.25 * model.gravity_torque * np.sin(2 * np.pi * frequencies * time[:, None] + phases).sum(axis=1)
    padded = np.concatenate([np.zeros(HISTORY), command])
    x0 = np.array([[math.pi - 0.3], [0.0], [0.0], [0.0]])
    angles = predict_windows(model, x0, padded, np.array([HISTORY]), time.size, period, 2, np.zeros(1))[:, :, 0]
    count = 2 * np.pi / model.counts_per_rev
    theta, phi = np.round(angles.T / count) * count
    return RunLog(f"run_{seed}.csv", "", time, theta, phi, "torque", command, period)


# The effects of the fit whose columns are checked: every input-chain form that is differentiable, springs,
# friction laws of both joints and the lumped constants
EFFECTS = {
    "input_delay": Effect("jitter", (3.3e-3, 1e-3)),
    "actuator_lag": Effect("", (6.3e-3,)),  # off the steps of its pre-roll's length (a whole number of substeps)
    "torque_gain_error": Effect("", (1.1,)),
    "actuator_deadzone": Effect("subtract", (4e-3,)),
    "actuator_saturation": Effect("smooth", (0.08,)),
    "arm_spring": Effect("cubic", (0.01, 0.05, 0.1)),
    "inertia_mismatch": Effect("", (1.05, 0.95, 1.02, 0.98)),
    "pendulum_friction": Effect("", (5e-5, 2e-6)),
}
# Relative steps of the residuals' differences: 1e-5 (a larger one crosses the kinks of an asymmetric friction
# or a dead zone at some stage of some window), the jitter's 1e-4 (its expected command, a double integral's
# difference, loses digits)
DIFFERENCE_STEPS = {"input_delay": 1e-4}
ARM_FORMS = {
    "dahl": ("arm_coulomb_friction", Effect("presliding", (2e-3, 3e-3))),
    "lugre": ("arm_stribeck", Effect("presliding", (2e-3, 4e-3, 0.1, 3e-3))),
    "static": ("friction_asymmetry", Effect("smooth", (2e-3, 1.5e-3, 0.02))),
}


@pytest.mark.parametrize("law", sorted(ARM_FORMS))
def test_the_fits_exact_columns_are_the_residuals_central_differences(law):
    """The columns of every parameter of a model holding every differentiable form of the vocabulary (the input
    chain's through the torque's difference, the rest through the packed parameters'), from the refined states of
    two logs at different rates, against central differences of the residuals at those states."""
    rig = qube_servo2_rig()
    name, arm = ARM_FORMS[law]
    effects = {**EFFECTS, name: arm}
    sizes = [len(effect.values) for effect in effects.values()]
    x = np.concatenate([effect.values for effect in effects.values()])

    def model_at(values):
        parts = np.split(values, np.cumsum(sizes)[:-1])
        return apply_effects(
            Model.from_rig(rig),
            {key: Effect(effect.form, tuple(part)) for (key, effect), part in zip(effects.items(), parts)},
        )

    model = model_at(x)
    logs = [_log(model, 0), _log(model, 1, period=1e-3, duration=1.0)]
    windows = make_windows(logs, rig).subset(12)
    states = projected_residuals(model, windows, rig.counts_per_rev)[1]

    def columns(sign: float) -> list[list[np.ndarray]]:
        steps = sign * 1e-4 * np.abs(x)
        shifted = [model_at(x + step * np.eye(x.size)[i]) for i, step in enumerate(steps)]
        assert all(same_branches(model, other) for other in shifted)
        return parameter_slopes_of(model, shifted, list(steps), windows, states, rig.counts_per_rev)

    forward, backward = columns(1.0), columns(-1.0)  # the mappings' differences on both sides: second order
    relative = np.concatenate([[DIFFERENCE_STEPS.get(key, 1e-5)] * size for key, size in zip(effects, sizes)])
    for i in range(x.size):
        step = relative[i] * abs(x[i])
        unit = np.eye(x.size)[i]
        near, far = (
            fixed_state_residuals_of(
                [model_at(x + k * step * unit), model_at(x - k * step * unit)], windows, states, rig.counts_per_rev
            )
            for k in (1, 2)
        )
        for log in range(len(logs)):
            differenced = (8.0 * (near[0][log] - near[1][log]) - (far[0][log] - far[1][log])) / (12.0 * step)
            exact = (forward[i][log] + backward[i][log]) / 2.0
            _compare(exact, (differenced, 1e-13 * np.max(np.abs(near[0][log])) / step), rtol=1e-5)


@pytest.mark.parametrize("law", ["none", *sorted(ARM_FORMS), "drive"])
def test_the_states_sensitivities_simulated_apart_are_the_refinements_to_the_last_bit(law):
    """A fit simulates the windows' state sensitivities only where it forms a Jacobian: at the refined states of
    two logs at different rates, those equal what the refinement returns with its sensitivities, bit for bit, for
    every arm friction law and for a geared drive's backlash (its twist differenced)."""
    if law == "drive":
        rig = geared_rig()
        model = apply_effects(rig_model(rig), {"drive_backlash": Effect("", (0.02,))})
    else:
        rig = qube_servo2_rig()
        model = Model.from_rig(rig) if law == "none" else apply_effects(Model.from_rig(rig), dict([ARM_FORMS[law]]))
    logs = [_log(model, 0), _log(model, 1, period=1e-3, duration=1.0)]
    windows = make_windows(logs, rig).subset(12)
    _, states, refined = projected_residuals(model, windows, rig.counts_per_rev)
    apart = state_jacobians(model, windows, states, rig.counts_per_rev)
    assert len(apart) == len(logs)
    for together, alone in zip(refined, apart):
        assert together.shape == alone.shape and together.shape[3] == states[0].shape[0]
        assert np.array_equal(together, alone)


def test_a_threshold_dead_zone_or_a_change_of_friction_law_is_no_direction_to_differentiate():
    """Where the kernel's branches differ between a model and its parameter step, or a threshold dead zone's width
    moves (its torque jumps), the fit keeps a finite difference."""
    model = _model("static")
    assert same_branches(model, model.replace(spring_stiffness=0.02, gain=1.1, deadzone=1e-3))
    assert not same_branches(model, model.replace(arm_friction=ARMS["dahl"]))
    assert not same_branches(model, model.replace(unmodelled_terms=TERMS[:-1]))
    threshold = model.replace(deadzone=1e-3, deadzone_form="threshold")
    assert not same_branches(threshold, threshold.replace(deadzone=1.001e-3))
    assert same_branches(threshold, threshold.replace(gain=1.1))
    lugre = _model("lugre")
    undamped = lugre.replace(arm_friction=dataclasses.replace(ARMS["lugre"], sigma1=0.0))
    assert not same_branches(undamped, lugre)


def test_a_fit_with_exact_columns_finds_the_finite_difference_fits_parameters(monkeypatch):
    """A hidden input lag and spring fitted from a surrogate log: the least squares with exact columns and with
    finite-difference ones (every column differenced) end at the same parameters, the true ones."""
    rig = qube_servo2_rig()
    truth = {"arm_spring": Effect("linear", (0.04, 0.15)), "actuator_lag": Effect("", (8e-3,))}
    logs = (_log(apply_effects(Model.from_rig(rig), truth), 2, duration=3.0),)
    task = FitTask(
        "actuator_lag",
        {"arm_spring": Effect("linear", (0.02, 0.0))},
        Model.from_rig(rig),
        make_windows(list(logs), rig),
        None,
        logs,
        rig.counts_per_rev,
        DiagnosisSettings(fit_windows=24, start_windows=8, max_nfev=12, interval_resamples=50),
    )
    exact = _least_squares(task, {"actuator_lag": ""})[0]
    monkeypatch.setattr(fit, "same_branches", lambda model, other: False)
    differenced = _least_squares(task, {"actuator_lag": ""})[0]
    for name, effect in truth.items():
        np.testing.assert_allclose(exact[name].values, differenced[name].values, rtol=1e-3, atol=1e-5)
        np.testing.assert_allclose(exact[name].values, effect.values, rtol=0.05, atol=5e-3)


def test_the_tangents_raise_at_a_division_by_zero_as_the_kernel_and_diverge_alone():
    """Run without division checks, the tangents are those of the checked compilation: a singular mass matrix (a
    b = c^2, upright) raises ZeroDivisionError as the kernel does, and a window driven to overflow leaves the
    others' numbers as they are alone."""
    model = _model("dahl")
    x0, z0, torque = _problem(model)
    seeds = np.eye(5)
    rigid, arm, pendulum, terms = kernel.pack(model)
    singular = np.array([1.0, 1.0, 1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    with pytest.raises(ZeroDivisionError):
        tangent.tangents(np.zeros((4, 1)), np.zeros(1), torque[:, :1], DT, 1, (singular, arm, pendulum, terms), seeds)
    torque[:, 0] = 1e6
    angles, slopes = tangent.tangents(x0, z0, torque, DT, 1, kernel.pack(model), seeds)
    alone = tangent.tangents(x0[:, 1:], z0[1:], torque[:, 1:], DT, 1, kernel.pack(model), seeds)
    assert not np.isfinite(slopes[..., 0, :]).all()
    assert np.array_equal(angles[..., 1:], alone[0]) and np.array_equal(slopes[:, :, 1:], alone[1])
