"""VFE observer (paper Eq. 11-15): eps_hat_F converges to the friction error F - F_hat on the linear plant with
friction, the velocity estimate to the truth, G has the placed eigenvalues, parameter checks."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import (
    Adder,
    ConstantVectorSource,
    LinearSystem,
    LogVectorOutput,
    MatrixGain,
    Multiplexer,
    Sine,
)
from scipy.linalg import expm
from scipy.signal import place_poles

from furuta_drake.errors import ConfigError
from furuta_drake.observers.vfe import VfeObserver, VfeParameters, vfe_error_matrix, vfe_gains
from furuta_drake.rig import linearized_upright, lund_rig

A, B_F = linearized_upright(lund_rig())
B = B_F[:, [1]]
C = np.hstack([np.eye(2), np.zeros((2, 2))])
PERIOD = 1e-3


def observe_plant_with_friction(friction, friction_estimate: float, excitation: float, duration: float = 3.0):
    """Eq. 10: the linear plant with a constant friction torque F = [F_theta, F_phi] [N m], under a stabilising
    state feedback u = -K x (poles -4..-7 rad/s) plus a 1 Hz arm torque of amplitude ``excitation`` [N m],
    from theta = 0.05, phi = 0.1 rad. The VFE observer gets the exact angles, u and F_hat_phi =
    ``friction_estimate``. Returns time, x, x_hat, eps_hat_F sampled at the period."""
    K = place_poles(A, B, [-4.0, -5.0, -6.0, -7.0]).gain_matrix
    builder = DiagramBuilder()
    plant = builder.AddSystem(LinearSystem(A - B @ K, np.hstack([B, B_F]), np.eye(4), np.zeros((4, 3))))
    excite = builder.AddSystem(Sine(excitation, 2 * np.pi, 0.0, 1))
    true_friction = builder.AddSystem(ConstantVectorSource(np.asarray(friction, dtype=float)))
    plant_input = builder.AddSystem(Multiplexer([1, 2]))
    control = builder.AddSystem(MatrixGain(-K))
    torque = builder.AddSystem(Adder(2, 1))
    measure = builder.AddSystem(MatrixGain(C))
    estimate = builder.AddSystem(ConstantVectorSource([friction_estimate]))
    vfe = builder.AddSystem(VfeObserver((A, B_F), period=PERIOD))
    builder.Connect(excite.get_output_port(0), plant_input.get_input_port(0))
    builder.Connect(true_friction.get_output_port(), plant_input.get_input_port(1))
    builder.Connect(plant_input.get_output_port(), plant.get_input_port())
    builder.Connect(plant.get_output_port(), control.get_input_port())
    builder.Connect(control.get_output_port(), torque.get_input_port(0))
    builder.Connect(excite.get_output_port(0), torque.get_input_port(1))
    builder.Connect(plant.get_output_port(), measure.get_input_port())
    builder.Connect(measure.get_output_port(), vfe.GetInputPort("measured_angles_rad"))
    builder.Connect(torque.get_output_port(), vfe.GetInputPort("arm_torque_Nm"))
    builder.Connect(estimate.get_output_port(), vfe.GetInputPort("friction_estimate_Nm"))
    logs = [
        LogVectorOutput(port, builder, PERIOD)
        for port in (
            plant.get_output_port(),
            vfe.GetOutputPort("state_estimate"),
            vfe.GetOutputPort("friction_error_estimate_Nm"),
        )
    ]
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    plant.GetMyMutableContextFromRoot(context).SetContinuousState([0.05, 0.1, 0.0, 0.0])
    Simulator(diagram, context).AdvanceTo(duration)
    x, x_hat, eps_hat = (log.FindLog(context).data().T for log in logs)
    return logs[0].FindLog(context).sample_times(), x, x_hat, eps_hat


@settings(max_examples=10, deadline=None)
@given(
    pendulum=st.floats(-0.002, 0.002),
    arm=st.floats(-0.02, 0.02),
    offset=st.floats(-0.01, 0.01),
    excitation=st.sampled_from([0.0, 0.02]),
)
def test_eps_hat_f_converges_to_the_friction_error(pendulum, arm, offset, excitation):
    """Eq. 14-15: with F - F_hat constant, [x - x_hat; (F - F_hat) - eps_hat_F] obeys G (slowest eigenvalue
    -20 1/s), so after 2 s (e^-40) eps_hat_F = F - F_hat = [F_theta, -offset] when F_hat_phi = F_phi + offset.
    Tolerance 2e-5 N m: the sampled observer's O(h) lag on the moving plant (0.02 N m of excitation)."""
    t, x, x_hat, eps_hat = observe_plant_with_friction([pendulum, arm], arm + offset, excitation)
    settled = t >= 2.0
    np.testing.assert_allclose(eps_hat[settled], np.tile([pendulum, -offset], (settled.sum(), 1)), atol=2e-5)


