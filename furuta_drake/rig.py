"""Rig parameters of a Furuta pendulum, in the vocabulary of ``spec/diagnosis-interface.md``.

A :class:`RigParameters` is the nominal model a user states for a rig: the rigid-body data that
MultibodyPlant needs, the sensor and actuator limits, and the friction and DC motor the nominal model
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
from typing import Any

import numpy as np

from furuta_drake.errors import ConfigError


@dataclass
class MotorParameters:
    """Armature-controlled DC motor driving the arm: tau = kt (V - ke phi_dot) / R (inductance neglected)."""

    resistance: float = 8.4  # [ohm]
    torque_constant: float = 0.042  # kt [N m / A]
    backemf_constant: float = 0.042  # ke [V s / rad]

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
class RigParameters:
    """The nominal model of a Furuta rig (SI units), field for field the spec's rig YAML.

    The defaults are the Lund pendulum of the paper (``paper/NOTES.md``): they reproduce the four lumped
    constants J_arm + m r^2, J_p + m l^2, m l r and m g l exactly.
    """

    arm_inertia: float = 1.274e-3  # arm (+ rotor) about the vertical axis [kg m^2]
    arm_length: float = 0.25  # pivot to pendulum joint [m]
    pendulum_mass: float = 0.033172  # [kg]
    pendulum_com: float = 0.30  # pendulum joint to its centre of mass [m]
    pendulum_inertia: float = 8.997e-4  # about its centre of mass, transverse [kg m^2]
    gravity: float = 9.81  # [m/s^2]
    counts_per_rev: int = 4096  # encoder resolution [counts/rev]
    sample_period: float = 0.001  # [s]
    torque_limit: float = 0.2  # [N m]
    theta_direction: int = 1  # -1 when logs count theta opposite to the paper's convention
    arm_coulomb: float = 0.0  # [N m]
    arm_viscous: float = 0.0  # [N m s/rad]
    pendulum_coulomb: float = 0.0  # [N m]
    pendulum_viscous: float = 0.0  # [N m s/rad]
    motor: MotorParameters | None = None
    # Effects the nominal model already includes: vocabulary names -> parameters (docs/diagnose.md).
    effects: dict[str, dict[str, Any]] | None = None

    def validate(self, where: str = "rig") -> None:
        """Raise :class:`ConfigError` naming the first non-physical value."""
        for name in ("arm_inertia", "arm_length", "pendulum_mass", "pendulum_com", "pendulum_inertia",
                     "gravity", "sample_period", "torque_limit"):
            _require_positive(getattr(self, name), f"{where}.{name}")
        if int(self.counts_per_rev) != self.counts_per_rev or self.counts_per_rev < 4:
            raise ConfigError(f"{where}.counts_per_rev must be an integer >= 4, got {self.counts_per_rev!r}")
        if self.theta_direction not in (1, -1):
            raise ConfigError(f"{where}.theta_direction must be 1 or -1, got {self.theta_direction!r}")
        for name in ("arm_coulomb", "arm_viscous", "pendulum_coulomb", "pendulum_viscous"):
            _require_nonnegative(getattr(self, name), f"{where}.{name}")
        if self.motor is not None:
            self.motor.validate(f"{where}.motor")
        if self.effects:
            from furuta_drake.diagnosis.candidates import rig_effects  # the vocabulary lives with the diagnosis

            try:
                rig_effects(self)
            except ConfigError as err:
                raise ConfigError(f"{where}.{err}") from None

    # Lumped constants of the Furuta equations of motion (Gaefvert 1998; NOTES.md).
    @property
    def arm_inertia_total(self) -> float:
        """J_arm + m r^2 [kg m^2]: arm inertia with the pendulum mass at the arm tip."""
        return self.arm_inertia + self.pendulum_mass * self.arm_length**2

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
    def encoder_resolution(self) -> float:
        """One encoder count [rad]."""
        return 2.0 * math.pi / self.counts_per_rev

    def replace(self, **changes) -> "RigParameters":
        return dataclasses.replace(self, **changes)


def lund_rig() -> RigParameters:
    """The Lund University Furuta pendulum of the paper (NOTES.md), 4096-count encoders, 1 kHz control."""
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


RIGS = {"lund": lund_rig, "qube_servo2": qube_servo2_rig}


def linearized_upright(rig: RigParameters) -> tuple[np.ndarray, np.ndarray]:
    """A (4x4) and B_F (4x2) of paper Eq. 1-2 at the upright, x = [theta, phi, theta_dot, phi_dot].

    B_F's columns are the pendulum-torque and arm-torque inputs, tau = [F_theta, u + F_phi] (Eq. 3;
    NOTES.md explains the column order printed in Eq. 2). Computed in closed form from the lumped constants;
    the tests check it against Drake's ``Linearize`` of the MultibodyPlant.
    """
    Ja, Jp, c, mgl = rig.arm_inertia_total, rig.pendulum_inertia_total, rig.coupling, rig.gravity_torque
    # Mass matrix at theta = 0 in q = [theta, phi]; with the paper's theta direction the coupling is +m l r,
    # which makes beta4 = -c / det(M) < 0.
    M = np.array([[Jp, c], [c, Ja]])
    Minv = np.linalg.inv(M)
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    A[2:, 0] = Minv[:, 0] * mgl  # gravity acts on theta only: d/dtheta (m g l sin theta) = m g l
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
    "MotorParameters", "RigParameters", "RIGS", "lund_rig", "qube_servo2_rig", "linearized_upright",
]
