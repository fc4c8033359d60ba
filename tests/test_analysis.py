"""Linear analysis with Drake's tools: observability with angle-only measurements, controllability, and the
separation principle checked on the linearized closed-loop diagram (plant + observer + LQR)."""

import numpy as np
import pytest
from scipy.linalg import solve_continuous_are

from furuta_drake.analysis import (
    controllability,
    observability,
    observer_for_analysis,
    observer_loop_eigenvalues,
    separation_error,
)
from furuta_drake.observers.hg import HighGainParameters
from furuta_drake.observers.linear import ANGLES
from furuta_drake.observers.vfe import VfeParameters
from furuta_drake.rig import RIGS, linearized_upright


@pytest.mark.parametrize("name", sorted(RIGS))
def test_angles_make_the_upright_observable_and_the_arm_torque_controllable(name):
    A, B_F = linearized_upright(RIGS[name]())
    assert observability(A, ANGLES)["observable"]
    assert controllability(A, B_F[:, [1]])["controllable"]
    # Measuring the arm angle alone still observes everything (the coupling carries theta into phi) ...
    assert observability(A, ANGLES[[1]])["observable"]
    # ... but the pendulum angle alone cannot see the arm angle (phi enters no equation: a pure integrator).
    assert not observability(A, ANGLES[[0]])["observable"]


@pytest.mark.parametrize("kind, params", [("hg", HighGainParameters()), ("vfe", VfeParameters())])
def test_closed_loop_eigenvalues_are_controller_and_observer_eigenvalues(kind, params):
    rig = RIGS["lund"]()
    A, B_F = linearized_upright(rig)
    B = B_F[:, [1]]
    K = np.linalg.solve([[10.0]], B.T @ solve_continuous_are(A, B, np.diag([10.0, 10.0, 0.1, 0.1]), [[10.0]]))
    observer, observer_eigenvalues = observer_for_analysis(kind, A, B_F, params)
    closed = observer_loop_eigenvalues(rig, K, observer)
    assert closed.size == 4 + observer_eigenvalues.size
    assert separation_error(closed, np.linalg.eigvals(A - B @ K), observer_eigenvalues) < 1e-6 * np.max(np.abs(closed))
    assert np.all(closed.real < 0)


def test_designed_hg_and_vfe_eigenvalues_are_where_they_were_placed():
    A, B_F = linearized_upright(RIGS["lund"]())
    _, hg = observer_for_analysis("hg", A, B_F, HighGainParameters(eps_theta=0.005, eps_phi=0.005))
    # Double pole at -1/eps per joint, split by the gravity coupling alpha1 (about +-sqrt(alpha1) * ...).
    assert np.all(np.abs(np.sort(hg.real) + 200.0) < 10.0)
    _, vfe = observer_for_analysis("vfe", A, B_F, VfeParameters())
    np.testing.assert_allclose(np.sort(vfe.real), np.sort(VfeParameters().eigenvalues), rtol=1e-6)
