"""Rig parameters of a Furuta pendulum: the rig file of ``furuta-drake diagnose`` (``docs/diagnose.md``).

A :class:`RigParameters` is the nominal model a user states for a rig: the rigid-body data that
MultibodyPlant needs, the sensor and actuator limits, and the friction, DC motor and gear drive the nominal model
already contains. The same dataclass is the ``rig`` section of a simulate config and the ``--rig`` file of
``furuta-drake diagnose``.

Conventions (paper Eq. 1-2): ``theta`` is the pendulum angle, 0 upright, positive so that a positive arm
torque gives a negative pendulum acceleration at the upright (beta4 < 0); ``phi`` is the arm angle, positive
in the direction a positive torque accelerates the arm.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from furuta_drake.errors import ConfigError
from furuta_drake.torque_disturbance import TorqueDisturbance
from furuta_drake.unmodelled import UnmodelledTorqueParameters
from furuta_drake.yamlio import documented_field

THETA_ZEROS = {"upright": 0.0, "hanging": math.pi}  # the named zeros of the logs' theta [rad]


def encoder_resolution(counts_per_rev: int) -> float:
    """One count of an encoder of ``counts_per_rev`` counts per revolution [rad]: 2 pi / counts_per_rev."""
    return 2.0 * math.pi / counts_per_rev


@dataclass
class MotorParameters:
    """Armature-controlled DC motor driving the arm: tau = kt (V - ke phi_dot) / R (inductance neglected), its
    constants as seen at the arm (through a drive's gear, at the rotor's speed over the gear ratio)."""

    resistance: float = documented_field(
        8.4,
        "armature resistance R",
        "ohm",
        required=True,
        measure="ohmmeter across the motor terminals with the rotor held (turn it a little between readings and "
        "take the typical value), or the motor's datasheet",
    )
    torque_constant: float = documented_field(
        0.042,
        "torque constant kt",
        "N m/A",
        required=True,
        measure="the motor's datasheet, times the drive's gear_ratio for a geared motor (the torque at the arm per "
        "ampere); in SI units it equals the back-EMF constant",
    )
    backemf_constant: float = documented_field(
        0.042,
        "back-EMF constant ke",
        "V s/rad",
        required=True,
        measure="spin the arm by hand or with a second motor and divide the open-circuit terminal voltage by the "
        "arm speed, or the datasheet (times the gear_ratio of a geared motor)",
    )

    def validate(self, where: str = "motor") -> None:
        for name in ("resistance", "torque_constant", "backemf_constant"):
            _require_positive(getattr(self, name), f"{where}.{name}")

    def torque_from_voltage(self, voltage, arm_velocity):
        """Arm torque [N m] for a motor voltage [V] at arm velocity [rad/s] (quasi-static armature)."""
        return self.torque_constant * (voltage - self.backemf_constant * arm_velocity) / self.resistance

    @property
    def back_emf_damping(self) -> float:
        """Equivalent viscous damping of the back-EMF, kt ke / R [N m s/rad]."""
        return self.torque_constant * self.backemf_constant / self.resistance


@dataclass
class DriveParameters:
    """A gear (or belt) between the motor's rotor and the arm: the rotor's inertia J_m reflected to the arm as
    J_m N^2, and the drive's free play and elasticity (:mod:`furuta_drake.drive`), all on the arm side.

    Rigid (no ``backlash``, no ``stiffness``) the rotor turns with the arm and only adds its reflected inertia;
    otherwise it is a second body coupled to the arm through a dead band of half-width ``backlash`` and a spring
    ``stiffness`` with damper ``damping``.
    """

    gear_ratio: float = documented_field(
        1.0,
        "motor turns per arm turn (1 for a direct or 1:1 belt drive)",
        "-",
        required=True,
        measure="the gearbox's stated ratio, or count the motor shaft's turns for one arm turn",
    )
    rotor_inertia: float = documented_field(
        1e-6,
        "the motor rotor's own inertia, motor side (arm_inertia then leaves the rotor out)",
        "kg m^2",
        required=True,
        measure="the motor's datasheet (rotor inertia, often in g cm^2: 1 g cm^2 = 1e-7 kg m^2); the arm feels it "
        "gear_ratio^2 times larger",
    )
    encoder: Literal["arm", "motor"] = documented_field(
        "arm",
        "where the logged arm angle phi is read: arm (an encoder on the arm's shaft) or motor (the motor's encoder, "
        "its angle divided by gear_ratio); both angles are read at counts_per_rev",
        "",
        measure="look where the encoder sits; a motor encoder turns gear_ratio times per arm turn",
    )
    backlash: float = documented_field(
        0.0,
        "half-width of the drive's free play, arm side: the arm turns freely within +-backlash of the rotor",
        "rad",
        measure="hold the motor shaft (a gearmotor at rest holds itself) and rock the arm by hand between the two "
        "flanks: half the arm's free travel",
    )
    stiffness: float | None = documented_field(
        None,
        "torsional stiffness between the rotor and the arm, arm side (a belt, a long shaft); null: rigid",
        "N m/rad",
        measure="hold the motor shaft, hang a known torque on the arm and read the arm's twist; or tap the arm and "
        "time the ringing: stiffness = J (2 pi f)^2 with J the arm side's inertia and the motor shaft held",
    )
    damping: float = documented_field(
        0.0,
        "damping of that spring (needs stiffness)",
        "N m s/rad",
        measure="the tapped ringing's decay: 2 zeta sqrt(stiffness J), zeta its damping ratio",
    )

    def validate(self, where: str = "drive") -> None:
        ratio = self.gear_ratio
        if isinstance(ratio, bool) or not isinstance(ratio, (int, float)) or not math.isfinite(ratio) or ratio < 1:
            raise ConfigError(
                f"{where}.gear_ratio must be a finite number >= 1 (motor turns per arm turn), got {self.gear_ratio!r}"
            )
        _require_positive(self.rotor_inertia, f"{where}.rotor_inertia")
        if self.encoder not in ("arm", "motor"):
            raise ConfigError(f"{where}.encoder must be 'arm' or 'motor', got {self.encoder!r}")
        _require_nonnegative(self.backlash, f"{where}.backlash")
        if self.stiffness is not None:
            _require_positive(self.stiffness, f"{where}.stiffness")
        _require_nonnegative(self.damping, f"{where}.damping")
        if self.damping > 0 and self.stiffness is None:
            raise ConfigError(f"{where}.damping needs a stiffness: a rigid drive has no spring to damp")

    @property
    def reflected_inertia(self) -> float:
        """J_m N^2 [kg m^2]: the rotor's inertia as the arm feels it."""
        return self.rotor_inertia * self.gear_ratio**2

    @property
    def rigid(self) -> bool:
        """Whether the rotor turns with the arm (no backlash, no stiffness): it only adds its inertia."""
        return self.backlash == 0 and self.stiffness is None


