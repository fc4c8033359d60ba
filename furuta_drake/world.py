"""The Furuta world: the MultibodyPlant and everything that acts on it, wired once for every user.

:func:`add_furuta_world` adds to a ``DiagramBuilder`` the plant of a rig (:mod:`furuta_drake.plant`), the
friction on its joints (:class:`~furuta_drake.friction.JointFriction`), the arm's spring and cogging
(:func:`~furuta_drake.actuator.add_arm_disturbance`), the DC motor's back-EMF, the actuator chain
(:func:`~furuta_drake.actuator.add_actuator`) and the rig's drive when it has backlash or elasticity
(:func:`~furuta_drake.drive.add_drive`, between the actuator chain and the arm), and returns the ports a user
connects: the arm torque command in, the true state, the state the encoders read and the friction torques out.
The closed loop (:mod:`furuta_drake.diagram`), the diagnosis' Drake replay (:mod:`furuta_drake.diagnosis.gap.replay`)
and the stability analysis (:mod:`furuta_drake.paper.stability`) all build their plant this way.

Sign convention (paper Eq. 3): the generalized forces on the plant are tau = [F_theta, u + F_phi] plus the arm's
spring, cogging and back-EMF torques and the unmodelled torques (:mod:`furuta_drake.unmodelled`), each an exerted
torque on its joint; with a drive of its own state u is the drive's coupling torque, and the back-EMF acts on the
drive's rotor.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import DiagramBuilder, InputPort, OutputPort, OutputPortSelection
from pydrake.systems.primitives import (
    Adder,
    ConstantVectorSource,
    Linearize,
    LinearSystem,
    MatrixGain,
    Multiplexer,
)
from pydrake.trajectories import PiecewisePolynomial

from furuta_drake.actuator import (
    ActuatorParameters,
    DisturbanceParameters,
    UnmodelledTorque,
    add_actuator,
    add_arm_disturbance,
)
from furuta_drake.drive import add_drive
from furuta_drake.friction import FrictionParameters, JointFriction, JointFrictionSystem
from furuta_drake.plant import ARM_JOINT, add_furuta_plant, plant_to_paper_permutation
from furuta_drake.rig import RigParameters
from furuta_drake.unmodelled import UnmodelledTorqueParameters


@dataclass
class FurutaWorld:
    """The handles of a world added by :func:`add_furuta_world`.

    ``true_state``: [theta, phi, theta_dot, phi_dot] in the paper's order [rad, rad/s]; ``arm_torque_input``: the
    commanded arm torque [N m], the actuator chain's input; ``friction_torque``: [F_theta, F_phi] [N m], the
    torques friction exerts on the joints; ``encoder_state``: what the encoders read, the true state with the arm's
    angle and rate replaced by the drive's rotor's when the arm's encoder sits on the motor; ``friction``: the
    friction system (its context holds the bristle states), None when both joints are frictionless;
    ``drive``: the drive's rotor (its context holds the rotor's state [psi, psi_dot], its output port is that
    state), None without a drive of its own state;
    ``to_paper``: P with x_paper = P x_plant.
    """

    plant: MultibodyPlant
    scene_graph: object
    friction: JointFrictionSystem | JointFriction | None
    true_state: OutputPort
    arm_torque_input: InputPort
    friction_torque: OutputPort
    encoder_state: OutputPort
    drive: LinearSystem | None
    to_paper: np.ndarray = field(repr=False)

    def set_state(self, root_context, x: np.ndarray, twist=(0.0, 0.0)) -> None:
        """Set the paper-order state ``x`` [rad, rad/s] in the diagram's ``root_context``; a drive's rotor at the
        ``twist`` [delta, delta_dot] [rad, rad/s] from the arm (default untwisted: in the middle of its backlash)."""
        self.plant.SetPositionsAndVelocities(self.plant.GetMyMutableContextFromRoot(root_context), self.to_paper.T @ x)
        if self.drive is not None:
            rotor = self.drive.GetMyMutableContextFromRoot(root_context).get_mutable_continuous_state_vector()
            rotor.SetFromVector([x[1] + twist[0], x[3] + twist[1]])


def add_furuta_world(
    builder: DiagramBuilder,
    *,
    rig: RigParameters,
    control_period: float,
    friction: FrictionParameters | None = None,
    actuator: ActuatorParameters | None = None,
    disturbance: DisturbanceParameters | None = None,
    back_emf_damping: float | None = None,
    unmodelled_torque: UnmodelledTorqueParameters | None = None,
    arm_torque_draw: PiecewisePolynomial | None = None,
    with_scene_graph: bool = False,
    linearizable: bool = False,
) -> FurutaWorld:
    """Add the continuous Furuta plant of ``rig`` with ``friction`` on its joints, the arm ``disturbance``
    (spring, cogging), the back-EMF damping torque -``back_emf_damping`` phi_dot [N m s/rad] (None: kt ke / R of
    ``rig.motor``, 0 without one), the ``unmodelled_torque`` expressions on either joint
    (:class:`~furuta_drake.unmodelled.UnmodelledTorque`), ``arm_torque_draw``, a draw of the ongoing
    disturbance (:meth:`~furuta_drake.torque_disturbance.TorqueDisturbance.trajectory`) on the arm, the
    ``actuator`` chain (its delays resolved to half the
    ``control_period`` [s]) and ``rig.drive`` (a rigid one as its rotor's inertia on the arm, one with backlash or
    elasticity as :func:`~furuta_drake.drive.add_drive` between the actuator chain and the arm, the back-EMF
    on its rotor); absent sections add nothing. ``with_scene_graph``: a SceneGraph for visualisation. The friction
    in ``rig`` itself (``arm_coulomb`` ...) is not read: friction comes as ``friction``, in C++
    (:class:`~furuta_drake.friction.JointFrictionSystem`), or with ``linearizable`` as the Python
    :class:`~furuta_drake.friction.JointFriction` that Drake's ``Linearize`` differentiates.
    """
    friction = friction or FrictionParameters()
    if back_emf_damping is None:
        back_emf_damping = 0.0 if rig.motor is None else rig.motor.back_emf_damping
    dynamic_drive = rig.drive is not None and not rig.drive.rigid
    plant, scene_graph = add_furuta_plant(
        builder, rig.replace(drive=None) if dynamic_drive else rig, time_step=0.0, with_scene_graph=with_scene_graph
    )
    P = plant_to_paper_permutation(plant)
    to_paper_order = builder.AddNamedSystem("true_state", MatrixGain(P))
    builder.Connect(plant.get_state_output_port(), to_paper_order.get_input_port())
    true_state = to_paper_order.get_output_port()

    joint_friction, friction_torque = _add_friction(builder, plant, friction, linearizable)
    forces = [] if joint_friction is None else [joint_friction.GetOutputPort("generalized_force_Nm")]
    _connect_forces(
        builder,
        plant,
        forces,
        true_state,
        disturbance=disturbance or DisturbanceParameters(),
        arm_torque_draw=arm_torque_draw,
        back_emf_damping=0.0 if dynamic_drive else back_emf_damping,
        unmodelled_torque=unmodelled_torque,
    )

    actuator_input, actuator_output = add_actuator(
        builder, actuator or ActuatorParameters(), delay_resolution=control_period / 2.0
    )
    rotor, encoder_state = None, true_state
    if dynamic_drive:
        actuator_output, rotor, encoder_state = _add_drive(builder, rig, back_emf_damping, actuator_output, true_state)
    builder.Connect(actuator_output, plant.get_actuation_input_port())
    return FurutaWorld(
        plant, scene_graph, joint_friction, true_state, actuator_input, friction_torque, encoder_state, rotor, P
    )


def _connect_forces(
    builder: DiagramBuilder,
    plant,
    forces: list,
    true_state: OutputPort,
    *,
    disturbance: DisturbanceParameters,
    arm_torque_draw: PiecewisePolynomial | None,
    back_emf_damping: float,
    unmodelled_torque: UnmodelledTorqueParameters | None,
) -> None:
    """Sum the joints' friction (``forces``), the arm's disturbance torques, the back-EMF on the arm and the
    unmodelled torques into the plant's applied generalised force."""
    arm = np.zeros((plant.num_velocities(), 1))  # an arm torque as generalized forces
    arm[plant.GetJointByName(ARM_JOINT).velocity_start(), 0] = 1.0
    arm_torque = add_arm_disturbance(builder, disturbance, true_state, arm_torque_draw)
    if arm_torque is not None:
        to_force = builder.AddNamedSystem("disturbance_to_force", MatrixGain(arm))
        builder.Connect(arm_torque, to_force.get_input_port())
        forces.append(to_force.get_output_port())
    if back_emf_damping != 0.0:
        # The DC motor's back-EMF: a torque -kt ke / R phi_dot on the arm (commands are torque-equivalent).
        back_emf = builder.AddNamedSystem(
            "motor_back_emf", MatrixGain(-back_emf_damping * arm @ np.array([[0.0, 0.0, 0.0, 1.0]]))
        )
        builder.Connect(true_state, back_emf.get_input_port())
        forces.append(back_emf.get_output_port())
    if unmodelled_torque is not None and not unmodelled_torque.is_empty:
        unmodelled = builder.AddNamedSystem("unmodelled_torque", UnmodelledTorque(plant, unmodelled_torque))
        builder.Connect(true_state, unmodelled.get_input_port())
        forces.append(unmodelled.get_output_port())
    if len(forces) == 1:
        builder.Connect(forces[0], plant.get_applied_generalized_force_input_port())
    elif forces:
        total = builder.AddNamedSystem("applied_forces", Adder(len(forces), plant.num_velocities()))
        for i, force in enumerate(forces):
            builder.Connect(force, total.get_input_port(i))
        builder.Connect(total.get_output_port(), plant.get_applied_generalized_force_input_port())


