"""``build_furuta_diagram``: the paper's block diagram wired in a Drake ``DiagramBuilder`` from small builders.

Reading order follows the signal path of the rig::

    u_LQ - F_hat ──► actuator chain ──► MultibodyPlant ◄── friction + spring/cogging + back-EMF   add_furuta_world
        ▲                                   │ (true state)
        │                                   ▼
    controller ◄── observers ◄──────── encoder (counts, sampled at the control period)           add_observers
    (LQR, Sec. IV-A,    HG (Eq. 4) | VFE (Eq. 11) + Dahl (Eq. 8, 16) + K_sigma (Eq. 18)
     or swing-up)                                                                                 add_command

Every block is a Drake system sampled at the control period; the loggers record every signal a result file
needs at that period (:func:`add_loggers`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem, OutputPort
from pydrake.systems.primitives import (
    Adder,
    ConstantVectorSource,
    DiscreteDerivative,
    LogVectorOutput,
    MatrixGain,
    Multiplexer,
    TrajectorySource,
    VectorLogSink,
    ZeroOrderHold,
)

from furuta_drake.config import SimulationConfig
from furuta_drake.controllers.lqr import LqrController, lqr_gain
from furuta_drake.controllers.quanser_swingup import QuanserSwingUpController
from furuta_drake.controllers.swingup import EnergySwingUpController, kinematic_model
from furuta_drake.encoder import Encoder
from furuta_drake.excitation import arm_reference_trajectory, torque_excitation_trajectory
from furuta_drake.observers.dahl import DahlFrictionObserver, add_dahl_adaptation
from furuta_drake.observers.filtered_derivative import FilteredDerivative
from furuta_drake.observers.hg import HighGainObserver, HighGainParameters
from furuta_drake.observers.vfe import VfeObserver, friction_error_response
from furuta_drake.rig import linearized_upright
from furuta_drake.world import FurutaWorld, add_furuta_world


@dataclass
class FurutaDiagram:
    """A built diagram with handles to what callers read: the world (its plant), the loggers and the LQR gain."""

    diagram: Diagram
    world: FurutaWorld
    plant: MultibodyPlant
    scene_graph: object
    loggers: dict[str, VectorLogSink]
    lqr_gain: np.ndarray | None
    config: SimulationConfig


def build_furuta_diagram(config: SimulationConfig, *, meshcat=None) -> FurutaDiagram:
    """Build the closed loop (or the open-loop excitation run) that ``config`` describes. With ``meshcat`` (a
    ``pydrake.geometry.Meshcat``) a ``MeshcatVisualizer`` draws the plant."""
    config.validate()
    period = config.control_period
    builder = DiagramBuilder()
    world = add_furuta_world(
        builder,
        rig=config.rig,
        friction=config.friction,
        actuator=config.actuator,
        disturbance=config.disturbance,
        unmodelled_torque=config.unmodelled_torque,
        arm_torque_draw=arm_torque_draw(config),
        control_period=period,
        with_scene_graph=meshcat is not None,
    )
    encoder = builder.AddNamedSystem("encoder", Encoder(config.encoder, period=period))
    builder.Connect(world.encoder_state, encoder.GetInputPort("true_state"))
    measured = encoder.GetOutputPort("measured_angles_rad")
    command = add_command(builder, config, world=world)
    observers = add_observers(builder, config, true_state=world.true_state, measured=measured, command=command.torque)
    if command.controller is not None:
        connect_estimates(builder, config, command.controller, observers)
    connect_arm_reference(builder, command.state_reference, observers.arm_dahl)
    loggers = add_loggers(builder, period, world=world, measured=measured, command=command, observers=observers)
    if meshcat is not None:
        from pydrake.geometry import MeshcatVisualizer, MeshcatVisualizerParams

        # Published on control samples (every 16th, ~60 frames/s at 1 kHz): the integrator already stops there,
        # so drawing adds no step boundary and the run is bit-identical to one without Meshcat.
        params = MeshcatVisualizerParams()
        params.publish_period = 16 * period
        MeshcatVisualizer.AddToBuilder(builder, world.scene_graph, meshcat, params)
    diagram = builder.Build()
    diagram.set_name("furuta_" + config.controller.mode)
    return FurutaDiagram(diagram, world, world.plant, world.scene_graph, loggers, command.lqr_gain, config)


def arm_torque_draw(config: SimulationConfig):
    """The seeded draw of ``config``'s ongoing arm disturbance over the run (None without one)."""
    disturbance = config.disturbance.arm_torque
    if disturbance is None or not disturbance.active:
        return None
    return disturbance.trajectory(config.duration, config.control_period, config.seed)


