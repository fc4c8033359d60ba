"""High-gain observer (paper Eq. 4-6): designed error rate, noise gain against the closed-form formula, exact
zero-order-hold discretisation, parameter checks."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydrake.common import RandomDistribution
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import (
    ConstantVectorSource,
    Gain,
    LinearSystem,
    LogVectorOutput,
    MatrixGain,
    RandomSource,
)
from scipy.linalg import expm
from scipy.signal import place_poles

from furuta_drake.errors import ConfigError
from furuta_drake.observers.hg import (
    HighGainObserver,
    HighGainParameters,
    high_gain_eigenvalues,
    high_gain_error_matrix,
    high_gain_matrix,
)
from furuta_drake.rig import linearized_upright, lund_rig

A, B_F = linearized_upright(lund_rig())
B = B_F[:, [1]]
C = np.hstack([np.eye(2), np.zeros((2, 2))])
PERIOD = 1e-3
QUANTUM = 2 * np.pi / 4096  # one count of the Lund rig's encoders [rad]


def observe_closed_loop(params: HighGainParameters, x0, x_hat0, duration: float):
    """The linear plant (Eq. 1) under a stabilising state feedback u = -K x (poles -4..-7 rad/s) from x0, its
    exact angles and torque fed to the HG observer started at x_hat0. Returns time, x, x_hat at the period."""
    K = place_poles(A, B, [-4.0, -5.0, -6.0, -7.0]).gain_matrix
    builder = DiagramBuilder()
    plant = builder.AddSystem(LinearSystem(A - B @ K, np.zeros((4, 1)), np.eye(4), np.zeros((4, 1))))
    zero = builder.AddSystem(ConstantVectorSource([0.0]))
    measure = builder.AddSystem(MatrixGain(C))
    control = builder.AddSystem(MatrixGain(-K))
    hg = builder.AddSystem(HighGainObserver((A, B_F), params, period=PERIOD))
    builder.Connect(zero.get_output_port(), plant.get_input_port())
    builder.Connect(plant.get_output_port(), measure.get_input_port())
    builder.Connect(plant.get_output_port(), control.get_input_port())
    builder.Connect(measure.get_output_port(), hg.GetInputPort("measured_angles_rad"))
    builder.Connect(control.get_output_port(), hg.GetInputPort("arm_torque_Nm"))
    state_log = LogVectorOutput(plant.get_output_port(), builder, PERIOD)
    estimate_log = LogVectorOutput(hg.GetOutputPort("state_estimate"), builder, PERIOD)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    plant.GetMyMutableContextFromRoot(context).SetContinuousState(x0)
    hg.discrete.GetMyMutableContextFromRoot(context).SetDiscreteState(x_hat0)
    Simulator(diagram, context).AdvanceTo(duration)
    return (
        state_log.FindLog(context).sample_times(),
        state_log.FindLog(context).data().T,
        estimate_log.FindLog(context).data().T,
    )


@settings(max_examples=10, deadline=None)
@given(eps=st.floats(0.005, 0.03))
def test_estimation_error_decays_at_the_designed_rate(eps):
    """a1 = 3, a2 = 2: per joint the error poles are the roots of s^2 + 3/eps s + 2/eps^2, -1/eps and -2/eps, so
    the error norm decays as exp(-t/eps) once the -2/eps modes have died (the model's coupling moves the
    poles by under 1 %). Fit over the decay from 1/10 to 1/1000 of its peak; the plant moves ten times less
    than the initial error, so the sampled observer's O(h) lag on a moving plant stays below that window."""
    params = HighGainParameters(a1=3.0, a2=2.0, eps_theta=eps, eps_phi=eps)
    t, x, x_hat = observe_closed_loop(params, [0.005, 0.01, 0.0, 0.0], [0.05, 0.1, 0.0, 0.0], duration=12 * eps)
    error = np.linalg.norm(x - x_hat, axis=1)
    peak = np.argmax(error)
    window = (t > t[peak]) & (error < 0.1 * error[peak]) & (error > 1e-3 * error[peak])
    assert window.sum() >= 10
    slope = np.polyfit(t[window], np.log(error[window]), 1)[0]
    assert slope == pytest.approx(-1.0 / eps, rel=0.03)


