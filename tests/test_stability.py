"""Stability of the nested loop: the presliding linearization against the separation principle, the conserved
bristle mode and the nonlinear simulation; stable frozen K_sigma ranges; the basin against the Lyapunov estimate."""

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.analysis import separation_error
from furuta_drake.config import ExcitationConfig
from furuta_drake.diagram import controller_gain
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.observers.hg import high_gain_error_matrix
from furuta_drake.observers.vfe import vfe_error_matrix, vfe_gains
from furuta_drake.paper import reproduce
from furuta_drake.paper.stability import (
    catches,
    common_lyapunov,
    interval_containing,
    linear_loop,
    lyapunov_region,
    presliding_plant,
    stable_intervals,
)
from furuta_drake.paper.studies.stability_study import adaptive_loop_config
from furuta_drake.plant import make_furuta_plant
from furuta_drake.rig import linearized_upright
from furuta_drake.simulate import simulate

BASE = reproduce.paper_rig_config()
REVERSED = linear_loop(BASE, "vfe", discrete=True, injection_sign=-1)


def _without_arm_friction(config):
    return dataclasses.replace(config, friction=dataclasses.replace(config.friction, arm=JointFrictionParameters()))


def test_presliding_friction_is_a_spring_of_stiffness_sigma0_on_the_bristle():
    plant = presliding_plant(BASE)
    A, B_F = linearized_upright(BASE.rig)
    sigma0 = BASE.friction.arm.sigma0
    np.testing.assert_allclose(plant.A[:4, :4], A, atol=1e-3)
    np.testing.assert_allclose(plant.A[:4, 4], -sigma0 * B_F[:, 1], rtol=1e-3)  # F_phi = -sigma0 z
    np.testing.assert_allclose(plant.A[4], [0, 0, 0, 1, 0], atol=1e-12)  # z' = phi_dot at rest
    np.testing.assert_allclose(plant.conserved @ plant.A, 0.0, atol=1e-9)  # z - phi is conserved


@pytest.mark.parametrize("observer", ["vfe", "hg"])
def test_without_friction_and_k_sigma_zero_the_separation_principle_holds(observer):
    # No bristle and F_hat = 0: the loop is plant + observer + LQR, eig(A - B K) with the observer's error
    # eigenvalues (eig(G), Eq. 12, or eig(A - H C), Eq. 4), plus z_hat's integrator, which nothing reads.
    config = _without_arm_friction(BASE)
    loop = linear_loop(config, observer)
    A, B_F = linearized_upright(config.rig)
    K = controller_gain(make_furuta_plant(config.rig), config)
    if observer == "vfe":
        error = np.linalg.eigvals(vfe_error_matrix(A, B_F, vfe_gains(A, B_F, config.observers.vfe.eigenvalues)))
    else:
        error = np.linalg.eigvals(high_gain_error_matrix(A, config.observers.hg))
    closed = loop.eigenvalues(0.0)
    expected = np.concatenate([error, [0.0]])
    assert separation_error(closed, np.linalg.eigvals(A - B_F[:, [1]] @ K), expected) < 1e-6 * np.max(np.abs(closed))


@pytest.mark.parametrize("discrete", [False, True])
def test_the_conserved_bristle_mode_is_the_only_eigenvalue_removed(discrete):
    loop = linear_loop(BASE, "vfe", discrete=discrete)
    M = loop.matrix(1.3)
    marginal = 1.0 if discrete else 0.0
    np.testing.assert_allclose(loop.conserved @ M, marginal * loop.conserved, atol=1e-9)
    full = np.linalg.eigvals(M)
    assert separation_error(full, loop.eigenvalues(1.3), np.array([marginal])) < 1e-6