@dataclass
class Command:
    """What :func:`add_command` added: ``torque``, the commanded arm torque [N m] (excitation plus controller,
    held at the control period); the ``controller`` (None in open loop), whose ``state_estimate`` input (and
    ``friction_compensation_Nm`` when compensating) the caller connects; its ``lqr_gain`` (1x4); and the
    paper-order ``state_reference`` [rad, rad/s] it tracks (None: the upright)."""

    torque: OutputPort
    controller: object | None
    lqr_gain: np.ndarray | None
    state_reference: OutputPort | None = None


def add_command(builder: DiagramBuilder, config: SimulationConfig, *, world: FurutaWorld) -> Command:
    """The seeded excitation torque and ``config``'s controller (the LQR of Sec. IV-A, the swing-up with it, or
    Quanser's voltage swing-up whose voltage reaches the arm as the torque kt V / R of the rig's motor), summed into
    ``world``'s arm torque input."""
    period, controller_config = config.control_period, config.controller
    torques = []
    excitation = torque_excitation_trajectory(config.excitation, config.duration, period, config.seed)
    if excitation is not None:
        # Held at the control period like the controller's output, so that every command is a discrete signal.
        source = builder.AddNamedSystem("torque_excitation", TrajectorySource(excitation))
        hold = builder.AddNamedSystem("torque_excitation_hold", ZeroOrderHold(period, 1))
        builder.Connect(source.get_output_port(), hold.get_input_port())
        torques.append(hold.get_output_port())
    controller = gain = state_reference = None
    if controller_config.mode == "quanser_swingup":
        controller = builder.AddNamedSystem(
            "quanser_swingup", QuanserSwingUpController(controller_config.quanser_swingup)
        )
        motor = config.rig.motor
        volts_to_torque = builder.AddNamedSystem(
            "motor_torque_per_volt", MatrixGain(np.array([[motor.torque_constant / motor.resistance]]))
        )
        builder.Connect(controller.GetOutputPort("voltage_V"), volts_to_torque.get_input_port())
        torques.append(volts_to_torque.get_output_port())
    elif controller_config.mode != "open_loop":
        gain = controller_gain(world.plant, config)
        limit, compensation = controller_config.lqr.torque_limit, controller_config.friction_compensation
        reference = arm_reference_trajectory(config.excitation, config.duration)
        if controller_config.mode == "lqr":
            controller = builder.AddNamedSystem(
                "lqr",
                LqrController(
                    gain,
                    period=period,
                    torque_limit=limit,
                    friction_compensation=compensation,
                    reference=reference is not None,
                ),
            )
        else:
            controller = builder.AddNamedSystem(
                "swingup",
                EnergySwingUpController(
                    config.rig,
                    gain,
                    controller_config.swingup,
                    period=period,
                    torque_limit=limit,
                    friction_compensation=compensation,
                ),
            )
        torques.append(controller.GetOutputPort("arm_torque_Nm"))
        if reference is not None:
            source = builder.AddNamedSystem("arm_reference", TrajectorySource(reference))
            state_reference = source.get_output_port()
            builder.Connect(state_reference, controller.GetInputPort("state_reference"))
    # Every command is the output of a block updated at the control period, so at each tick the observers read
    # the torque applied over the previous period (Drake's discrete semantics: updates read pre-update values).
    if len(torques) == 1:
        torque = torques[0]
    else:
        total = builder.AddNamedSystem("commanded_torque", Adder(len(torques), 1))
        for i, port in enumerate(torques):
            builder.Connect(port, total.get_input_port(i))
        torque = total.get_output_port()
    builder.Connect(torque, world.arm_torque_input)
    return Command(torque, controller, gain, state_reference)