@dataclass
class RigParameters:
    """The nominal model of a Furuta rig (SI units), field for field the rig file.

    The defaults are the Lund pendulum of the paper (``docs/paper.md``): they reproduce the four lumped
    constants J_arm + m r^2, J_p + m l^2, m l r and m g l exactly. A rig file must state every field declared
    ``required``; ``furuta-drake rig --template`` writes one with each key explained.
    """

    arm_inertia: float = documented_field(
        1.274e-3,
        "arm with everything it carries except the pendulum (hub, encoder, motor rotor; the rotor left out when a "
        "drive states it) about the vertical axis",
        "kg m^2",
        required=True,
        measure="CAD, or the rotor's datasheet inertia plus m_arm L^2/3 for a rod pivoted at its end "
        "(m_arm L^2/12 for one spun about its centre), or a torsion-pendulum test of the arm",
    )
    arm_length: float = documented_field(
        0.25, "arm pivot axis to pendulum joint axis", "m", required=True, measure="calliper between the two axes"
    )
    pendulum_mass: float = documented_field(
        0.033172,
        "pendulum link with everything that swings with it",
        "kg",
        required=True,
        measure="kitchen or lab scale",
    )
    pendulum_com: float = documented_field(
        0.30,
        "pendulum joint axis to the pendulum's centre of mass",
        "m",
        required=True,
        measure="balance the link on a knife edge and measure from the joint axis to the balance point",
    )
    pendulum_inertia: float = documented_field(
        8.997e-4,
        "pendulum inertia about its centre of mass, about an axis parallel to the joint",
        "kg m^2",
        required=True,
        measure="hold the arm, time small free swings of the hanging pendulum: period T gives J_p + m l^2 = m g l "
        "(T / 2 pi)^2, subtract m l^2 (m pendulum_mass, l pendulum_com); m L^2/12 for a uniform rod of "
        "length L",
    )
    gravity: float = documented_field(
        9.81,
        "gravitational acceleration",
        "m/s^2",
        required=True,
        measure="the local value; 9.81 anywhere on Earth to 0.3 %",
    )
    counts_per_rev: int = documented_field(
        4096,
        "encoder resolution the nominal model assumes, after quadrature decoding",
        "counts/rev",
        required=True,
        measure="encoder lines x 4 for quadrature, or count the change over one full turn by hand",
    )
    sample_period: float = documented_field(
        0.001,
        "control and logging period",
        "s",
        required=True,
        measure="the controller's fixed step; the logs' median time step",
    )
    torque_limit: float = documented_field(
        0.2,
        "largest arm torque the actuator gives",
        "N m",
        required=True,
        measure="voltage limit x kt / R at stall for a voltage-driven DC motor, or current limit x kt",
    )
    theta_direction: int = documented_field(
        1,
        "1 when the logs count theta as furuta-drake does, -1 when they count it the other way",
        "",
        measure="with the pendulum hanging, push the arm towards +phi: 1 when the pendulum swings towards +theta; "
        "furuta-drake diagnose checks it on the logs and names this key when it disagrees",
    )
    theta_zero: Any = documented_field(
        "upright",
        "where the logs' theta is 0: upright, hanging, or the angle in rad (furuta-drake's theta, after "
        "theta_direction) at which the logs read 0",
        "",
        measure="read the logged theta with the pendulum hanging still: near 0 means hanging, near +-pi upright; "
        "furuta-drake diagnose checks it on the logs (gravity's sign about theta = 0) and names this key when it "
        "disagrees",
    )
    arm_coulomb: float = documented_field(
        0.0,
        "arm Coulomb friction the nominal model already has",
        "N m",
        measure="the smallest steady torque that keeps the arm turning slowly; 0 lets the diagnosis find it",
    )
    arm_viscous: float = documented_field(
        0.0,
        "arm viscous friction the nominal model already has (not the motor's back-EMF)",
        "N m s/rad",
        measure="slope of the steady torque against the arm speed at a few speeds",
    )
    pendulum_coulomb: float = documented_field(
        0.0,
        "pendulum joint Coulomb friction the nominal model already has",
        "N m",
        measure="linear (not exponential) decay of the hanging pendulum's free swings with the arm held",
    )
    pendulum_viscous: float = documented_field(
        0.0,
        "pendulum joint viscous friction the nominal model already has",
        "N m s/rad",
        measure="exponential decay rate of the hanging pendulum's free swings times 2 (J_p + m l^2)",
    )
    motor: MotorParameters | None = documented_field(
        None,
        "DC motor driving the arm; required when the logs give the input as a voltage",
        measure="see its three keys",
    )
    drive: DriveParameters | None = documented_field(
        None,
        "gear or belt between the motor and the arm: its ratio, the rotor's inertia, where the arm encoder sits, "
        "and the drive's backlash and elasticity when the nominal model has them",
        measure="see its keys; leave it out for a direct drive whose rotor arm_inertia includes",
    )
    effects: dict[str, dict[str, Any]] | None = documented_field(
        None,
        "effects the nominal model already includes: vocabulary names -> parameters (docs/diagnose.md)",
        measure="leave it out at first; a diagnosis writes fitted_rig.yaml with the effects it accepted",
    )
    unmodelled_torque: UnmodelledTorqueParameters | None = documented_field(
        None,
        "torques beyond the effect vocabulary: {arm: ..., pendulum: ...}, each a numpy expression in theta, phi, "
        "theta_dot, phi_dot (rad, rad/s, the logs' conventions) giving the torque on that joint",
        "N m",
        measure="leave it out at first; a diagnosis writes fitted_rig.yaml with the torque it found beyond the "
        "vocabulary",
    )
    disturbance: TorqueDisturbance | None = documented_field(
        None,
        "the ongoing arm torque no model term explains: {arm_torque_rms, spectrum: [[Hz, PSD], ...], bandwidth_hz, "
        "ci}; every simulation of the rig adds a seeded draw of it",
        "N m, N^2 m^2/Hz",
        measure="leave it out; a diagnosis writes fitted_rig.yaml with what its corrected model still misses on the "
        "held-out logs",
    )

    def validate(self, where: str = "rig") -> None:
        """Raise :class:`ConfigError` naming the first non-physical value."""
        for name in (
            "arm_inertia",
            "arm_length",
            "pendulum_mass",
            "pendulum_com",
            "pendulum_inertia",
            "gravity",
            "sample_period",
            "torque_limit",
        ):
            _require_positive(getattr(self, name), f"{where}.{name}")
        if int(self.counts_per_rev) != self.counts_per_rev or self.counts_per_rev < 4:
            raise ConfigError(f"{where}.counts_per_rev must be an integer >= 4, got {self.counts_per_rev!r}")
        if self.theta_direction not in (1, -1):
            raise ConfigError(f"{where}.theta_direction must be 1 or -1, got {self.theta_direction!r}")
        for name in ("arm_coulomb", "arm_viscous", "pendulum_coulomb", "pendulum_viscous"):
            _require_nonnegative(getattr(self, name), f"{where}.{name}")
        try:
            _ = self.theta_zero_angle
        except ConfigError as err:
            raise ConfigError(f"{where}.{err}") from None
        if self.motor is not None:
            self.motor.validate(f"{where}.motor")
        if self.drive is not None:
            self.drive.validate(f"{where}.drive")
        if self.unmodelled_torque is not None:
            self.unmodelled_torque.validate(f"{where}.unmodelled_torque")
        if self.disturbance is not None:
            self.disturbance.validate(f"{where}.disturbance")

    @property
    def rotor_inertia_reflected(self) -> float:
        """The drive's rotor inertia as the arm feels it, J_m N^2 [kg m^2] (0 without a drive)."""
        return 0.0 if self.drive is None else self.drive.reflected_inertia

    @property
    def rigid_arm_inertia(self) -> float:
        """J_arm [kg m^2]: the arm with the drive's rotor turning with it (``arm_inertia`` plus J_m N^2)."""
        return self.arm_inertia + self.rotor_inertia_reflected

    # Lumped constants of the Furuta equations of motion (Gaefvert 1998; docs/paper.md).
    @property
    def arm_inertia_total(self) -> float:
        """J_arm + m r^2 [kg m^2]: arm inertia (the drive's rotor turning with it) with the pendulum mass at the
        arm tip."""
        return self.rigid_arm_inertia + self.pendulum_mass * self.arm_length**2

    @property
    def pendulum_inertia_total(self) -> float:
        """J_p + m l^2 [kg m^2]: pendulum inertia about its joint."""
        return self.pendulum_inertia + self.pendulum_mass * self.pendulum_com**2

    @property
    def coupling(self) -> float:
        """m l r [kg m^2]."""
        return self.pendulum_mass * self.pendulum_com * self.arm_length

    @property
    def gravity_torque(self) -> float:
        """m g l [N m]."""
        return self.pendulum_mass * self.gravity * self.pendulum_com

    @property
    def theta_zero_angle(self) -> float:
        """furuta-drake's theta [rad] at which the logs read theta = 0 (``theta_zero``): 0 upright, pi hanging."""
        if isinstance(self.theta_zero, str) and self.theta_zero in THETA_ZEROS:
            return THETA_ZEROS[self.theta_zero]
        value = self.theta_zero
        if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
            raise ConfigError(f"theta_zero must be upright, hanging or a finite angle in rad, got {self.theta_zero!r}")
        return float(value)

    @property
    def encoder_resolution(self) -> float:
        """One encoder count [rad]."""
        return encoder_resolution(self.counts_per_rev)

    def replace(self, **changes) -> RigParameters:
        return dataclasses.replace(self, **changes)

    def with_rigid_drive(self) -> RigParameters:
        """This rig with its drive's backlash and elasticity left out (its rotor turning with the arm)."""
        if self.drive is None:
            return self
        return self.replace(drive=dataclasses.replace(self.drive, backlash=0.0, stiffness=None, damping=0.0))