def test_the_1khz_linear_loop_predicts_the_nonlinear_simulation_at_small_amplitude():
    # 1e-6 rad keeps the bristle far inside presliding (sigma0 |z| << Fc); fine encoders, no pendulum Coulomb.
    theta0 = 1e-6
    config = dataclasses.replace(
        BASE,
        duration=0.3,
        excitation=ExcitationConfig(),
        initial_state=[theta0, 0.0, 0.0, 0.0],
        encoder=dataclasses.replace(BASE.encoder, counts_per_rev=2**40),
        friction=dataclasses.replace(BASE.friction, pendulum=JointFrictionParameters()),
        observers=dataclasses.replace(BASE.observers, run=[]),
    )
    result = simulate(config)
    loop = linear_loop(config, "vfe", discrete=True)
    from pydrake.systems.analysis import DiscreteTimeApproximation

    from furuta_drake.observers.vfe import continuous_vfe_observer

    A, B_F = linearized_upright(config.rig)
    Bd = DiscreteTimeApproximation(continuous_vfe_observer(A, B_F, config.observers.vfe), 1e-3).B()
    state = np.zeros(loop.A0.shape[0])
    state[0] = theta0
    state[loop.slices["observer"]] = Bd[:, 0] * theta0  # the first update reads the initial sample
    M = loop.matrix(1.0)
    predicted = []
    for _ in result.time:
        predicted.append(state[:4])
        state = M @ state
    predicted = np.array(predicted)
    assert np.max(np.abs(result.state - predicted)) < 1e-2 * np.max(np.abs(predicted), axis=0).max()


def test_printed_injection_leaves_no_stable_k_sigma_and_reversed_contains_the_adapted_values():
    assert stable_intervals(linear_loop(BASE, "vfe", discrete=True)) == []
    assert stable_intervals(linear_loop(BASE, "hg", discrete=True)) == []
    interval = interval_containing(stable_intervals(REVERSED), 1.0)
    assert interval is not None
    low, high = interval
    assert low < 1.0 and high > 2.0  # K_sigma = 1 and the adapted 1.33-2.0 (Figs. 6-7)
    assert REVERSED.decay_rate(0.5 * low) > 0 and REVERSED.decay_rate(1.2 * high) > 0


CONTINUOUS = linear_loop(BASE, "vfe", injection_sign=-1)
P_CERTIFIED = common_lyapunov(CONTINUOUS, 1.0, 1.7)


@settings(max_examples=25, deadline=None)
@given(k_sigma=st.floats(1.0, 1.7))
def test_the_common_lyapunov_function_decreases_for_every_k_sigma_of_its_interval(k_sigma):
    assert P_CERTIFIED is not None
    A = CONTINUOUS.reduced(k_sigma)
    assert np.max(np.linalg.eigvalsh(A.T @ P_CERTIFIED + P_CERTIFIED @ A)) < 0


def _adaptive(config):
    return dataclasses.replace(adaptive_loop_config(config), duration=1.0, excitation=ExcitationConfig())


@pytest.mark.parametrize("theta0", [-0.05, 0.05])
def test_the_nested_adaptive_loop_catches_the_papers_start_states(theta0):
    assert catches(dataclasses.replace(_adaptive(BASE), initial_state=[theta0, 0.0, 0.0, 0.0]))


REGION = lyapunov_region(BASE, directions=300)


def test_every_sampled_state_inside_the_lyapunov_estimate_is_caught_by_the_true_state_loop():
    # The estimate is of the true-state LQR loop with the torque limit: random states near its boundary on the
    # (theta, theta_dot) slice, simulated with the encoder angles and the true velocities (and the Dahl friction).
    S = REGION.P[np.ix_([0, 2], [0, 2])]
    L = np.linalg.cholesky(S)
    true_state = dataclasses.replace(
        _adaptive(BASE),
        duration=2.0,
        controller=dataclasses.replace(BASE.controller, velocity_source="true", friction_compensation=False),
    )
    for angle in np.random.default_rng(1).uniform(0, 2 * np.pi, 3):
        point = np.linalg.solve(L.T, 0.95 * np.sqrt(REGION.level) * np.array([np.cos(angle), np.sin(angle)]))
        state = np.array([point[0], 0.0, point[1], 0.0])
        assert REGION.contains(state)[0]
        assert catches(dataclasses.replace(true_state, initial_state=state.tolist()))


def test_the_nested_adaptive_loop_catches_every_start_at_rest_inside_the_estimate():
    # At rest the observers' zero initial velocity estimate is right; the paper's starts (0.05 rad) lie inside.
    assert REGION.theta_extent() >= 0.05
    for theta0 in (-0.95 * REGION.theta_extent(), 0.95 * REGION.theta_extent()):
        assert catches(dataclasses.replace(_adaptive(BASE), duration=2.0, initial_state=[theta0, 0.0, 0.0, 0.0]))