def connect_estimates(builder: DiagramBuilder, config: SimulationConfig, controller, observers: Observers) -> None:
    """Feed ``controller`` the estimate of ``config``'s velocity source and, when it compensates, the F_hat of
    ``observers``."""
    builder.Connect(observers.estimates[config.controller.velocity_source], controller.GetInputPort("state_estimate"))
    if config.controller.friction_compensation:
        builder.Connect(observers.compensation, controller.GetInputPort("friction_compensation_Nm"))


def controller_gain(plant: MultibodyPlant, config: SimulationConfig) -> np.ndarray:
    """The LQR gain K (1x4, paper order) of ``config``: ``controller.gain`` checked to stabilise the upright of
    ``plant``, or the LQ design of ``controller.lqr``, at the control period."""
    return lqr_gain(plant, config.controller.lqr, period=config.control_period, gain=config.controller.gain)


@dataclass
class Observers:
    """What :func:`add_observers` added: ``estimates``, the state estimate [rad, rad/s] of each velocity source
    that runs; ``compensation``, the F_hat [N m] a compensating controller subtracts (None when the controller
    does not compensate); ``signals``, the observers' further outputs a run logs (``friction_estimate``,
    ``friction_error_estimate``, and ``K_sigma`` or ``dahl_parameters`` when the Dahl observer adapts);
    ``arm_dahl``, the arm's Dahl observers, whose Eq. 9 errors are taken from the arm's reference."""

    estimates: dict[str, OutputPort] = field(default_factory=dict)
    compensation: OutputPort | None = None
    signals: dict[str, OutputPort] = field(default_factory=dict)
    arm_dahl: list[DahlFrictionObserver] = field(default_factory=list)


def add_observers(
    builder: DiagramBuilder,
    config: SimulationConfig,
    *,
    true_state: OutputPort,
    measured: OutputPort,
    command: OutputPort,
) -> Observers:
    """The observers of ``config`` (Sec. III) on the ``measured`` angles [rad] and the commanded arm torque
    ``command`` [N m]: those of ``observers.run`` and the controller's velocity source, with the Dahl observer
    whose F_hat a compensating controller subtracts (Sec. IV-A: on the arm velocity of the observer it uses).
    The reference diagram (iv) reads the true velocities from ``true_state``."""
    controller = config.controller
    source = controller.velocity_source if controller.mode != "open_loop" else None
    compensate = source is not None and controller.friction_compensation
    needed = set(config.observers.run) | ({source} & {"hg", "vfe"})
    model = linearized_upright(config.observers.model or config.rig)
    out, linear = Observers(), []
    if "hg" in needed:
        linear.append(_add_hg(builder, config, model, measured, command, out, compensate and source == "hg"))
    if "vfe" in needed:
        compensate_vfe = compensate and source in ("vfe", "kinematic_hg")
        linear.append(_add_nested_vfe(builder, config, model, measured, command, out, compensate_vfe))
    if source in ("derivative", "true", "filtered_derivative"):
        out.estimates[source] = _add_angle_rates(builder, config, source, true_state, measured)
    if source == "kinematic_hg":
        kinematic = _add_kinematic_hg(builder, config, measured, command)
        out.estimates["kinematic_hg"] = kinematic.GetOutputPort("state_estimate")
        linear.append(kinematic)
    if config.observers.start_at_initial_state:
        start_at(linear, config.initial_state)
    return out


def _add_hg(builder, config, model, measured, command, out: Observers, compensate: bool) -> LeafSystem:
    """The paper's HG observer (Eq. 4) on the upright ``model`` (A, B_F), its estimate into ``out``; with
    ``compensate`` a Dahl observer (Eq. 8) on its arm velocity gives ``out.compensation``."""
    period = config.control_period
    hg = builder.AddNamedSystem("hg_observer", HighGainObserver(model, config.observers.hg, period=period))
    builder.Connect(measured, hg.GetInputPort("measured_angles_rad"))
    builder.Connect(command, hg.GetInputPort("arm_torque_Nm"))
    out.estimates["hg"] = hg.GetOutputPort("state_estimate")
    if compensate:
        # Adaptation reads the VFE's eps_hat_F: on the HG estimate the Dahl observer runs without it.
        hg_dahl, _ = add_dahl_observer(
            builder,
            dataclasses.replace(config.observers.dahl, adaptation=None),
            out.estimates["hg"],
            measured,
            "hg",
            period=period,
        )
        out.compensation = hg_dahl.GetOutputPort("friction_estimate_Nm")
        out.arm_dahl.append(hg_dahl)
    return hg


