"""What stands between the commanded arm torque and the rigid bodies: actuator imperfections, a spring or
cogging on the arm, a torque beyond the effect vocabulary (:class:`UnmodelledTorque`, an expression in the state),
and a DC motor driven by voltage.

These are the sim-to-real effects of the diagnosis vocabulary (``docs/diagnose.md``:
``input_delay``, ``actuator_lag``, ``actuator_deadzone``, ``torque_gain_error``, ``actuator_saturation``,
``arm_spring``), built from Drake's C++ primitives so that they add next to nothing to a closed-loop run; the
nominal values make every block an identity and leave it out.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np
from pydrake.systems.framework import DiagramBuilder, InputPort, LeafSystem, OutputPort
from pydrake.systems.primitives import (
    Adder,
    AffineSystem,
    DiscreteTimeDelay,
    FirstOrderLowPassFilter,
    Gain,
    MatrixGain,
    Multiplexer,
    PassThrough,
    Saturation,
    TrajectorySource,
    ZeroOrderHold,
)
from pydrake.trajectories import PiecewisePolynomial

from furuta_drake.errors import ConfigError, SimulationDiverged
from furuta_drake.plant import joint_indices
from furuta_drake.rig import MotorParameters, _require_nonnegative, _require_positive
from furuta_drake.torque_disturbance import TorqueDisturbance
from furuta_drake.unmodelled import TORQUE_VARIABLES, UnmodelledTorqueParameters


@dataclass
class ActuatorParameters:
    """The actuator chain u_cmd -> delay -> first-order lag -> dead zone -> gain -> saturation -> u."""

    gain: float = 1.0  # torque gain (1 + torque_gain_error) [-]
    deadzone: float = 0.0  # half-width of the dead zone [N m]
    deadzone_form: Literal["subtract", "threshold"] = "subtract"  # u - sat(u), or u only where |u| > deadzone
    saturation_form: Literal["hard", "smooth"] = "hard"  # clip(u, -L, L), or L tanh(u / L)
    saturation: float | None = None  # torque limit of the actuator [N m]; None: no limit beyond the controller's
    delay: float = 0.0  # pure input delay [s]
    lag_time_constant: float = 0.0  # first-order lag [s]

    def validate(self, where: str = "actuator") -> None:
        _require_positive(self.gain, f"{where}.gain")
        for name in ("deadzone", "delay", "lag_time_constant"):
            _require_nonnegative(getattr(self, name), f"{where}.{name}")
        if self.deadzone_form not in ("subtract", "threshold"):
            raise ConfigError(f"{where}.deadzone_form must be 'subtract' or 'threshold', got {self.deadzone_form!r}")
        if self.saturation_form not in ("hard", "smooth"):
            raise ConfigError(f"{where}.saturation_form must be 'hard' or 'smooth', got {self.saturation_form!r}")
        if self.saturation is not None:
            _require_positive(self.saturation, f"{where}.saturation")


def add_actuator(
    builder: DiagramBuilder, params: ActuatorParameters, delay_resolution: float
) -> tuple[InputPort, OutputPort]:
    """Add the actuator chain to ``builder``; return its (input port, output port), torques in N m.

    The chain starts with a ``PassThrough`` (the one input port) followed by the blocks that are not an
    identity, so the nominal chain is that pass-through alone:

    - delay: ``ZeroOrderHold(delay_resolution, offset = delay_resolution / 2)`` then
      ``DiscreteTimeDelay(delay_resolution, n - 1)``, n = round(delay / delay_resolution). A command that changes
      at a multiple of ``delay_resolution`` (every command of the diagram: they are held at the control period)
      reaches the output exactly n delay_resolution later. The half-period offset of the hold keeps its samples
      away from those instants, where sampling at the same instant would read the command before or after its
      update depending on the last bit of the two event times; a continuously varying input is delayed by
      n delay_resolution +- delay_resolution / 2.
    - lag: ``FirstOrderLowPassFilter(lag_time_constant)``, tau du/dt = u_in - u, starting from 0.
    - dead zone, form ``subtract``: u - sat_d(u) with ``Saturation(-deadzone, deadzone)``, a negated copy and an
      ``Adder``; form ``threshold``: :func:`threshold_deadzone`.
    - gain: ``Gain(gain)``; saturation, form ``hard``: ``Saturation(-saturation, saturation)``; form ``smooth``:
      :func:`smooth_saturation`.
    """
    params.validate()
    _require_positive(delay_resolution, "actuator delay_resolution")
    entry = builder.AddNamedSystem("actuator_input", PassThrough(1))
    signal = entry.get_output_port()

    def then(name: str, system) -> None:
        nonlocal signal
        builder.AddNamedSystem(name, system)
        builder.Connect(signal, system.get_input_port(0))
        signal = system.get_output_port(0)

    delay_steps = round(params.delay / delay_resolution)
    if delay_steps > 0:
        then("actuator_delay_sampler", ZeroOrderHold(delay_resolution, 1, offset_sec=delay_resolution / 2))
        then("actuator_delay", DiscreteTimeDelay(delay_resolution, delay_steps - 1, 1))
    if params.lag_time_constant > 0:
        then("actuator_lag", FirstOrderLowPassFilter(params.lag_time_constant, 1))
    if params.deadzone > 0 and params.deadzone_form == "threshold":
        then("actuator_deadzone", threshold_deadzone(params.deadzone))
    elif params.deadzone > 0:
        clipped = builder.AddNamedSystem("actuator_deadzone_clip", Saturation([-params.deadzone], [params.deadzone]))
        negated = builder.AddNamedSystem("actuator_deadzone_negate", Gain(-1.0, 1))
        deadzone = builder.AddNamedSystem("actuator_deadzone", Adder(2, 1))
        builder.Connect(signal, clipped.get_input_port())
        builder.Connect(clipped.get_output_port(), negated.get_input_port())
        builder.Connect(signal, deadzone.get_input_port(0))
        builder.Connect(negated.get_output_port(), deadzone.get_input_port(1))
        signal = deadzone.get_output_port()
    if params.gain != 1.0:
        then("actuator_gain", Gain(params.gain, 1))
    if params.saturation is not None and params.saturation_form == "smooth":
        then("actuator_saturation", smooth_saturation(params.saturation))
    elif params.saturation is not None:
        then("actuator_saturation", Saturation([-params.saturation], [params.saturation]))
    return entry.get_input_port(), signal


class ScalarMap(LeafSystem):
    """y = f(u[index]): a static map of one entry of a vector input, with direct feedthrough. The actuator chain's
    nonlinear maps (a command in [N m], a torque out) and the arm's position-dependent torques (the true state in,
    f of phi out) are such maps."""

    def __init__(self, function, input_name: str, input_size: int, index: int, output_name: str):
        super().__init__()
        self._function, self._index = function, index
        self._input = self.DeclareVectorInputPort(input_name, input_size)
        self.DeclareVectorOutputPort(
            output_name, 1, self._calc, prerequisites_of_calc={self.input_port_ticket(self._input.get_index())}
        )

    def _calc(self, context, output):
        output.SetAtIndex(0, self._function(self._input.Eval(context)[self._index]))


def threshold_deadzone(width: float) -> ScalarMap:
    """A dead zone that drops small commands and passes larger ones whole: u where |u| > ``width``, else 0."""
    return ScalarMap(lambda u: u if abs(u) > width else 0.0, "command_Nm", 1, 0, "torque_Nm")


def smooth_saturation(limit: float) -> ScalarMap:
    """A drive that saturates gradually: L tanh(u / L), L = ``limit``."""
    return ScalarMap(lambda u: limit * math.tanh(u / limit), "command_Nm", 1, 0, "torque_Nm")


@dataclass
class DisturbanceParameters:
    """Torques on the arm beside the command: a spring (e.g. a cable), motor cogging, both position-dependent, and
    ``arm_torque``, an ongoing disturbance drawn from its spectrum (seeded by the config's seed)."""

    arm_spring_stiffness: float = 0.0  # k [N m/rad]
    arm_spring_equilibrium: float = 0.0  # phi0 [rad]
    arm_spring_cubic_stiffness: float = 0.0  # k3 [N m/rad^3]: the spring's torque is -(k x + k3 x^3), x = phi - phi0
    cogging_amplitude: float = 0.0  # A [N m]
    cogging_periods: int = 0  # N, periods per arm revolution
    cogging_phase: float = 0.0  # psi [rad]
    arm_torque: TorqueDisturbance | None = None

    def validate(self, where: str = "disturbance") -> None:
        if self.arm_torque is not None:
            self.arm_torque.validate(f"{where}.arm_torque")
        for name in ("arm_spring_stiffness", "arm_spring_cubic_stiffness", "cogging_amplitude"):
            _require_nonnegative(getattr(self, name), f"{where}.{name}")
        for name in ("arm_spring_equilibrium", "cogging_phase"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
                raise ConfigError(f"{where}.{name} must be a finite number, got {value!r}")
        periods = self.cogging_periods
        if isinstance(periods, bool) or not isinstance(periods, int) or periods < 0:
            raise ConfigError(f"{where}.cogging_periods must be a non-negative integer, got {periods!r}")
        if self.cogging_amplitude > 0 and periods == 0:
            raise ConfigError(f"{where}.cogging_periods must be >= 1 when cogging_amplitude > 0")


def add_arm_disturbance(
    builder: DiagramBuilder,
    params: DisturbanceParameters,
    true_state_port: OutputPort,
    arm_torque_draw: PiecewisePolynomial | None = None,
) -> OutputPort | None:
    """Add the arm's spring -(k x + k3 x^3), x = phi - phi0, and cogging A sin(N phi + psi) fed by
    ``true_state_port`` (paper x), and ``arm_torque_draw``, a draw of the ongoing disturbance
    (:meth:`~furuta_drake.torque_disturbance.TorqueDisturbance.trajectory`) as a ``TrajectorySource``; return the
    port of their sum, the torque on the arm [N m], or None when there is none.

    The spring's linear part is a stateless C++ ``AffineSystem`` (y = -k phi + k phi0); its cubic part and the
    cogging are :class:`ScalarMap` s of phi.
    """
    params.validate()
    torques = []
    if params.arm_spring_stiffness > 0:
        k = params.arm_spring_stiffness
        spring = builder.AddNamedSystem(
            "arm_spring",
            AffineSystem(
                A=np.zeros((0, 0)),
                B=np.zeros((0, 4)),
                f0=np.zeros(0),
                C=np.zeros((1, 0)),
                D=np.array([[0.0, -k, 0.0, 0.0]]),
                y0=np.array([k * params.arm_spring_equilibrium]),
            ),
        )
        builder.Connect(true_state_port, spring.get_input_port())
        torques.append(spring.get_output_port())
    maps = {}
    if params.arm_spring_cubic_stiffness > 0:
        k3, phi0 = params.arm_spring_cubic_stiffness, params.arm_spring_equilibrium
        maps["arm_spring_cubic"] = lambda phi: -k3 * (phi - phi0) ** 3
    if params.cogging_amplitude > 0:
        amplitude, periods, phase = params.cogging_amplitude, params.cogging_periods, params.cogging_phase
        maps["arm_cogging"] = lambda phi: amplitude * math.sin(periods * phi + phase)
    for name, function in maps.items():
        system = builder.AddNamedSystem(name, ScalarMap(function, "true_state", 4, 1, "arm_torque_Nm"))
        builder.Connect(true_state_port, system.get_input_port())
        torques.append(system.get_output_port())
    if arm_torque_draw is not None:
        torques.append(
            builder.AddNamedSystem("arm_torque_disturbance", TrajectorySource(arm_torque_draw)).get_output_port()
        )
    if len(torques) < 2:
        return torques[0] if torques else None
    total = builder.AddNamedSystem("arm_disturbance", Adder(len(torques), 1))
    for i, torque in enumerate(torques):
        builder.Connect(torque, total.get_input_port(i))
    return total.get_output_port()


class UnmodelledTorque(LeafSystem):
    """The torques of :class:`UnmodelledTorqueParameters` on the Furuta ``MultibodyPlant``'s joints.

    Input ``true_state``: [theta, phi, theta_dot, phi_dot] [rad, rad/s] in the paper's order and signs (the
    world's ``true_state`` port, the logs' conventions). Output ``generalized_force_Nm``: the torques in the
    plant's velocity order, for its applied-generalised-force input. A non-finite torque raises
    :class:`~furuta_drake.errors.SimulationDiverged` naming the key, the time and the state.
    """

    def __init__(self, plant, params: UnmodelledTorqueParameters, where: str = "unmodelled_torque"):
        super().__init__()
        self._where = where
        velocity = dict(zip(("pendulum", "arm"), joint_indices(plant)))  # a revolute joint's v index is its q index
        self._joints = [(joint, velocity[joint], f) for joint, f in params.torques(where).items()]
        self._size = plant.num_velocities()
        self._state = self.DeclareVectorInputPort("true_state", 4)
        self.DeclareVectorOutputPort(
            "generalized_force_Nm", self._size, self._calc, prerequisites_of_calc={self._state.ticket()}
        )

    def _calc(self, context, output) -> None:
        x = self._state.Eval(context)
        force = np.zeros(self._size)
        for joint, index, torque in self._joints:
            force[index] = torque.at(x)
            if not math.isfinite(force[index]):
                state = ", ".join(f"{name} = {value:.6g}" for name, value in zip(TORQUE_VARIABLES, x))
                t = context.get_time()
                cause = f"{self._where}.{joint} gave a non-finite torque ({force[index]}) at {state}"
                raise SimulationDiverged(f"simulation diverged at t = {t:.4f} s: {cause}", t, cause)
        output.SetFromVector(force)


def add_dc_motor(
    builder: DiagramBuilder, motor: MotorParameters, voltage_port: OutputPort, true_state_port: OutputPort
) -> OutputPort:
    """Add an armature-controlled DC motor, tau = kt (V - ke phi_dot) / R (inductance neglected): a C++
    ``MatrixGain`` on [V; x] (``Multiplexer``), x the paper's state. Returns the arm torque port [N m]."""
    motor.validate()
    stacked = builder.AddNamedSystem("motor_inputs", Multiplexer([1, 4]))
    kt_over_r = motor.torque_constant / motor.resistance
    torque = builder.AddNamedSystem(
        "motor_torque", MatrixGain(np.array([[kt_over_r, 0.0, 0.0, 0.0, -kt_over_r * motor.backemf_constant]]))
    )
    builder.Connect(voltage_port, stacked.get_input_port(0))
    builder.Connect(true_state_port, stacked.get_input_port(1))
    builder.Connect(stacked.get_output_port(), torque.get_input_port())
    return torque.get_output_port()


__all__ = [
    "ActuatorParameters",
    "add_actuator",
    "ScalarMap",
    "threshold_deadzone",
    "smooth_saturation",
    "DisturbanceParameters",
    "add_arm_disturbance",
    "add_dc_motor",
]