def _add_friction(builder: DiagramBuilder, plant, friction: FrictionParameters, linearizable: bool):
    """(the friction system, None without friction on either joint; its [F_theta, F_phi] [N m] output port) of
    :func:`add_furuta_world`, its input wired to ``plant``'s state."""
    if friction.arm.model == "none" and friction.pendulum.model == "none":
        # No friction: a constant zero rather than a system evaluated at every integrator stage.
        return None, builder.AddNamedSystem("friction", ConstantVectorSource(np.zeros(2))).get_output_port()
    law = JointFriction if linearizable else JointFrictionSystem
    joint_friction = builder.AddNamedSystem("friction", law(plant, friction))
    builder.Connect(plant.get_state_output_port(), joint_friction.get_input_port())
    return joint_friction, joint_friction.GetOutputPort("friction_torque_Nm")


def _add_drive(
    builder: DiagramBuilder,
    rig: RigParameters,
    back_emf_damping: float,
    motor_torque: OutputPort,
    true_state: OutputPort,
) -> tuple[OutputPort, LinearSystem, OutputPort]:
    """``rig.drive`` (:func:`~furuta_drake.drive.add_drive`) between ``motor_torque`` and the arm, the back-EMF on its
    rotor: (the torque on the arm [N m], the rotor, the state the encoders read)."""
    drive = add_drive(
        builder,
        rig.drive,
        arm_inertia=rig.arm_inertia_total - rig.rotor_inertia_reflected,
        rotor_damping=back_emf_damping,
        motor_torque=motor_torque,
        true_state=true_state,
    )
    encoder_state = true_state
    if rig.drive.encoder == "motor":
        encoder_state = _motor_encoder_state(builder, true_state, drive.rotor_state)
    return drive.coupling_torque, drive.rotor, encoder_state