def _add_nested_vfe(builder, config, model, measured, command, out: Observers, compensate: bool) -> LeafSystem:
    """The VFE observer (Eq. 11) nested with the Dahl observer (Eq. 8, 16) and its adaptation (Eq. 18); its
    estimate and signals into ``out``; with ``compensate`` the Dahl F_hat gives ``out.compensation``."""
    observers = config.observers
    nested = add_vfe_with_dahl(
        builder,
        model,
        observers.vfe,
        observers.dahl,
        measured,
        command,
        observers.pendulum_friction,
        period=config.control_period,
    )
    vfe, dahl, adapter = nested.vfe, nested.dahl, nested.adapter
    out.estimates["vfe"] = vfe.GetOutputPort("state_estimate")
    out.arm_dahl += [dahl] if dahl is not None else []
    adaptation = observers.dahl.adaptation
    if adaptation is not None and adaptation.parameters is not None:
        out.signals["dahl_parameters"] = adapter.GetOutputPort("dahl_parameters")
    out.signals["friction_estimate"] = dahl.GetOutputPort("friction_estimate_Nm")
    out.signals["friction_error_estimate"] = vfe.GetOutputPort("friction_error_estimate_Nm")
    if adaptation is not None and adaptation.k_sigma is not None:
        out.signals["K_sigma"] = adapter.GetOutputPort("K_sigma_branches")
    if compensate:
        out.compensation = dahl.GetOutputPort("friction_estimate_Nm")
    return vfe


def connect_arm_reference(
    builder: DiagramBuilder, state_reference: OutputPort | None, arm_dahl: list[DahlFrictionObserver]
) -> None:
    """The arm's [phi_ref, v_phi_ref] of the paper-order ``state_reference`` into each of the ``arm_dahl``
    observers: Eq. 9's eps_phi and eps_v are the arm's errors from its reference, not from the upright's zero
    (``state_reference`` None: the upright, a zero reference)."""
    if not arm_dahl:
        return
    if state_reference is None:
        select = builder.AddNamedSystem("arm_reference_of_dahl", ConstantVectorSource(np.zeros(2)))
    else:
        rows = np.zeros((2, 4))
        rows[0, 1] = rows[1, 3] = 1.0
        select = builder.AddNamedSystem("arm_reference_of_dahl", MatrixGain(rows))
        builder.Connect(state_reference, select.get_input_port())
    for dahl in arm_dahl:
        builder.Connect(select.get_output_port(), dahl.GetInputPort("arm_reference_rad"))


def _add_angle_rates(builder, config, source: str, true_state: OutputPort, measured: OutputPort) -> OutputPort:
    """The paper-order estimate of the velocity ``source`` "derivative" (backward difference), "true" (the
    reference diagram's true velocities) or "filtered_derivative"."""
    period = config.control_period
    if source == "derivative":
        derivative = builder.AddNamedSystem("angle_derivative", DiscreteDerivative(2, period))
        builder.Connect(measured, derivative.get_input_port())
        return _angles_and(builder, "angles_and_rates", measured, derivative.get_output_port())
    if source == "true":
        velocities = builder.AddNamedSystem("true_velocities", MatrixGain(np.hstack([np.zeros((2, 2)), np.eye(2)])))
        builder.Connect(true_state, velocities.get_input_port())
        return _angles_and(builder, "angles_and_true_velocities", measured, velocities.get_output_port())
    filtered = builder.AddNamedSystem(
        "filtered_derivative", FilteredDerivative(config.observers.filtered_derivative, period=period)
    )
    builder.Connect(measured, filtered.GetInputPort("measured_angles_rad"))
    return filtered.GetOutputPort("state_estimate")


def _add_kinematic_hg(builder, config, measured: OutputPort, command: OutputPort) -> LeafSystem:
    """The swing-up's velocities: the high-gain structure (Eq. 4) on the gravity-free kinematic model."""
    eps = config.controller.swingup.velocity_eps
    kinematic = builder.AddNamedSystem(
        "kinematic_hg_observer",
        HighGainObserver(
            kinematic_model(), HighGainParameters(eps_theta=eps, eps_phi=eps), period=config.control_period
        ),
    )
    builder.Connect(measured, kinematic.GetInputPort("measured_angles_rad"))
    builder.Connect(command, kinematic.GetInputPort("arm_torque_Nm"))
    return kinematic