@pytest.mark.parametrize("offset", [0.0, 0.005])
def test_velocity_estimate_converges_to_the_truth_whatever_the_friction_estimate(offset):
    """F_hat = F, or F_hat off by 0.005 N m (absorbed by eps_hat_F): on an excited plant (arm speed ~0.7 rad/s
    RMS) the velocity estimates match the truth to 1 % RMS (the O(h) lag of sampling, h = 1 ms against a
    1 Hz motion) and eps_hat_F (arm) = F - F_hat."""
    t, x, x_hat, eps_hat = observe_plant_with_friction([0.0, -0.012], -0.012 + offset, excitation=0.02)
    settled = t >= 2.0
    np.testing.assert_allclose(eps_hat[settled, 1], -offset, atol=1e-5)
    velocity_rms = np.sqrt(np.mean(x[settled, 2:] ** 2, axis=0))
    error_rms = np.sqrt(np.mean((x[settled, 2:] - x_hat[settled, 2:]) ** 2, axis=0))
    assert np.all(velocity_rms > 0.2)
    assert np.all(error_rms < 0.01 * velocity_rms)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.integers(2, 80), min_size=6, max_size=6, unique=True))
def test_gains_place_the_eigenvalues_of_g(rates):
    """Eq. 12-13: G = A_F - K_F C_F with A_F = [[A, B_F], [0, 0]], C_F = [I 0 0], built here from the paper's
    block structure, has the requested eigenvalues."""
    eigenvalues = [-float(rate) for rate in rates]
    K_F = vfe_gains(A, B_F, eigenvalues)
    A_F = np.block([[A, B_F], [np.zeros((2, 6))]])
    C_F = np.hstack([np.eye(2), np.zeros((2, 4))])
    G = A_F - K_F @ C_F
    np.testing.assert_allclose(vfe_error_matrix(A, B_F, K_F), G, atol=1e-9)
    np.testing.assert_allclose(np.sort(np.linalg.eigvals(G).real), np.sort(eigenvalues), rtol=1e-5)
    np.testing.assert_allclose(np.linalg.eigvals(G).imag, 0.0, atol=1e-6 * max(map(abs, eigenvalues)))


def test_discretisation_is_the_exact_zero_order_hold_and_ports_are_named():
    """x_k+1 = e^(G h) x_k + int_0^h e^(G s) ds [K_F, b, b] [y; u; F_hat_phi], b = [B; 0] the arm column."""
    vfe = VfeObserver(lund_rig(), period=PERIOD)
    K_F = vfe.gains
    arm = np.concatenate([B[:, 0], np.zeros(2)])[:, None]
    augmented = np.zeros((10, 10))
    augmented[:6, :6] = np.block([[A, B_F], [np.zeros((2, 6))]]) - K_F @ np.hstack([C, np.zeros((2, 2))])
    augmented[:6, 6:] = np.hstack([K_F, arm, arm])
    exact = expm(augmented * PERIOD)
    np.testing.assert_allclose(vfe.discrete.A(), exact[:6, :6], atol=1e-12)
    np.testing.assert_allclose(vfe.discrete.B(), exact[:6, 6:], rtol=1e-9, atol=1e-12)
    assert [vfe.get_input_port(i).get_name() for i in range(3)] == [
        "measured_angles_rad",
        "arm_torque_Nm",
        "friction_estimate_Nm",
    ]
    assert [vfe.get_output_port(i).get_name() for i in range(2)] == ["state_estimate", "friction_error_estimate_Nm"]


@pytest.mark.parametrize(
    "eigenvalues, field",
    [
        ([-20.0, -23.0, -26.0, -29.0, -32.0, 0.0], r"eigenvalues\[5\]"),
        ([-20.0, 1.0, -26.0, -29.0, -32.0, -35.0], r"eigenvalues\[1\]"),
        ([-20.0, -23.0, -26.0, -29.0, float("nan"), -35.0], r"eigenvalues\[4\]"),
        ([-20.0, -23.0, -26.0, -29.0, -32.0], r"eigenvalues"),
        ([-20.0, -20.0, -20.0, -29.0, -32.0, -35.0], r"eigenvalues"),
    ],
)
def test_invalid_eigenvalues_are_rejected_naming_the_field(eigenvalues, field):
    with pytest.raises(ConfigError, match=rf"observers\.vfe\.{field}"):
        VfeObserver(lund_rig(), VfeParameters(eigenvalues=eigenvalues), period=PERIOD)


def test_a_stated_period_must_be_positive_and_the_control_period():
    with pytest.raises(ConfigError, match=r"observers\.vfe\.period must be > 0"):
        VfeObserver(lund_rig(), VfeParameters(period=0.0), period=PERIOD)
    with pytest.raises(ConfigError, match=r"observers\.vfe\.period = 0.001 differs from the control period = 0.002"):
        VfeObserver(lund_rig(), VfeParameters(period=1e-3), period=2e-3)