def lund_rig() -> RigParameters:
    """The Lund University Furuta pendulum of the paper (docs/paper.md), 4096-count encoders, 1 kHz control."""
    return RigParameters()


def qube_servo2_rig() -> RigParameters:
    """Quanser QUBE-Servo 2 from public data (arm 0.095 kg / 0.085 m spun about its centre, rotor 4e-6 kg m^2,
    pendulum 0.024 kg / 0.129 m rod, 2048-count encoders, Rm 8.4 ohm, kt = km = 0.042)."""
    arm_mass, arm_length, rotor = 0.095, 0.085, 4e-6
    pend_mass, pend_length = 0.024, 0.129
    motor = MotorParameters(resistance=8.4, torque_constant=0.042, backemf_constant=0.042)
    voltage_limit = 10.0  # the amplifier's range [V]
    return RigParameters(
        arm_inertia=arm_mass * arm_length**2 / 12 + rotor,
        arm_length=arm_length,
        pendulum_mass=pend_mass,
        pendulum_com=pend_length / 2,
        pendulum_inertia=pend_mass * pend_length**2 / 12,
        counts_per_rev=2048,
        sample_period=0.002,
        torque_limit=voltage_limit * motor.torque_constant / motor.resistance,
        motor=motor,
    )


def geared_rig() -> RigParameters:
    """A lab-built rig with values typical of its parts, not of one product: a 12 V DC motor through a 30:1 spur
    gearbox (rotor 1e-6 kg m^2; kt = ke = 0.3 at the arm, R 2.2 ohm), an optical encoder of 600 lines on the arm's
    shaft and on the pendulum's (2400 counts), an aluminium arm of 40 g and 0.15 m pivoted at its end (with hub,
    3.2e-4 kg m^2), a rod pendulum of 30 g and 0.25 m, logged by a microcontroller at 100 Hz."""
    rod_mass, rod_length, volts = 0.03, 0.25, 12.0
    motor = MotorParameters(resistance=2.2, torque_constant=0.3, backemf_constant=0.3)
    return RigParameters(
        arm_inertia=3.2e-4,
        arm_length=0.15,
        pendulum_mass=rod_mass,
        pendulum_com=rod_length / 2,
        pendulum_inertia=rod_mass * rod_length**2 / 12,
        counts_per_rev=2400,
        sample_period=0.01,
        torque_limit=volts * motor.torque_constant / motor.resistance,
        motor=motor,
        drive=DriveParameters(gear_ratio=30.0, rotor_inertia=1e-6, encoder="arm"),
    )