def start_at(observers, state) -> None:
    """Start the linear ``observers`` (HG, VFE: :class:`~furuta_drake.observers.linear.DiscreteLinearObserver`) at
    the paper-order ``state`` [rad, rad/s] (their friction-error entries at 0) rather than at x_hat = 0."""
    for observer in observers:
        start = np.zeros(observer.discrete.A().shape[0])
        start[:4] = state
        observer.discrete.configure_default_state(start)


def _angles_and(builder: DiagramBuilder, name: str, measured: OutputPort, velocities: OutputPort) -> OutputPort:
    """[theta, phi] of the encoder stacked on [theta_dot, phi_dot] of ``velocities``: a paper-order estimate."""
    mux = builder.AddNamedSystem(name, Multiplexer([2, 2]))
    builder.Connect(measured, mux.get_input_port(0))
    builder.Connect(velocities, mux.get_input_port(1))
    return mux.get_output_port()


class NestedObservers(NamedTuple):
    """What :func:`add_vfe_with_dahl` added: the VFE observer, the arm's Dahl observer, the selector of its arm
    velocity, and the Dahl observer's adapter (the last three None without a Dahl observer; the adapter None
    without adaptation)."""

    vfe: LeafSystem
    dahl: DahlFrictionObserver | None
    arm_velocity: LeafSystem | None
    adapter: LeafSystem | None


def add_vfe_with_dahl(
    builder: DiagramBuilder,
    model,
    vfe_params,
    dahl_params,
    measured: OutputPort,
    command: OutputPort,
    pendulum_params=None,
    *,
    period: float,
):
    """The nested observers of Sec. III-B/C: the VFE observer (Eq. 11) fed by the Dahl observer's F_hat
    (Eq. 8, 16), which reads the VFE's arm velocity estimate and, when ``dahl_params.adaptation`` is given, its
    eps_hat_F (Eq. 18, or the Fc and sigma0 law of Sec. VII); with ``pendulum_params`` a second friction
    observer on the pendulum joint feeds F_hat_theta too. ``model`` is (A, B_F) of Eq. 1-2, ``period`` the
    control period [s]. ``dahl_params`` None: a model without arm friction, F_hat held at 0 (eps_hat_F carries
    all of it). Returns the :class:`NestedObservers` added."""
    vfe = builder.AddNamedSystem(
        "vfe_observer",
        VfeObserver(model, vfe_params, period=period, pendulum_friction_input=pendulum_params is not None),
    )
    estimate = vfe.GetOutputPort("state_estimate")
    builder.Connect(measured, vfe.GetInputPort("measured_angles_rad"))
    builder.Connect(command, vfe.GetInputPort("arm_torque_Nm"))
    if dahl_params is None:
        zero = builder.AddNamedSystem("no_friction_model", ConstantVectorSource(np.zeros(1)))
        builder.Connect(zero.get_output_port(), vfe.GetInputPort("friction_estimate_Nm"))
        dahl = arm_velocity = adapter = None
    else:
        dahl, arm_velocity, adapter = _add_arm_dahl(builder, vfe, dahl_params, model, measured, period)
    if pendulum_params is not None:
        pendulum, _ = add_dahl_observer(
            builder, pendulum_params, estimate, measured, "vfe", period=period, joint="pendulum"
        )
        builder.Connect(
            pendulum.GetOutputPort("friction_estimate_Nm"), vfe.GetInputPort("pendulum_friction_estimate_Nm")
        )
    return NestedObservers(vfe, dahl, arm_velocity, adapter)


