"""The MultibodyPlant models against the Lund rig's numbers (docs/paper.md) and public QUBE-Servo 2 data."""

import numpy as np
import pytest
from pydrake.systems.primitives import Linearize

from furuta_drake.errors import ConfigError
from furuta_drake.plant import MODEL_FILES, MODELS_DIR, furuta_urdf, joint_indices, make_furuta_plant
from furuta_drake.rig import RIGS, linearized_hanging, linearized_upright, lund_rig, qube_servo2_rig

# docs/paper.md: linearization of the Lund rig at the upright, x = [theta, phi, theta_dot, phi_dot].
ALPHA1, ALPHA2 = 47.949, -35.640
BETA3, BETA4, BETA5 = 491.16, -365.07, 570.10
UNSTABLE_POLE = 6.925


def drake_linearization(rig, theta0=0.0):
    """Linearize the parsed plant at rest at theta = ``theta0`` (the upright by default); return A and the
    [pendulum, arm] torque columns in paper order."""
    plant = make_furuta_plant(rig)
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, np.where(np.arange(2) == joint_indices(plant)[0], theta0, 0.0))
    plant.get_actuation_input_port().FixValue(context, [0.0])
    plant.get_applied_generalized_force_input_port().FixValue(context, np.zeros(2))
    theta, phi = joint_indices(plant)
    order = [theta, phi, 2 + theta, 2 + phi]
    arm_lin = Linearize(
        plant, context, plant.get_actuation_input_port().get_index(), plant.get_state_output_port().get_index()
    )
    A = arm_lin.A()[np.ix_(order, order)]
    B_arm = arm_lin.B()[order, 0]
    force_lin = Linearize(
        plant,
        context,
        plant.get_applied_generalized_force_input_port().get_index(),
        plant.get_state_output_port().get_index(),
    )
    B_pendulum = force_lin.B()[order, theta]
    return A, B_pendulum, B_arm


def test_lund_linearization_matches_the_paper_constants_within_half_a_percent():
    A, B_pendulum, B_arm = drake_linearization("lund")
    assert A[2, 0] == pytest.approx(ALPHA1, rel=5e-3)
    assert A[3, 0] == pytest.approx(ALPHA2, rel=5e-3)
    assert B_pendulum[2] == pytest.approx(BETA3, rel=5e-3)
    assert B_pendulum[3] == pytest.approx(BETA4, rel=5e-3)
    assert B_arm[2] == pytest.approx(BETA4, rel=5e-3)
    assert B_arm[3] == pytest.approx(BETA5, rel=5e-3)
    np.testing.assert_allclose(A[:2], [[0, 0, 1, 0], [0, 0, 0, 1]], atol=1e-12)
    np.testing.assert_allclose(A[2:, 1:], 0.0, atol=1e-9)
    poles = np.sort(np.linalg.eigvals(A).real)
    np.testing.assert_allclose(poles, [-UNSTABLE_POLE, 0, 0, UNSTABLE_POLE], atol=5e-3)


@pytest.mark.parametrize("name", ["lund", "qube_servo2"])
def test_closed_form_linearization_agrees_with_drake(name):
    A_drake, B_pendulum, B_arm = drake_linearization(name)
    A, B_F = linearized_upright(RIGS[name]())
    np.testing.assert_allclose(A, A_drake, rtol=1e-4, atol=1e-9)
    np.testing.assert_allclose(B_F[:, 0], B_pendulum, rtol=1e-4)
    np.testing.assert_allclose(B_F[:, 1], B_arm, rtol=1e-4)


def test_lumped_constants_of_the_lund_rig():
    rig = lund_rig()
    assert rig.arm_inertia_total == pytest.approx(0.0033472, rel=1e-4)
    assert rig.pendulum_inertia_total == pytest.approx(0.0038852, rel=1e-4)
    assert rig.coupling == pytest.approx(0.0024879, rel=1e-4)
    assert rig.gravity_torque == pytest.approx(0.097625, rel=1e-4)


@pytest.mark.parametrize("name", ["lund", "qube_servo2"])
def test_closed_form_hanging_linearization_agrees_with_drake(name):
    A_drake, B_pendulum, B_arm = drake_linearization(name, theta0=np.pi)
    A, B_F = linearized_hanging(RIGS[name]())
    np.testing.assert_allclose(A, A_drake, rtol=1e-4, atol=1e-9)
    np.testing.assert_allclose(B_F[:, 0], B_pendulum, rtol=1e-4, atol=1e-9)
    np.testing.assert_allclose(B_F[:, 1], B_arm, rtol=1e-4, atol=1e-9)


def test_hanging_pendulum_frequency_of_the_qube_matches_a_compound_pendulum():
    """Hanging, arm free: small oscillations at sqrt(m g l / (J_p + m l^2 - (m l r)^2 / Ja_total))."""
    rig = qube_servo2_rig()
    A_hanging, _ = linearized_hanging(rig)
    omega = np.max(np.abs(np.linalg.eigvals(A_hanging).imag))
    Jp, Ja, c, mgl = rig.pendulum_inertia_total, rig.arm_inertia_total, rig.coupling, rig.gravity_torque
    assert omega == pytest.approx(np.sqrt(mgl / (Jp - c**2 / Ja)), rel=1e-9)


def test_positive_arm_torque_swings_hanging_pendulum_towards_positive_theta():
    """The sign convention of the logs: hanging, accelerating the arm towards +phi swings the pendulum to +theta."""
    from pydrake.systems.analysis import Simulator

    plant = make_furuta_plant("qube_servo2")
    context = plant.CreateDefaultContext()
    theta, phi = joint_indices(plant)
    q = np.zeros(2)
    q[theta] = np.pi
    plant.SetPositions(context, q)
    plant.get_actuation_input_port().FixValue(context, [0.01])
    plant.get_applied_generalized_force_input_port().FixValue(context, np.zeros(2))
    simulator = Simulator(plant, context)
    simulator.AdvanceTo(0.05)
    q = plant.GetPositions(context)
    assert q[phi] > 0
    assert q[theta] > np.pi


@pytest.mark.parametrize("name", sorted(MODEL_FILES))
def test_shipped_model_files_are_the_generated_urdf(name):
    text = (MODELS_DIR / MODEL_FILES[name]).read_text()
    assert text == furuta_urdf(RIGS[name](), name=f"furuta_{name}")


def test_parsed_model_has_no_inertia_warnings_and_named_joints(capfd):
    plant = make_furuta_plant("lund")
    assert {plant.get_joint(i).name() for i in plant.GetJointIndices()} >= {"arm", "pendulum"}
    assert plant.num_actuators() == 1
    assert "inertia" not in capfd.readouterr().err.lower()


def test_non_physical_rig_is_rejected_with_the_field_named():
    with pytest.raises(ConfigError, match="pendulum_mass"):
        furuta_urdf(lund_rig().replace(pendulum_mass=-0.1))
    with pytest.raises(ConfigError, match="counts_per_rev"):
        lund_rig().replace(counts_per_rev=0).validate()