RIGS = {"lund": lund_rig, "qube_servo2": qube_servo2_rig, "geared": geared_rig}


def linearized_upright(rig: RigParameters) -> tuple[np.ndarray, np.ndarray]:
    """A (4x4) and B_F (4x2) of paper Eq. 1-2 at the upright, x = [theta, phi, theta_dot, phi_dot].

    B_F's columns are the pendulum-torque and arm-torque inputs, tau = [F_theta, u + F_phi] (Eq. 3;
    ``docs/paper.md`` explains the column order printed in Eq. 2). Computed in closed form from the lumped constants;
    the tests check it against Drake's ``Linearize`` of the MultibodyPlant.
    """
    return _linearized(rig, cos_theta=1.0)


def linearized_hanging(rig: RigParameters) -> tuple[np.ndarray, np.ndarray]:
    """A (4x4) and B_F (4x2) as :func:`linearized_upright`, at the hanging equilibrium theta = pi: the
    coupling and the gravity stiffness change sign, so the pendulum mode is an oscillation at
    sqrt(m g l (J_arm + m r^2) / det M) rad/s with the arm free."""
    return _linearized(rig, cos_theta=-1.0)


def _linearized(rig: RigParameters, cos_theta: float) -> tuple[np.ndarray, np.ndarray]:
    """Eq. 1 linearized at rest at cos(theta) = +-1 (the upright or hanging)."""
    Ja, Jp, c, mgl = rig.arm_inertia_total, rig.pendulum_inertia_total, rig.coupling, rig.gravity_torque
    # Mass matrix in q = [theta, phi]; with the paper's theta direction the coupling is +m l r cos(theta), which
    # makes beta4 = -c / det(M) < 0 at the upright.
    M = np.array([[Jp, c * cos_theta], [c * cos_theta, Ja]])
    Minv = np.linalg.inv(M)
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    A[2:, 0] = Minv[:, 0] * mgl * cos_theta  # gravity acts on theta only: d/dtheta (m g l sin theta)
    B_F = np.zeros((4, 2))
    B_F[2:, :] = Minv
    return A, B_F


def _require_positive(value, where: str) -> None:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value) or value <= 0:
        raise ConfigError(f"{where} must be a positive finite number, got {value!r}")


def _require_nonnegative(value, where: str) -> None:
    if not isinstance(value, (int, float)) or isinstance(value, bool) or not math.isfinite(value) or value < 0:
        raise ConfigError(f"{where} must be a non-negative finite number, got {value!r}")


__all__ = [
    "MotorParameters",
    "DriveParameters",
    "RigParameters",
    "RIGS",
    "lund_rig",
    "qube_servo2_rig",
    "geared_rig",
    "linearized_upright",
    "linearized_hanging",
]
