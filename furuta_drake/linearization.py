"""The observers' model at either equilibrium: Drake's ``Linearize`` of the Furuta plant at rest, upright or hanging.

The paper's observers (Eq. 4, Eq. 11) carry the linearisation of Eq. 1-2 at the upright. A rig driven by voltage
through a DC motor also feels the back-EMF, a torque -(kt ke / R) phi_dot on the arm that is linear in the state;
and a rig logged hanging (an open-loop chirp) is linearised at theta = pi, where the coupling and the gravity
stiffness change sign (``docs/paper.md``). :func:`plant_linearization` gives (A, B_F) at theta = 0 or pi from
Drake's ``Linearize`` of the ``MultibodyPlant`` (the applied generalized forces as the input, so that B_F has
both columns, pendulum torque and arm torque, tau = [F_theta, u + F_phi] of Eq. 3), permuted to the paper's
order; :func:`observer_model` adds the back-EMF of ``rig.motor``. The closed forms are
:func:`furuta_drake.rig.linearized_upright` and :func:`~furuta_drake.rig.linearized_hanging`; the tests hold the
two to each other.

An observer linearised at the hanging equilibrium estimates the deviation x - x_eq, x_eq = [theta_eq, 0, 0, 0]:
its measured pendulum angle is theta - theta_eq (:func:`equilibrium_angle` gives the theta_eq of a log's turn).
"""

from __future__ import annotations

import math
from typing import Literal

import numpy as np
from pydrake.systems.primitives import Linearize

from furuta_drake.errors import ConfigError
from furuta_drake.plant import joint_indices, make_furuta_plant, plant_to_paper_permutation
from furuta_drake.rig import RigParameters

Equilibrium = Literal["upright", "hanging"]
EQUILIBRIA: dict[str, float] = {"upright": 0.0, "hanging": math.pi}  # theta at rest [rad]


def plant_linearization(rig: RigParameters, equilibrium: Equilibrium = "upright") -> tuple[np.ndarray, np.ndarray]:
    """A (4x4) and B_F (4x2) of Eq. 1-2 at rest at ``equilibrium`` (theta = 0 or pi), paper order
    x = [theta, phi, theta_dot, phi_dot], from Drake's ``Linearize`` of the ``MultibodyPlant`` of ``rig``.

    B_F's columns answer a torque on the pendulum joint and on the arm [1/(kg m^2)] (Eq. 3's tau = [F_theta,
    u + F_phi]). No friction, no motor: the rigid body only (:func:`observer_model` adds the back-EMF).
    """
    theta0 = _equilibrium_theta(equilibrium)
    plant = make_furuta_plant(rig)
    context = plant.CreateDefaultContext()
    theta, _ = joint_indices(plant)
    q = np.zeros(plant.num_positions())
    q[theta] = theta0
    plant.SetPositions(context, q)
    plant.get_actuation_input_port().FixValue(context, np.zeros(plant.num_actuated_dofs()))
    plant.get_applied_generalized_force_input_port().FixValue(context, np.zeros(plant.num_velocities()))
    linear = Linearize(
        plant,
        context,
        plant.get_applied_generalized_force_input_port().get_index(),
        plant.get_state_output_port().get_index(),
    )
    P = plant_to_paper_permutation(plant)
    # The input is the generalized force in the plant's velocity order; columns to [pendulum, arm].
    to_joints = P[2:, plant.num_positions() :]  # rows [theta_dot, phi_dot] of the plant's velocities
    return P @ linear.A() @ P.T, P @ linear.B() @ to_joints.T


def observer_model(
    rig: RigParameters, equilibrium: Equilibrium = "upright", back_emf_damping: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """(A, B_F) an observer carries at ``equilibrium``: :func:`plant_linearization` with the DC motor's back-EMF,
    the arm torque -b phi_dot, b = ``back_emf_damping`` [N m s/rad] (None: kt ke / R of ``rig.motor``, 0 without
    one), in A's phi_dot column: A[:, 3] -= b B_F[:, 1]."""
    A, B_F = plant_linearization(rig, equilibrium)
    if back_emf_damping is None:
        back_emf_damping = 0.0 if rig.motor is None else rig.motor.back_emf_damping
    A = A.copy()
    A[:, 3] -= back_emf_damping * B_F[:, 1]
    return A, B_F


def equilibrium_angle(theta: float, equilibrium: Equilibrium) -> float:
    """The theta [rad] of ``equilibrium`` nearest to ``theta`` (the encoder counts turns: the upright is any
    2 pi n, hanging any pi + 2 pi n)."""
    theta0 = _equilibrium_theta(equilibrium)
    return theta0 + 2.0 * math.pi * round((theta - theta0) / (2.0 * math.pi))


def _equilibrium_theta(equilibrium: str) -> float:
    if equilibrium not in EQUILIBRIA:
        raise ConfigError(f"equilibrium must be one of {list(EQUILIBRIA)}, got {equilibrium!r}")
    return EQUILIBRIA[equilibrium]


__all__ = ["Equilibrium", "EQUILIBRIA", "plant_linearization", "observer_model", "equilibrium_angle"]
