"""``build_furuta_diagram``: the paper's block diagram wired in a Drake ``DiagramBuilder``.

Reading order follows the signal path of the rig::

    u_LQ - F_hat ──► actuator chain ──► MultibodyPlant ◄── friction + spring/cogging + back-EMF
        ▲                                   │ (true state)
        │                                   ▼
    LQR (Sec. IV-A) ◄── observer ◄──── encoder (counts, 1 kHz)
                         HG (Eq. 4) | VFE (Eq. 11) + Dahl (Eq. 8, 16) + K_sigma (Eq. 18)

Every block is a Drake system; the loggers record every signal a result file needs at the control period.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Diagram, DiagramBuilder, OutputPort
from pydrake.systems.primitives import (
    Adder, ConstantVectorSource, DiscreteDerivative, LogVectorOutput, MatrixGain, Multiplexer, TrajectorySource,
    VectorLogSink, ZeroOrderHold,
)

from furuta_drake.actuator import add_actuator, add_arm_disturbance
from furuta_drake.config import SimulationConfig
from furuta_drake.controllers.lqr import LqrController, lqr_gain
from furuta_drake.encoder import Encoder
from furuta_drake.excitation import arm_reference_trajectory, torque_excitation_trajectory
from furuta_drake.friction import JointFriction
from furuta_drake.observers.dahl import DahlFrictionObserver
from furuta_drake.observers.hg import HighGainObserver
from furuta_drake.observers.vfe import VfeObserver, friction_error_response
from furuta_drake.plant import add_furuta_plant, plant_to_paper_permutation
from furuta_drake.rig import linearized_upright


@dataclass
class FurutaDiagram:
    """A built diagram with handles to what callers read: the plant, the loggers and the LQR gain."""

    diagram: Diagram
    plant: MultibodyPlant
    scene_graph: object
    loggers: dict[str, VectorLogSink]
    lqr_gain: np.ndarray | None
    config: SimulationConfig


def build_furuta_diagram(config: SimulationConfig, *, meshcat=None, make_controller=None) -> FurutaDiagram:
    """Build the closed loop (or the open-loop excitation run) that ``config`` describes.

    With ``meshcat`` (a ``pydrake.geometry.Meshcat``) a ``MeshcatVisualizer`` draws the plant.
    ``make_controller(builder, lqr_gain, measured)`` replaces the LqrController of ``controller.mode = 'lqr'``
    (e.g. :mod:`furuta_drake.controllers.swingup`): it adds a system with the LqrController's ports (``arm_torque_Nm`` out,
    ``state_estimate`` in, fed the ``velocity_source`` estimate unless it connected it itself, and
    ``friction_compensation_Nm`` when compensating) and returns (system, {name: estimate port of an observer it
    added}); its other outputs are logged into ``signals`` and the estimates into ``estimates``.
    """
    config.validate()
    rig, period = config.rig, config.control_period
    builder = DiagramBuilder()
    loggers: dict[str, VectorLogSink] = {}

    def log(name: str, port: OutputPort) -> None:
        loggers[name] = LogVectorOutput(port, builder, publish_period=period)

    # --- The plant and the world around it --------------------------------------------------------------------
    plant, scene_graph = add_furuta_plant(builder, rig, time_step=0.0, with_scene_graph=meshcat is not None)
    P = plant_to_paper_permutation(plant)
    to_paper_order = builder.AddNamedSystem("true_state", MatrixGain(P))
    builder.Connect(plant.get_state_output_port(), to_paper_order.get_input_port())
    true_state = to_paper_order.get_output_port()

    applied_forces = []
    if config.friction.arm.model == "none" and config.friction.pendulum.model == "none":
        # No friction: a constant zero for the log rather than a Python system evaluated twice at every integrator
        # stage (a fifth of a frictionless closed loop's time in the profile).
        true_friction = builder.AddNamedSystem("friction", ConstantVectorSource(np.zeros(2))).get_output_port()
    else:
        friction = builder.AddNamedSystem("friction", JointFriction(plant, config.friction))
        builder.Connect(plant.get_state_output_port(), friction.get_input_port())
        applied_forces.append(friction.GetOutputPort("generalized_force_Nm"))
        true_friction = friction.GetOutputPort("friction_torque_Nm")

    arm_torque_to_generalized = _arm_torque_to_generalized_force(plant)
    disturbance = add_arm_disturbance(builder, config.disturbance, true_state)
    if disturbance is not None:
        to_force = builder.AddNamedSystem("disturbance_to_force", MatrixGain(arm_torque_to_generalized))
        builder.Connect(disturbance, to_force.get_input_port())
        applied_forces.append(to_force.get_output_port())
    if rig.motor is not None:
        # Back-EMF of the DC motor: a torque -kt ke / R phi_dot on the arm (the command is torque-equivalent).
        back_emf = builder.AddNamedSystem("motor_back_emf", MatrixGain(
            -rig.motor.back_emf_damping * arm_torque_to_generalized @ np.array([[0.0, 0.0, 0.0, 1.0]])))
        builder.Connect(true_state, back_emf.get_input_port())
        applied_forces.append(back_emf.get_output_port())
    if applied_forces:
        _sum_into(builder, applied_forces, plant.get_applied_generalized_force_input_port(), "applied_forces")

    # Delays are resolved to half a control period (a finer clock costs an integrator stop per tick).
    actuator_input, actuator_output = add_actuator(builder, config.actuator, delay_resolution=period / 2.0)
    builder.Connect(actuator_output, plant.get_actuation_input_port())

    # --- Sensors ---------------------------------------------------------------------------------------------
    encoder = builder.AddNamedSystem("encoder", Encoder(config.encoder, period=period))
    builder.Connect(true_state, encoder.GetInputPort("true_state"))
    measured = encoder.GetOutputPort("measured_angles_rad")

    # --- Command: LQR on an estimate, or open-loop excitation ------------------------------------------------
    commands = []
    excitation = torque_excitation_trajectory(config.excitation, config.duration, period, config.seed)
    if excitation is not None:
        # Held at the control period like the controller's output, so that every command is a discrete signal.
        source = builder.AddNamedSystem("torque_excitation", TrajectorySource(excitation))
        hold = builder.AddNamedSystem("torque_excitation_hold", ZeroOrderHold(period, 1))
        builder.Connect(source.get_output_port(), hold.get_input_port())
        commands.append(hold.get_output_port())
    lqr_gain = None
    estimates: dict[str, OutputPort] = {}
    controller = None
    if config.controller.mode == "lqr":
        lqr_gain = controller_gain(plant, config)
        reference = arm_reference_trajectory(config.excitation, config.duration)
        if make_controller is None:
            controller = builder.AddNamedSystem("lqr", LqrController(
                lqr_gain, period=period, torque_limit=config.controller.lqr.torque_limit,
                friction_compensation=config.controller.friction_compensation, reference=reference is not None))
        else:
            controller, own_estimates = make_controller(builder, lqr_gain, measured)
            estimates.update(own_estimates)
            for i in range(controller.num_output_ports()):
                if controller.get_output_port(i).get_name() != "arm_torque_Nm":
                    log(f"signal_{controller.get_output_port(i).get_name()}", controller.get_output_port(i))
        commands.append(controller.GetOutputPort("arm_torque_Nm"))
        if reference is not None:
            source = builder.AddNamedSystem("arm_reference", TrajectorySource(reference))
            builder.Connect(source.get_output_port(), controller.GetInputPort("state_reference"))
    # Every command is the output of a block updated at the control period, so at each tick the observers read
    # the torque applied over the previous period (Drake's discrete semantics: updates read pre-update values).
    command = _sum_into(builder, commands, actuator_input, "commanded_torque")

    # --- Observers (Sec. III) --------------------------------------------------------------------------------
    needed = set(config.observers.run)
    if config.controller.mode == "lqr" and config.controller.velocity_source in ("hg", "vfe"):
        needed.add(config.controller.velocity_source)
    A_model, B_F = linearized_upright(rig)
    if "hg" in needed:
        hg = builder.AddNamedSystem("hg_observer", HighGainObserver((A_model, B_F), config.observers.hg, period=period))
        builder.Connect(measured, hg.GetInputPort("measured_angles_rad"))
        builder.Connect(command, hg.GetInputPort("arm_torque_Nm"))
        estimates["hg"] = hg.GetOutputPort("state_estimate")
        if controller is not None and config.controller.friction_compensation \
                and config.controller.velocity_source == "hg":
            # Sec. IV-A: u = u_LQ - F_hat with F_hat from the Dahl observer (Eq. 8) on the HG arm velocity.
            # Adaptation reads the VFE's eps_hat_F: on the HG estimate the Dahl observer runs without it.
            hg_dahl, _ = add_dahl_observer(builder, dataclasses.replace(config.observers.dahl, adaptation=None),
                                           hg.GetOutputPort("state_estimate"), measured, "hg", period=period)
            builder.Connect(hg_dahl.GetOutputPort("friction_estimate_Nm"),
                            controller.GetInputPort("friction_compensation_Nm"))
    if "vfe" in needed:
        vfe, dahl, _ = add_vfe_with_dahl(builder, (A_model, B_F), config.observers.vfe, config.observers.dahl,
                                         measured, command, config.observers.pendulum_friction, period=period)
        adaptation = config.observers.dahl.adaptation
        if adaptation is not None and adaptation.parameters is not None:
            log("dahl_parameters", dahl.GetOutputPort("dahl_parameters"))
        estimates["vfe"] = vfe.GetOutputPort("state_estimate")
        log("friction_estimate", dahl.GetOutputPort("friction_estimate_Nm"))
        log("friction_error_estimate", vfe.GetOutputPort("friction_error_estimate_Nm"))
        if adaptation is not None and adaptation.k_sigma is not None:
            log("K_sigma", dahl.GetOutputPort("K_sigma_branches"))
        if controller is not None and config.controller.friction_compensation \
                and config.controller.velocity_source == "vfe":
            builder.Connect(dahl.GetOutputPort("friction_estimate_Nm"),
                            controller.GetInputPort("friction_compensation_Nm"))
    if "derivative" == config.controller.velocity_source and config.controller.mode == "lqr":
        derivative = builder.AddNamedSystem("angle_derivative", DiscreteDerivative(2, period))
        mux = builder.AddNamedSystem("angles_and_rates", Multiplexer([2, 2]))
        builder.Connect(measured, derivative.get_input_port())
        builder.Connect(measured, mux.get_input_port(0))
        builder.Connect(derivative.get_output_port(), mux.get_input_port(1))
        estimates["derivative"] = mux.get_output_port()
    if controller is not None and config.controller.velocity_source == "true":
        # The reference diagram (iv): encoder angles with the true velocities.
        velocities = builder.AddNamedSystem("true_velocities", MatrixGain(np.hstack([np.zeros((2, 2)), np.eye(2)])))
        mux = builder.AddNamedSystem("angles_and_true_velocities", Multiplexer([2, 2]))
        builder.Connect(true_state, velocities.get_input_port())
        builder.Connect(measured, mux.get_input_port(0))
        builder.Connect(velocities.get_output_port(), mux.get_input_port(1))
        estimates["true"] = mux.get_output_port()
    if controller is not None and not builder.IsConnectedOrExported(controller.GetInputPort("state_estimate")):
        builder.Connect(estimates[config.controller.velocity_source], controller.GetInputPort("state_estimate"))

    # --- Loggers, sampled at the control period like the rig's data ------------------------------------------
    true_sampled = builder.AddNamedSystem("true_state_sample", ZeroOrderHold(period, 4))
    builder.Connect(true_state, true_sampled.get_input_port())
    friction_sampled = builder.AddNamedSystem("true_friction_sample", ZeroOrderHold(period, 2))
    builder.Connect(true_friction, friction_sampled.get_input_port())
    log("state", true_sampled.get_output_port())
    log("measured_angles", measured)
    log("torque", command)
    log("true_friction", friction_sampled.get_output_port())
    for name, port in estimates.items():
        if name != "true":
            log(f"estimate_{name}", port)

    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams
        # Published on control samples (16 ms, ~60 frames/s): the integrator already stops there, so drawing
        # adds no step boundary and the run is bit-identical to one without Meshcat (the default 1/64 s is not).
        params = MeshcatVisualizerParams()
        params.publish_period = 16 * period
        MeshcatVisualizer.AddToBuilder(builder, scene_graph, meshcat, params)

    diagram = builder.Build()
    diagram.set_name("furuta_" + config.controller.mode)
    return FurutaDiagram(diagram, plant, scene_graph, loggers, lqr_gain, config)


def add_vfe_with_dahl(builder: DiagramBuilder, model, vfe_params, dahl_params, measured: OutputPort,
                      command: OutputPort, pendulum_params=None, *, period: float):
    """The nested observers of Sec. III-B/C: the VFE observer (Eq. 11) fed by the Dahl observer's F_hat
    (Eq. 8, 16), which reads the VFE's arm velocity estimate and, when ``dahl_params.adaptation`` is given, its
    eps_hat_F (Eq. 18, or the Fc and sigma0 law of Sec. VII); with ``pendulum_params`` a second friction
    observer on the pendulum joint feeds F_hat_theta too. Returns (vfe, dahl, arm_velocity)."""
    vfe = builder.AddNamedSystem("vfe_observer", VfeObserver(
        model, vfe_params, period=period, pendulum_friction_input=pendulum_params is not None))
    estimate = vfe.GetOutputPort("state_estimate")
    adaptation = dahl_params.adaptation
    error_response = friction_error_response(*model, vfe.gains) if adaptation is not None \
        and adaptation.parameters is not None else None
    dahl, arm_velocity = add_dahl_observer(builder, dahl_params, estimate, measured, "vfe", period=period,
                                           error_response=error_response)
    if adaptation is not None:
        builder.Connect(vfe.GetOutputPort("friction_error_estimate_Nm"),
                        dahl.GetInputPort("friction_error_estimate_Nm"))
    builder.Connect(measured, vfe.GetInputPort("measured_angles_rad"))
    builder.Connect(command, vfe.GetInputPort("arm_torque_Nm"))
    builder.Connect(dahl.GetOutputPort("friction_estimate_Nm"), vfe.GetInputPort("friction_estimate_Nm"))
    if pendulum_params is not None:
        pendulum, _ = add_dahl_observer(builder, pendulum_params, estimate, measured, "vfe", period=period,
                                        joint="pendulum")
        builder.Connect(pendulum.GetOutputPort("friction_estimate_Nm"),
                        vfe.GetInputPort("pendulum_friction_estimate_Nm"))
    return vfe, dahl, arm_velocity


def controller_gain(plant: MultibodyPlant, config: SimulationConfig) -> np.ndarray:
    """The LQR gain K (1x4, paper order) of ``config``: ``controller.gain`` checked to stabilise the upright of
    ``plant``, or the LQ design of ``controller.lqr``, at the control period."""
    return lqr_gain(plant, config.controller.lqr, period=config.control_period, gain=config.controller.gain)


def _arm_torque_to_generalized_force(plant: MultibodyPlant) -> np.ndarray:
    """Column (nv x 1) mapping an arm torque to the plant's generalized forces."""
    column = np.zeros((plant.num_velocities(), 1))
    column[plant.GetJointByName("arm").velocity_start(), 0] = 1.0
    return column


