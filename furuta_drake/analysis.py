"""Linear analysis with Drake's tools: observability and controllability of the linearized Furuta pendulum,
the observers' error dynamics, and the separation principle checked on a linearized closed-loop diagram.

The closed loop is analysed in continuous time, where the separation principle is exact: the MultibodyPlant
(linearized by Drake's ``Linearize`` at the upright), a continuous observer (HG, Eq. 4, or VFE, Eq. 11-13, as a
``LinearSystem``) fed by the angle measurements y = C x and the torque, and the LQR as a ``MatrixGain``. The
eigenvalues of the linearized diagram must equal eig(A - B K) together with the observer's error eigenvalues
(eig(A - H C) for HG, eig(G) of Eq. 12 for VFE, which has two extra friction-error states).
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import (
    ControllabilityMatrix,
    IsControllable,
    IsObservable,
    Linearize,
    LinearSystem,
    MatrixGain,
    Multiplexer,
    ObservabilityMatrix,
)

from furuta_drake.observers.linear import ANGLES
from furuta_drake.plant import add_furuta_plant, plant_to_paper_permutation
from furuta_drake.rig import RigParameters


def linear_plant(A: np.ndarray, B: np.ndarray, C: np.ndarray = ANGLES) -> LinearSystem:
    """The linearized plant as a Drake ``LinearSystem`` (x = [theta, phi, theta_dot, phi_dot], y = C x)."""
    B = np.asarray(B, dtype=float).reshape(4, -1)
    return LinearSystem(A, B, C, np.zeros((C.shape[0], B.shape[1])))


def observability(A: np.ndarray, C: np.ndarray = ANGLES) -> dict:
    """Drake's ``IsObservable`` and the rank and condition number of its ``ObservabilityMatrix``."""
    system = linear_plant(A, np.zeros((4, 1)), C)
    matrix = ObservabilityMatrix(system)
    return {
        "observable": bool(IsObservable(system)),
        "rank": int(np.linalg.matrix_rank(matrix)),
        "condition": float(np.linalg.cond(matrix)),
    }


def controllability(A: np.ndarray, B: np.ndarray) -> dict:
    """Drake's ``IsControllable`` and the rank and condition number of its ``ControllabilityMatrix``."""
    system = linear_plant(A, B)
    matrix = ControllabilityMatrix(system)
    return {
        "controllable": bool(IsControllable(system)),
        "rank": int(np.linalg.matrix_rank(matrix)),
        "condition": float(np.linalg.cond(matrix)),
    }


def observer_loop_eigenvalues(rig: RigParameters, K: np.ndarray, observer: LinearSystem) -> np.ndarray:
    """Eigenvalues of the continuous closed loop plant + observer + LQR, from ``Linearize`` of the diagram.

    ``observer`` is a continuous ``LinearSystem`` with input [y (2); u (1)] (and, for VFE, the friction
    estimate held at zero: a linear analysis sees no friction) and output the state estimate x_hat (4).
    """
    builder = DiagramBuilder()
    plant, _ = add_furuta_plant(builder, rig, time_step=0.0, with_scene_graph=False)
    P = plant_to_paper_permutation(plant)
    measure = builder.AddSystem(MatrixGain(ANGLES @ P))
    builder.Connect(plant.get_state_output_port(), measure.get_input_port())
    observer = builder.AddSystem(observer)
    lqr = builder.AddSystem(MatrixGain(-np.asarray(K, dtype=float).reshape(1, 4)))
    inputs = builder.AddSystem(Multiplexer([2, 1]))
    builder.Connect(measure.get_output_port(), inputs.get_input_port(0))
    builder.Connect(lqr.get_output_port(), inputs.get_input_port(1))
    builder.Connect(inputs.get_output_port(), observer.get_input_port())
    builder.Connect(observer.get_output_port(), lqr.get_input_port())
    builder.Connect(lqr.get_output_port(), plant.get_actuation_input_port())
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    plant.get_applied_generalized_force_input_port().FixValue(
        plant.GetMyMutableContextFromRoot(context), np.zeros(plant.num_velocities())
    )
    linear = Linearize(diagram, context)  # the diagram has no free input; its first output is unused
    return np.linalg.eigvals(linear.A())


def separation_error(closed_loop: np.ndarray, controller: np.ndarray, observer: np.ndarray) -> float:
    """Largest distance between the closed loop's eigenvalues and the union of the controller's and the
    observer's (matched one to one); 0 when the separation principle holds."""
    from scipy.optimize import linear_sum_assignment

    union = np.concatenate([controller, observer])
    if union.size != closed_loop.size:
        raise ValueError(f"{closed_loop.size} closed-loop eigenvalues for {union.size} controller + observer ones")
    cost = np.abs(closed_loop[:, None] - union[None, :])
    rows, cols = linear_sum_assignment(cost)
    return float(cost[rows, cols].max())


def observer_for_analysis(kind: str, A: np.ndarray, B_F: np.ndarray, params) -> tuple[LinearSystem, np.ndarray]:
    """The continuous observer ``kind`` ('hg' or 'vfe') as a LinearSystem with input [y (2); u] and output
    x_hat (the VFE's friction input held at zero, its eps_hat_F output dropped), and its error eigenvalues:
    eig(A - H C) for HG (Eq. 4), eig(G) for VFE (Eq. 12)."""
    from furuta_drake.observers.hg import continuous_high_gain_observer, high_gain_error_matrix
    from furuta_drake.observers.vfe import continuous_vfe_observer, vfe_error_matrix, vfe_gains

    if kind == "hg":
        return continuous_high_gain_observer(A, B_F, params), np.linalg.eigvals(high_gain_error_matrix(A, params))
    if kind == "vfe":
        full = continuous_vfe_observer(A, B_F, params)
        reduced = LinearSystem(full.A(), full.B()[:, :3], full.C()[:4], full.D()[:4, :3])
        G = vfe_error_matrix(A, B_F, vfe_gains(A, B_F, params.eigenvalues))
        return reduced, np.linalg.eigvals(G)
    raise ValueError(f"unknown observer {kind!r}: 'hg' or 'vfe'")
