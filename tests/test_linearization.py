"""The observers' model at either equilibrium: Drake's Linearize of the plant against the closed forms of Eq. 1-2."""

import math

import numpy as np
import pytest

from furuta_drake.data import QUBE_REAL_RIG
from furuta_drake.linearization import equilibrium_angle, observer_model, plant_linearization
from furuta_drake.rig import RIGS, linearized_hanging, linearized_upright
from furuta_drake.rig_file import load_rig


@pytest.fixture(scope="module")
def qube():
    return load_rig(QUBE_REAL_RIG)


@pytest.mark.parametrize("name", ["lund", "qube_servo2"])
def test_drake_hanging_linearization_is_the_closed_form(name):
    """At theta = pi the coupling and the gravity stiffness change sign: A and both columns of B_F agree."""
    A, B_F = plant_linearization(RIGS[name](), "hanging")
    A_closed, B_closed = linearized_hanging(RIGS[name]())
    np.testing.assert_allclose(A, A_closed, rtol=1e-8, atol=1e-9)
    np.testing.assert_allclose(B_F, B_closed, rtol=1e-8, atol=1e-9)
    assert A[2, 0] < 0 < B_F[2, 1]  # hanging: gravity restores, an arm torque swings the pendulum towards +theta


def test_drake_upright_linearization_is_the_closed_form(qube):
    A, B_F = plant_linearization(qube, "upright")
    A_closed, B_closed = linearized_upright(qube)
    np.testing.assert_allclose(A, A_closed, rtol=1e-8, atol=1e-9)
    np.testing.assert_allclose(B_F, B_closed, rtol=1e-8, atol=1e-9)


def test_hanging_pendulum_oscillates_at_the_compound_frequency_and_the_back_emf_damps_it(qube):
    """Arm free, no motor: undamped oscillation at sqrt(a d / (a b - c^2)); with the motor's back-EMF the
    phi_dot column loses kt ke / R times the arm-torque column, and every mode but the arm's angle decays."""
    A, B_F = observer_model(qube, "hanging", back_emf_damping=0.0)
    a, b, c, d = qube.arm_inertia_total, qube.pendulum_inertia_total, qube.coupling, qube.gravity_torque
    eigenvalues = np.linalg.eigvals(A)
    assert np.max(np.abs(eigenvalues.imag)) == pytest.approx(math.sqrt(a * d / (a * b - c**2)), rel=1e-9)
    assert np.max(np.abs(eigenvalues.real)) < 1e-9
    A_motor, B_motor = observer_model(qube, "hanging")
    damping = qube.motor.torque_constant * qube.motor.backemf_constant / qube.motor.resistance
    np.testing.assert_allclose(A_motor[:, 3], A[:, 3] - damping * B_F[:, 1], rtol=1e-12)
    np.testing.assert_array_equal(B_motor, B_F)
    real_parts = np.sort(np.linalg.eigvals(A_motor).real)
    assert real_parts[-1] == pytest.approx(0.0, abs=1e-9) and np.all(real_parts[:-1] < 0)


def test_equilibrium_angle_counts_turns():
    assert equilibrium_angle(-3.1, "hanging") == pytest.approx(-math.pi)
    assert equilibrium_angle(3.2, "hanging") == pytest.approx(math.pi)
    assert equilibrium_angle(6.2, "upright") == pytest.approx(2 * math.pi)
    assert equilibrium_angle(0.1, "upright") == 0.0