def _sum_into(builder: DiagramBuilder, ports: list[OutputPort], destination, name: str):
    """Connect the sum of ``ports`` into ``destination`` (an input port, or None) and return the summed port."""
    if len(ports) == 1:
        summed = ports[0]
    else:
        adder = builder.AddNamedSystem(name, Adder(len(ports), ports[0].size()))
        for i, port in enumerate(ports):
            builder.Connect(port, adder.get_input_port(i))
        summed = adder.get_output_port()
    if destination is not None:
        builder.Connect(summed, destination)
    return summed


def add_dahl_observer(builder: DiagramBuilder, params, state_estimate: OutputPort, measured: OutputPort, prefix: str,
                      *, period: float, joint: str = "arm", error_response=None):
    """The Dahl (or LuGre) friction observer (Eq. 8, 16) of ``joint`` on that joint's velocity in an observer's
    ``state_estimate`` (paper order), adapting as ``params.adaptation`` says (``error_response``: its VFE's
    ``friction_error_response``, for the Fc and sigma0 law). Returns (observer, velocity selector), named
    ``{prefix}_dahl_observer`` and ``{prefix}_arm_velocity`` for the arm, ``{prefix}_pendulum_dahl_observer``
    and ``{prefix}_pendulum_velocity`` for the pendulum."""
    label = prefix if joint == "arm" else f"{prefix}_pendulum"
    dahl = builder.AddNamedSystem(f"{label}_dahl_observer", DahlFrictionObserver(
        params, period=period, joint=joint, error_response=error_response))
    row = np.array([[0.0, 0.0, 0.0, 1.0]]) if joint == "arm" else np.array([[0.0, 0.0, 1.0, 0.0]])
    velocity = builder.AddNamedSystem(f"{prefix}_{joint}_velocity", MatrixGain(row))
    builder.Connect(state_estimate, velocity.get_input_port())
    builder.Connect(velocity.get_output_port(), dahl.GetInputPort(f"{joint}_velocity_estimate_rad_per_s"))
    builder.Connect(measured, dahl.GetInputPort("measured_angles_rad"))
    return dahl, velocity