def test_designed_eigenvalues_are_the_polynomial_roots_and_close_to_the_true_ones():
    """a1 = 2, a2 = 1: s^2 + 2/eps s + 1/eps^2 = (s + 1/eps)^2, a double pole at -1/eps per joint. The true
    poles of A - H C differ by the gravity coupling, of relative size alpha1 eps^2 ~ 1e-3 here."""
    params = HighGainParameters(a1=2.0, a2=1.0, eps_theta=0.005, eps_phi=0.01)
    np.testing.assert_allclose(np.sort(high_gain_eigenvalues(params).real), [-200, -200, -100, -100], rtol=1e-6)
    true = np.sort(np.linalg.eigvals(high_gain_error_matrix(A, params)).real)
    np.testing.assert_allclose(true, [-200, -200, -100, -100], rtol=0.05)
    assert np.all(true < 0)


def velocity_noise_std(eps: float, noise_std: float, duration: float = 20.0) -> np.ndarray:
    """Std of the velocity estimates [theta_dot, phi_dot] of an HG observer fed white Gaussian angle noise of
    std ``noise_std`` per sample (the plant at rest, u = 0)."""
    builder = DiagramBuilder()
    noise = builder.AddSystem(RandomSource(RandomDistribution.kGaussian, 2, PERIOD))
    scale = builder.AddSystem(Gain(noise_std, 2))
    zero = builder.AddSystem(ConstantVectorSource([0.0]))
    hg = builder.AddSystem(HighGainObserver((A, B_F), HighGainParameters(eps_theta=eps, eps_phi=eps), period=PERIOD))
    builder.Connect(noise.get_output_port(), scale.get_input_port())
    builder.Connect(scale.get_output_port(), hg.GetInputPort("measured_angles_rad"))
    builder.Connect(zero.get_output_port(), hg.GetInputPort("arm_torque_Nm"))
    log = LogVectorOutput(hg.GetOutputPort("state_estimate"), builder, PERIOD)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    Simulator(diagram, context).AdvanceTo(duration)
    velocities = log.FindLog(context).data()[2:, 1000:]  # after the start-up transient
    return velocities.std(axis=1)


def test_quantisation_noise_gain_matches_the_formula_and_grows_as_eps_shrinks():
    """White angle noise of variance s^2 per sample (PSD s^2 h) through the velocity channel
    l2 s / (s^2 + l1 s + l2), l1 = a1/eps, l2 = a2/eps^2, gives a variance s^2 h l2^2 / (2 l1), i.e. a std
    s sqrt(h a2^2 / (2 a1 eps^3)): it grows as eps^-1.5. s = q / sqrt(12), the quantisation noise of a count."""
    sigma = QUANTUM / math.sqrt(12)
    measured = {eps: velocity_noise_std(eps, sigma) for eps in (0.02, 0.01, 0.005)}
    for eps, std in measured.items():
        expected = sigma * math.sqrt(PERIOD * 1.0 / (2 * 2.0 * eps**3))
        np.testing.assert_allclose(std, expected, rtol=0.1)
    assert measured[0.02].max() < measured[0.01].min() and measured[0.01].max() < measured[0.005].min()


def test_discretisation_is_the_exact_zero_order_hold_of_eq_4():
    """x_hat_k+1 = e^(F h) x_hat_k + int_0^h e^(F s) ds G [y_k; u_k] with F = A - H C, G = [H, B]: the matrix
    exponential of the augmented matrix [[F, G], [0, 0]] (scipy), against Drake's discretisation."""
    params = HighGainParameters()
    hg = HighGainObserver(lund_rig(), params, period=PERIOD)
    H = high_gain_matrix(params)
    augmented = np.zeros((7, 7))
    augmented[:4, :4], augmented[:4, 4:] = A - H @ C, np.hstack([H, B])
    exact = expm(augmented * PERIOD)
    np.testing.assert_allclose(hg.discrete.A(), exact[:4, :4], atol=1e-12)
    np.testing.assert_allclose(hg.discrete.B(), exact[:4, 4:], rtol=1e-9, atol=1e-12)
    assert hg.discrete.time_period() == PERIOD
    assert [hg.get_input_port(i).get_name() for i in range(2)] == ["measured_angles_rad", "arm_torque_Nm"]
    assert hg.get_output_port(0).get_name() == "state_estimate"


@pytest.mark.parametrize(
    "field, value",
    [
        ("a1", 0.0),
        ("a2", -1.0),
        ("a1", float("nan")),
        ("eps_theta", 0.0),
        ("eps_phi", -0.01),
        ("period", 0.0),
    ],
)
def test_invalid_parameters_are_rejected_naming_the_field(field, value):
    params = HighGainParameters(**{field: value})
    with pytest.raises(ConfigError, match=rf"observers\.hg\.{field}"):
        HighGainObserver(lund_rig(), params, period=PERIOD)
