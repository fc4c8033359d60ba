"""LQ control at the upright: the linearization, the design, the sampled controller in a Drake closed loop."""

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder, InputPortSelection, OutputPortSelection
from pydrake.systems.primitives import Linearize, MatrixGain
from scipy.linalg import expm, solve_continuous_are, solve_discrete_are

from furuta_drake.controllers.lqr import (
    LqrController,
    LqrParameters,
    check_stabilizing,
    design_lqr,
    lqr_gain,
    state_feedback_eigenvalues,
    upright_linearization,
)
from furuta_drake.errors import ConfigError
from furuta_drake.plant import add_furuta_plant, make_furuta_plant, plant_to_paper_permutation

# The paper's linearization of the Lund rig at the upright (docs/paper.md), x = [theta, phi, theta_dot, phi_dot].
ALPHA1, ALPHA2, BETA4, BETA5 = 47.949, -35.640, -365.07, 570.10
PERIOD = 1e-3  # [s] the Lund rig's control period


@pytest.fixture(scope="module")
def lund_plant():
    return make_furuta_plant("lund")


def scipy_zoh(A, B, period):
    n, m = B.shape
    M = expm(np.block([[A, B], [np.zeros((m, n + m))]]) * period)
    return M[:n, :n], M[:n, n:]


def test_upright_linearization_is_the_papers_model_in_paper_order(lund_plant):
    A, B = upright_linearization(lund_plant)
    expected_A = np.zeros((4, 4))
    expected_A[0, 2] = expected_A[1, 3] = 1.0
    expected_A[2, 0], expected_A[3, 0] = ALPHA1, ALPHA2
    np.testing.assert_allclose(A, expected_A, rtol=5e-3, atol=1e-9)
    np.testing.assert_allclose(B.ravel(), [0, 0, BETA4, BETA5], rtol=5e-3, atol=1e-9)


def test_upright_linearization_of_a_plant_in_an_unbuilt_builder_with_scene_graph(lund_plant):
    plant, _ = add_furuta_plant(DiagramBuilder(), "lund", with_scene_graph=True)
    for got, expected in zip(upright_linearization(plant), upright_linearization(lund_plant)):
        np.testing.assert_allclose(got, expected, rtol=1e-12)


@pytest.mark.parametrize("discrete", [True, False])
def test_design_is_the_riccati_optimum_computed_by_scipy(lund_plant, discrete):
    params = LqrParameters(discrete=discrete)
    K = design_lqr(lund_plant, params, period=PERIOD)
    A, B = upright_linearization(lund_plant)
    Q, R = np.diag(params.state_weights), np.array([[params.input_weight]])
    if discrete:
        Ad, Bd = scipy_zoh(A, B, PERIOD)
        S = solve_discrete_are(Ad, Bd, Q, R)
        expected = np.linalg.solve(R + Bd.T @ S @ Bd, Bd.T @ S @ Ad)
    else:
        expected = np.linalg.solve(R, B.T @ solve_continuous_are(A, B, Q, R))
    np.testing.assert_allclose(K, expected, rtol=1e-6)
    assert K.shape == (1, 4)
    # Sign conventions: a pendulum leaning to +theta needs a negative arm torque (beta4 < 0).
    assert K[0, 0] < 0


def test_default_gains_start_within_the_torque_limit_from_a_tenth_of_a_radian(lund_plant):
    params = LqrParameters()
    K = design_lqr(lund_plant, params, period=PERIOD)
    assert abs(K[0, 0]) * 0.1 <= params.torque_limit