def _motor_encoder_state(builder: DiagramBuilder, true_state: OutputPort, rotor_state: OutputPort) -> OutputPort:
    """[theta, psi, theta_dot, psi_dot]: the true state with the arm's angle and rate replaced by the rotor's (a C++
    ``MatrixGain`` on [x; psi; psi_dot])."""
    stacked = builder.AddNamedSystem("encoder_state_inputs", Multiplexer([4, 2]))
    select = np.zeros((4, 6))
    select[0, 0], select[1, 4], select[2, 2], select[3, 5] = 1.0, 1.0, 1.0, 1.0
    encoder_state = builder.AddNamedSystem("encoder_state", MatrixGain(select))
    builder.Connect(true_state, stacked.get_input_port(0))
    builder.Connect(rotor_state, stacked.get_input_port(1))
    builder.Connect(stacked.get_output_port(), encoder_state.get_input_port())
    return encoder_state.get_output_port()


def linearized_world(
    *,
    rig: RigParameters,
    control_period: float,
    friction: FrictionParameters | None = None,
    actuator: ActuatorParameters | None = None,
    disturbance: DisturbanceParameters | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Drake's ``Linearize`` of the world of :func:`add_furuta_world` (these sections, the rig's back-EMF) at
    the upright at rest under a zero command: d/dt s = A s + B u with s = [theta, phi, theta_dot, phi_dot (paper
    order), the further continuous states in the order their systems were added (friction's bristles, then the
    actuator's lag)] and u the arm torque command [N m]. Every section must have a linearization there (continuous
    states only: no delay)."""
    builder = DiagramBuilder()
    world = add_furuta_world(
        builder,
        rig=rig,
        friction=friction,
        actuator=actuator,
        disturbance=disturbance,
        control_period=control_period,
        linearizable=True,
    )
    builder.ExportInput(world.arm_torque_input, "arm_torque_Nm")
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    diagram.get_input_port().FixValue(context, [0.0])
    linear = Linearize(diagram, context, output_port_index=OutputPortSelection.kNoOutput)
    nx = world.plant.num_multibody_states()
    n = linear.A().shape[0]
    T = np.zeros((n, n))
    T[:4, :nx] = world.to_paper
    T[4:, nx:] = np.eye(n - nx)
    return T @ linear.A() @ T.T, T @ linear.B()


__all__ = ["FurutaWorld", "add_furuta_world", "linearized_world"]