def _add_arm_dahl(builder: DiagramBuilder, vfe, dahl_params, model, measured: OutputPort, period: float):
    """The arm's Dahl observer nested with ``vfe`` (:func:`add_vfe_with_dahl`), with its adapter when it adapts:
    (dahl, arm_velocity, adapter or None)."""
    estimate = vfe.GetOutputPort("state_estimate")
    adaptation = dahl_params.adaptation
    dahl, arm_velocity = add_dahl_observer(builder, dahl_params, estimate, measured, "vfe", period=period)
    adapter = add_dahl_adaptation(
        builder,
        dahl,
        velocity=arm_velocity.get_output_port(),
        friction_error=vfe.GetOutputPort("friction_error_estimate_Nm"),
        name="vfe_k_sigma_adapter" if adaptation is not None and adaptation.k_sigma else "vfe_parameter_adapter",
        error_response=(
            friction_error_response(*model, vfe.gains)
            if adaptation is not None and adaptation.parameters is not None
            else None
        ),
    )
    builder.Connect(dahl.GetOutputPort("friction_estimate_Nm"), vfe.GetInputPort("friction_estimate_Nm"))
    return dahl, arm_velocity, adapter


def add_dahl_observer(
    builder: DiagramBuilder,
    params,
    state_estimate: OutputPort,
    measured: OutputPort,
    prefix: str,
    *,
    period: float,
    joint: str = "arm",
):
    """The Dahl (or LuGre) friction observer (Eq. 8, 16) of ``joint`` on that joint's velocity in an observer's
    ``state_estimate`` (paper order); an adapting one needs its adapter (:func:`add_dahl_adaptation`). Returns
    (observer, velocity selector), named
    ``{prefix}_dahl_observer`` and ``{prefix}_arm_velocity`` for the arm, ``{prefix}_pendulum_dahl_observer``
    and ``{prefix}_pendulum_velocity`` for the pendulum."""
    label = prefix if joint == "arm" else f"{prefix}_pendulum"
    dahl = builder.AddNamedSystem(
        f"{label}_dahl_observer",
        DahlFrictionObserver(params, period=period, joint=joint),
    )
    row = np.array([[0.0, 0.0, 0.0, 1.0]]) if joint == "arm" else np.array([[0.0, 0.0, 1.0, 0.0]])
    velocity = builder.AddNamedSystem(f"{prefix}_{joint}_velocity", MatrixGain(row))
    builder.Connect(state_estimate, velocity.get_input_port())
    builder.Connect(velocity.get_output_port(), dahl.GetInputPort(f"{joint}_velocity_estimate_rad_per_s"))
    builder.Connect(measured, dahl.GetInputPort("measured_angles_rad"))
    return dahl, velocity


def add_loggers(
    builder: DiagramBuilder,
    period: float,
    *,
    world: FurutaWorld,
    measured: OutputPort,
    command: Command,
    observers: Observers,
) -> dict[str, VectorLogSink]:
    """Loggers at the control ``period`` [s], sampled like the rig's data: ``state`` (the true state, held),
    ``measured_angles``, ``torque`` (the command), ``true_friction`` (held), ``estimate_{source}`` for each
    observer's estimate and ``signal_{name}`` for the observers' signals and the swing-up controllers'
    ``swingup_mode`` and ``pendulum_energy_J``."""
    loggers = {}

    def log(name: str, port: OutputPort) -> None:
        loggers[name] = LogVectorOutput(port, builder, publish_period=period)

    true_sampled = builder.AddNamedSystem("true_state_sample", ZeroOrderHold(period, 4))
    builder.Connect(world.true_state, true_sampled.get_input_port())
    friction_sampled = builder.AddNamedSystem("true_friction_sample", ZeroOrderHold(period, 2))
    builder.Connect(world.friction_torque, friction_sampled.get_input_port())
    log("state", true_sampled.get_output_port())
    log("measured_angles", measured)
    log("torque", command.torque)
    log("true_friction", friction_sampled.get_output_port())
    for name, port in observers.estimates.items():
        if name != "true":
            log(f"estimate_{name}", port)
    signals = dict(observers.signals)
    if isinstance(command.controller, (EnergySwingUpController, QuanserSwingUpController)):
        signals.update({name: command.controller.GetOutputPort(name) for name in ("swingup_mode", "pendulum_energy_J")})
    for name, port in signals.items():
        log(f"signal_{name}", port)
    return loggers


__all__ = [
    "FurutaDiagram",
    "build_furuta_diagram",
    "Command",
    "add_command",
    "connect_estimates",
    "controller_gain",
    "Observers",
    "add_observers",
    "start_at",
    "NestedObservers",
    "add_vfe_with_dahl",
    "connect_arm_reference",
    "add_dahl_observer",
    "add_loggers",
]