def closed_loop(plant_rig, K, period, torque_limit, accuracy=1e-4):
    """Continuous Lund plant fed by the discrete LqrController on the true paper-order state."""
    builder = DiagramBuilder()
    plant, _ = add_furuta_plant(builder, plant_rig, with_scene_graph=False)
    to_paper = builder.AddSystem(MatrixGain(plant_to_paper_permutation(plant)))
    controller = builder.AddSystem(LqrController(K, period=period, torque_limit=torque_limit))
    builder.Connect(plant.get_state_output_port(), to_paper.get_input_port())
    builder.Connect(to_paper.get_output_port(), controller.GetInputPort("state_estimate"))
    builder.Connect(controller.GetOutputPort("arm_torque_Nm"), plant.get_actuation_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    plant.get_applied_generalized_force_input_port().FixValue(plant_context, np.zeros(2))
    integrator = simulator.get_mutable_integrator()
    integrator.set_target_accuracy(accuracy)
    P = plant_to_paper_permutation(plant)

    def run(x0, duration):
        context.SetTime(0.0)
        diagram.SetDefaultContext(context)
        plant.get_applied_generalized_force_input_port().FixValue(plant_context, np.zeros(2))
        plant.SetPositionsAndVelocities(plant_context, P.T @ np.asarray(x0, dtype=float))
        simulator.Initialize()
        simulator.AdvanceTo(duration)
        return P @ plant.GetPositionsAndVelocities(plant_context)

    return run


def test_sampled_closed_loop_transition_has_the_designed_discrete_eigenvalues(lund_plant):
    """The one-period map x(t_0) -> x(t_1) of the Drake hybrid loop (continuous plant, command from the sample
    at t_0 held over the period) is Ad - Bd K with scipy's expm-based zero-order hold."""
    period = 5e-3
    K = design_lqr(lund_plant, LqrParameters(), period=period)
    run = closed_loop("lund", K, period, torque_limit=1.0, accuracy=1e-10)
    scale = 1e-4  # linear regime: the cubic terms are 1e-8 relative
    transition = np.column_stack([run(scale * e, period) / scale for e in np.eye(4)])
    A, B = upright_linearization(lund_plant)
    Ad, Bd = scipy_zoh(A, B, period)
    np.testing.assert_allclose(transition, Ad - Bd @ K, rtol=1e-5, atol=1e-8)
    designed = np.sort_complex(state_feedback_eigenvalues(A, B, K, True, period))
    np.testing.assert_allclose(np.sort_complex(np.linalg.eigvals(transition)), designed, atol=1e-6)
    assert np.all(np.abs(designed) < 1)


def test_continuous_closed_loop_eigenvalues_are_those_of_the_linearized_drake_loop(lund_plant):
    """Continuous variant of the loop: the plant with u = -K P x_plant wired in Drake, linearized as a whole."""
    A, B = upright_linearization(lund_plant)
    K = design_lqr(lund_plant, LqrParameters(discrete=False), period=PERIOD)
    builder = DiagramBuilder()
    plant, _ = add_furuta_plant(builder, "lund", with_scene_graph=False)
    feedback = builder.AddSystem(MatrixGain(-K @ plant_to_paper_permutation(plant)))
    builder.Connect(plant.get_state_output_port(), feedback.get_input_port())
    builder.Connect(feedback.get_output_port(), plant.get_actuation_input_port())
    builder.ExportInput(plant.get_applied_generalized_force_input_port())
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    diagram.get_input_port(0).FixValue(context, np.zeros(2))
    loop = Linearize(
        diagram, context, input_port_index=InputPortSelection.kNoInput, output_port_index=OutputPortSelection.kNoOutput
    )
    eigenvalues = state_feedback_eigenvalues(A, B, K, discrete=False, period=1e-3)
    np.testing.assert_allclose(np.sort_complex(eigenvalues), np.sort_complex(np.linalg.eigvals(loop.A())), rtol=1e-6)
    assert np.all(eigenvalues.real < 0)
    # The discrete eigenvalues of the same gain sampled fast tend to exp(lambda T).
    fine = state_feedback_eigenvalues(A, B, K, discrete=True, period=1e-5)
    np.testing.assert_allclose(np.sort_complex(np.log(fine) / 1e-5), np.sort_complex(eigenvalues), rtol=1e-2)


def test_lqr_balances_the_friction_free_lund_pendulum_from_a_tenth_of_a_radian(lund_plant):
    params = LqrParameters()
    run = closed_loop("lund", design_lqr(lund_plant, params, period=PERIOD), PERIOD, params.torque_limit)
    x = run([0.1, 0.0, 0.0, 0.0], 3.0)
    assert abs(x[0]) < 1e-3
    assert np.all(np.abs(x) < 1e-2)


def test_command_is_held_between_samples_and_has_no_feedthrough():
    controller = LqrController([[-2.0, 0, 0, 0]], period=1e-3, torque_limit=0.2)
    context = controller.CreateDefaultContext()
    port = controller.GetInputPort("state_estimate")
    port.FixValue(context, [0.01, 0, 0, 0])
    simulator = Simulator(controller, context)
    simulator.AdvanceTo(0.0015)
    port.FixValue(context, [0.05, 0, 0, 0])
    assert controller.GetOutputPort("arm_torque_Nm").Eval(context)[0] == pytest.approx(0.02)
    simulator.AdvanceTo(0.0025)
    assert controller.GetOutputPort("arm_torque_Nm").Eval(context)[0] == pytest.approx(0.1)
    assert not controller.HasAnyDirectFeedthrough()


def test_check_stabilizing_rejects_unstable_and_non_finite_gains(lund_plant):
    A, B = upright_linearization(lund_plant)
    with pytest.raises(ConfigError, match=r"controller.gain .*does not stabilise.*\|z\| = 1.00[0-9]* >= 1"):
        check_stabilizing(A, B, np.zeros((1, 4)), True, 1e-3, "controller.gain")
    with pytest.raises(ConfigError, match="controller.gain .*non-negative real part"):
        check_stabilizing(A, B, np.zeros((1, 4)), False, 1e-3, "controller.gain")
    with pytest.raises(ConfigError, match="controller.gain must be 4 finite numbers"):
        check_stabilizing(A, B, [[-2.0, math.nan, 0, 0]], True, 1e-3, "controller.gain")
    K = design_lqr(lund_plant, LqrParameters(discrete=False), period=PERIOD)
    check_stabilizing(A, B, K, False, 1e-3, "controller.gain")
    check_stabilizing(A, B, K, True, 1e-3, "controller.gain")
    # The same continuous gain sampled ten times too slowly no longer stabilises (fastest pole ~ -20 rad/s).
    with pytest.raises(ConfigError, match="0.2 s period"):
        check_stabilizing(A, B, K, True, 0.2, "controller.gain")


def test_lqr_gain_is_the_design_or_the_given_gain_checked_at_the_control_period(lund_plant):
    params = LqrParameters()
    np.testing.assert_array_equal(
        lqr_gain(lund_plant, params, period=2e-3), design_lqr(lund_plant, params, period=2e-3)
    )
    given = design_lqr(lund_plant, LqrParameters(discrete=False), period=PERIOD)
    np.testing.assert_array_equal(lqr_gain(lund_plant, params, period=PERIOD, gain=given.ravel().tolist()), given)
    with pytest.raises(ConfigError, match="controller.gain .*does not stabilise the upright at a 0.2 s period"):
        lqr_gain(lund_plant, params, period=0.2, gain=given.ravel().tolist())
    with pytest.raises(ConfigError, match=r"controller.lqr.period = 0.001 differs from the control period = 0.002"):
        design_lqr(lund_plant, LqrParameters(period=1e-3), period=2e-3)


@pytest.mark.parametrize(
    "changes, field",
    [
        ({"state_weights": [1.0, 1.0, 1.0]}, "state_weights"),
        ({"state_weights": [1, -1, 0, 0]}, "state_weights"),
        ({"input_weight": 0.0}, "input_weight"),
        ({"period": math.nan}, "period"),
        ({"torque_limit": -0.2}, "torque_limit"),
    ],
)
def test_invalid_lqr_parameters_are_rejected_with_the_field_named(lund_plant, changes, field):
    with pytest.raises(ConfigError, match=f"controller.lqr.{field}"):
        design_lqr(lund_plant, LqrParameters(**changes), period=PERIOD)


def test_weights_that_leave_the_arm_unregulated_are_rejected(lund_plant):
    for discrete in (True, False):
        with pytest.raises(ConfigError, match=r"controller.lqr.state_weights .* out of the cost"):
            design_lqr(lund_plant, LqrParameters(state_weights=[10.0, 0.0, 0.1, 0.0], discrete=discrete), period=PERIOD)


def controller_update(controller, estimate, friction=None, reference=None):
    """(arm_torque_Nm, lqr_torque_Nm) of an LqrController after its sample at t = 0."""
    context = controller.CreateDefaultContext()
    controller.GetInputPort("state_estimate").FixValue(context, estimate)
    if friction is not None:
        controller.GetInputPort("friction_compensation_Nm").FixValue(context, [friction])
    if reference is not None:
        controller.GetInputPort("state_reference").FixValue(context, reference)
    Simulator(controller, context).AdvanceTo(5e-4)
    return tuple(controller.GetOutputPort(name).Eval(context)[0] for name in ("arm_torque_Nm", "lqr_torque_Nm"))


def test_control_law_with_reference_friction_compensation_and_saturation():
    K = np.array([[-2.0, -0.5, -0.4, -0.2]])
    x = np.array([0.01, 0.1, 0.0, 0.2])
    u_lq = 0.02 + 0.05 + 0.04  # -K x
    plain = LqrController(K, period=1e-3, torque_limit=0.2)
    assert [plain.get_input_port(i).get_name() for i in range(plain.num_input_ports())] == ["state_estimate"]
    assert controller_update(plain, x) == pytest.approx((u_lq, u_lq))
    assert controller_update(plain, 10 * x) == pytest.approx((0.2, 10 * u_lq))
    assert controller_update(plain, -10 * x) == pytest.approx((-0.2, -10 * u_lq))
    # Paper Sec. IV-C: u = u_LQ - F_hat; F_hat = -0.012 N m (friction resisting a positive arm velocity).
    compensating = LqrController(K, period=1e-3, torque_limit=0.2, friction_compensation=True)
    assert controller_update(compensating, x, friction=-0.012) == pytest.approx((u_lq + 0.012, u_lq))
    tracking = LqrController(K, period=1e-3, torque_limit=0.2, reference=True)
    reference = np.array([0.0, 0.1, 0.0, 0.0])  # at the arm reference: only theta and phi_dot act
    assert controller_update(tracking, x, reference=reference) == pytest.approx((0.06, 0.06))
    both = LqrController(K, period=1e-3, torque_limit=0.2, friction_compensation=True, reference=True)
    assert controller_update(both, x, friction=-0.012, reference=reference) == pytest.approx((0.072, 0.06))
    assert not compensating.HasAnyDirectFeedthrough()
