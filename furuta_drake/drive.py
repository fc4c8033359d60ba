"""A drive with memory between the motor and the arm: gear backlash and an elastic coupling (a belt, a long shaft).

The rotor is a second body on the arm's axis, written on the arm side: its angle psi is the motor's angle over the
gear ratio N, its inertia J = J_m N^2, and the torque tau it receives is the actuator chain's torque-equivalent
command (what a rigid gear would put on the arm). With the arm at angle phi, the twist delta = psi - phi and

    J psi'' = tau - d psi' - T(delta, delta'),        the arm receives T(delta, delta'),

d the motor's back-EMF damping kt ke / R (it acts on the rotor's speed, not the arm's). The coupling torque T:

- an elastic coupling of stiffness k and damping c, no backlash: T = k delta + c delta'. With the pendulum locked or
  removed the pair rings at sqrt(k (1 / J + 1 / J_arm)) rad/s.
- backlash of half-width b: T = 0 while |delta| <= b (the arm is free); beyond, the teeth touch and
  T = k p + c delta', p = delta - b sign(delta) the penetration, held at 0 when it would pull (a tooth only pushes).
  The rotor travels 2 b before the arm follows a reversal.

A rigid gear with backlash has no stiffness of its own to state; its tooth contact is a stiff spring-damper tuned on
the pair's reduced inertia mu = J J_arm / (J + J_arm): k = mu w^2, c = 2 zeta mu w, w = 2 pi CONTACT_FREQUENCY and
zeta = CONTACT_DAMPING_RATIO, so that in contact the pair rings at CONTACT_FREQUENCY and an impact rebounds with a
few per cent of its speed (a nearly inelastic gear impact). A spring-damper rather than an impact law: T is a
function of the state, so Drake's error-controlled integrators step through engagements without witness functions
or mode switches; the contact rings out within 1 / (zeta w) (about a millisecond), above what logs at up to 400 Hz
resolve, and is soft enough for explicit steps of a fraction of a millisecond.

A rigid drive (no backlash, no stiffness) has no state: the rotor turns with the arm and the plant's arm carries its
inertia (:attr:`~furuta_drake.rig.RigParameters.rigid_arm_inertia`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import DiagramBuilder, LeafSystem, OutputPort
from pydrake.systems.primitives import LinearSystem, MatrixGain, Multiplexer

from furuta_drake.errors import ConfigError
from furuta_drake.rig import DriveParameters, _require_nonnegative, _require_positive

CONTACT_FREQUENCY = 200.0  # [Hz] the rotor-arm pair's ringing in a rigid gear's tooth contact
CONTACT_DAMPING_RATIO = 0.7  # [-] of that contact


@dataclass(frozen=True)
class Coupling:
    """The coupling law's constants: half-width ``backlash`` b [rad], ``stiffness`` k [N m/rad], ``damping``
    c [N m s/rad] (arm side)."""

    backlash: float
    stiffness: float
    damping: float

    def torque(self, twist: float, twist_rate: float) -> float:
        """T [N m] on the arm at the twist delta = psi - phi [rad] and its rate [rad/s] (module docstring)."""
        b = self.backlash
        if b == 0.0:
            return self.stiffness * twist + self.damping * twist_rate
        if twist > b:
            return max(self.stiffness * (twist - b) + self.damping * twist_rate, 0.0)
        if twist < -b:
            return min(self.stiffness * (twist + b) + self.damping * twist_rate, 0.0)
        return 0.0


def drive_coupling(drive: DriveParameters, arm_inertia: float) -> Coupling:
    """The coupling of ``drive`` against an arm side of inertia ``arm_inertia`` [kg m^2] (the arm with the pendulum's
    mass at its tip): the drive's own spring and damper, or a rigid gear's tooth contact (module docstring)."""
    drive.validate()
    _require_positive(arm_inertia, "drive arm_inertia")
    if drive.stiffness is not None:
        return Coupling(drive.backlash, drive.stiffness, drive.damping)
    return Coupling(drive.backlash, *tooth_contact(drive.reflected_inertia, arm_inertia))


def tooth_contact(rotor_inertia: float, arm_inertia: float) -> tuple[float, float]:
    """(k [N m/rad], c [N m s/rad]) of a rigid gear's tooth contact between a rotor of ``rotor_inertia`` J and an arm
    side of ``arm_inertia`` J_arm [kg m^2]: k = mu w^2, c = 2 zeta mu w, mu = J J_arm / (J + J_arm) (module
    docstring)."""
    reduced = rotor_inertia * arm_inertia / (rotor_inertia + arm_inertia)
    w = 2.0 * math.pi * CONTACT_FREQUENCY
    return reduced * w**2, 2.0 * CONTACT_DAMPING_RATIO * reduced * w


def resonance(drive: DriveParameters, arm_inertia: float) -> float:
    """sqrt(k (1 / J + 1 / J_arm)) [rad/s]: the rotor-arm pair's ringing through the drive's spring, pendulum
    locked, J = J_m N^2 and J_arm = ``arm_inertia`` [kg m^2] (undamped; ``drive.stiffness`` must be stated)."""
    return math.sqrt(drive.stiffness * (1.0 / drive.reflected_inertia + 1.0 / arm_inertia))


class BacklashCoupling(LeafSystem):
    """T of a :class:`Coupling` with backlash: input ``twist`` [delta, delta_dot] [rad, rad/s], output
    ``coupling_torque_Nm``, with direct feedthrough."""

    def __init__(self, coupling: Coupling):
        super().__init__()
        self._coupling = coupling
        self._twist = self.DeclareVectorInputPort("twist", 2)
        self.DeclareVectorOutputPort("coupling_torque_Nm", 1, self._calc, prerequisites_of_calc={self._twist.ticket()})

    def _calc(self, context, output) -> None:
        twist, rate = self._twist.Eval(context).tolist()
        output.SetAtIndex(0, self._coupling.torque(twist, rate))


@dataclass
class Drive:
    """What :func:`add_drive` added: ``coupling_torque`` T on the arm [N m]; ``rotor_state`` [psi, psi_dot] [rad,
    rad/s]; ``rotor``, the system whose context holds that state."""

    coupling_torque: OutputPort
    rotor_state: OutputPort
    rotor: LinearSystem


def add_drive(
    builder: DiagramBuilder,
    drive: DriveParameters,
    *,
    arm_inertia: float,
    rotor_damping: float,
    motor_torque: OutputPort,
    true_state: OutputPort,
) -> Drive:
    """Add ``drive``'s rotor and coupling (module docstring) between ``motor_torque`` (tau [N m], the actuator
    chain's output) and the arm of ``true_state`` ([theta, phi, theta_dot, phi_dot], paper order); ``arm_inertia``
    [kg m^2]: the arm side's, for a rigid gear's tooth contact; ``rotor_damping`` d [N m s/rad].

    Drake's C++ blocks carry the linear parts: the rotor is a ``LinearSystem`` (state [psi, psi_dot], inputs
    [tau, T]), the twist [delta, delta_dot] a ``MatrixGain`` on [psi, psi_dot, x] (``Multiplexer``), and an elastic
    coupling without backlash the ``MatrixGain`` [k, c]; backlash is a :class:`BacklashCoupling`. T depends on the
    states alone, so the loop through the rotor's input has no feedthrough.
    """
    if drive.rigid:
        raise ConfigError("drive: a rigid drive has no state of its own (its rotor turns with the arm)")
    _require_nonnegative(rotor_damping, "drive rotor_damping")
    coupling = drive_coupling(drive, arm_inertia)
    J, d = drive.reflected_inertia, float(rotor_damping)
    rotor = builder.AddNamedSystem(
        "drive_rotor",
        LinearSystem(
            A=np.array([[0.0, 1.0], [0.0, -d / J]]),
            B=np.array([[0.0, 0.0], [1.0 / J, -1.0 / J]]),
            C=np.eye(2),
            D=np.zeros((2, 2)),
        ),
    )
    states = builder.AddNamedSystem("drive_states", Multiplexer([2, 4]))
    twist = builder.AddNamedSystem(
        "drive_twist", MatrixGain(np.array([[1.0, 0.0, 0.0, -1.0, 0.0, 0.0], [0.0, 1.0, 0.0, 0.0, 0.0, -1.0]]))
    )
    if coupling.backlash > 0:
        law = builder.AddNamedSystem("drive_coupling", BacklashCoupling(coupling))
    else:
        law = builder.AddNamedSystem("drive_coupling", MatrixGain(np.array([[coupling.stiffness, coupling.damping]])))
    inputs = builder.AddNamedSystem("drive_rotor_inputs", Multiplexer([1, 1]))
    builder.Connect(rotor.get_output_port(), states.get_input_port(0))
    builder.Connect(true_state, states.get_input_port(1))
    builder.Connect(states.get_output_port(), twist.get_input_port())
    builder.Connect(twist.get_output_port(), law.get_input_port())
    builder.Connect(motor_torque, inputs.get_input_port(0))
    builder.Connect(law.get_output_port(), inputs.get_input_port(1))
    builder.Connect(inputs.get_output_port(), rotor.get_input_port())
    return Drive(law.get_output_port(), rotor.get_output_port(), rotor)


__all__ = [
    "CONTACT_FREQUENCY",
    "CONTACT_DAMPING_RATIO",
    "Coupling",
    "drive_coupling",
    "tooth_contact",
    "resonance",
    "BacklashCoupling",
    "Drive",
    "add_drive",
]
