"""Quanser's swing-up and balance controller for the QUBE-Servo 2, as SimuRLacra runs it on the real rig: energy
pumping from hanging, a PD law near the upright, voltage out.

The law (SimuRLacra's ``QQubeSwingUpAndBalanceCtrl``, Quanser's gains), rewritten in the package's conventions
(``docs/paper.md``: theta = 0 upright and counted so that beta4 < 0; SimuRLacra's pendulum angle alpha is 0
hanging and counts the other way, alpha = pi - theta, alpha_dot = -theta_dot; its arm angle is phi):

- **Balance**, while the wrapped angle |theta_w| < ``balance_angle``: SimuRLacra's
  V = [-2, 35, -1.5, 3] . ([0, pi, 0, 0] - [phi, alpha, phi_dot, alpha_dot]) reads

      V = k_theta theta_w + k_phi phi + k_thetadot theta_dot + k_phidot phi_dot,
      [k_theta, k_phi, k_thetadot, k_phidot] = [35, 2, 3, 1.5]  (``balance_gains`` [V/rad, V s/rad]).

- **Swing** otherwise: with the controller's own energy of the pendulum, a rod of mass m_p and length L_p (its
  inertia m_p L_p^2 / 12 about the centre of mass, as the published controller writes it),

      E = 1/2 (m_p L_p^2 / 12) theta_dot^2 + 1/2 m_p g L_p (1 + cos theta)      [J], 0 hanging at rest,
      a = sat_a(k_E (E - E_ref) sign(theta_dot cos theta) - k_x phi)             [m/s^2], |a| <= a_max,
      V = (R / k_m) m_r L_r a                                                    [V]

  (sign(alpha_dot cos alpha) = sign(theta_dot cos theta)); the acceleration of the arm tip is turned into a
  voltage through the arm's mass m_r and length L_r and the motor's R and k_m. At rest hanging the sign is 0 in
  the published code; the real rig's first velocity is noise, which picks the first kick's direction, and
  ``rest_direction`` (+1 or -1) is that choice for a simulation, which starts at rest.

The command is clipped at +-``voltage_limit`` (the rig's 4 V software clip). The mode is decided afresh at each
sample (no hysteresis). The constants of the controller's model (``pendulum_mass`` ... ``motor_constant``) are its
own: they stay the nominal QUBE's when the simulated rig is corrected.

:func:`quanser_command` evaluates the law on arrays (the check against logged voltages);
:class:`QuanserSwingUpController` is the Drake system (``controller.mode: quanser_swingup``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from furuta_drake.controllers.swingup import BALANCE, SWING, wrap_angle
from furuta_drake.errors import ConfigError
from furuta_drake.rig import _require_nonnegative, _require_positive


@dataclass
class QuanserSwingUpParameters:
    """Gains, limits and the controller's own model of the QUBE (SimuRLacra's defaults, Quanser's PD gains)."""

    energy_gain: float = 50.0  # k_E [m/(s^2 J)]
    reference_energy: float = 0.025  # E_ref [J]
    arm_position_gain: float = 0.4  # k_x [m/(s^2 rad)]
    acceleration_limit: float = 5.0  # a_max [m/s^2]
    balance_angle: float = math.radians(20.0)  # [rad] the PD law runs while |theta_w| is below this
    balance_gains: list[float] = field(
        default_factory=lambda: [35.0, 2.0, 3.0, 1.5]
    )  # [V/rad, V/rad, V s/rad, V s/rad]
    voltage_limit: float = 4.0  # [V] software clip of the command
    rest_direction: int = 1  # sign taken for theta_dot cos(theta) when it is 0 (the first kick from rest)
    pendulum_mass: float = 0.024  # m_p [kg]
    pendulum_length: float = 0.129  # L_p [m], a rod pivoted at its end
    arm_mass: float = 0.095  # m_r [kg]
    arm_length: float = 0.085  # L_r [m]
    motor_resistance: float = 8.4  # R [ohm]
    motor_constant: float = 0.042  # k_m [N m/A]
    gravity: float = 9.81  # [m/s^2]

    def validate(self, where: str = "controller.quanser_swingup") -> None:
        for name in (
            "energy_gain",
            "acceleration_limit",
            "balance_angle",
            "voltage_limit",
            "pendulum_mass",
            "pendulum_length",
            "arm_mass",
            "arm_length",
            "motor_resistance",
            "motor_constant",
            "gravity",
        ):
            _require_positive(getattr(self, name), f"{where}.{name}")
        for name in ("reference_energy", "arm_position_gain"):
            _require_nonnegative(getattr(self, name), f"{where}.{name}")
        if not self.balance_angle < math.pi:
            raise ConfigError(f"{where}.balance_angle must be below pi rad, got {self.balance_angle!r}")
        if len(self.balance_gains) != 4 or not all(
            isinstance(g, (int, float)) and math.isfinite(g) for g in self.balance_gains
        ):
            raise ConfigError(
                f"{where}.balance_gains must be 4 finite numbers [theta, phi, theta_dot, phi_dot], "
                f"got {self.balance_gains!r}"
            )
        if self.rest_direction not in (1, -1):
            raise ConfigError(f"{where}.rest_direction must be 1 or -1, got {self.rest_direction!r}")

    @property
    def volts_per_acceleration(self) -> float:
        """(R / k_m) m_r L_r [V s^2/m]: the swing law's arm-tip acceleration as a voltage."""
        return self.motor_resistance / self.motor_constant * self.arm_mass * self.arm_length


def quanser_energy(params: QuanserSwingUpParameters, theta, theta_dot):
    """The controller's pendulum energy E [J] (module docstring): 0 hanging at rest, m_p g L_p upright at rest."""
    m, length, g = params.pendulum_mass, params.pendulum_length, params.gravity
    return 0.5 * (m * length**2 / 12.0) * np.square(theta_dot) + 0.5 * m * g * length * (1.0 + np.cos(theta))


def balancing(params: QuanserSwingUpParameters, theta):
    """True where the PD law runs: the wrapped pendulum angle within ``balance_angle`` of the upright."""
    return np.abs(wrap_angle(theta)) < params.balance_angle


def quanser_command(params: QuanserSwingUpParameters, state):
    """The law on paper-order states ``state`` (..., 4) [rad, rad/s]: (voltage [V] clipped at the limit, mode
    (``SWING`` 0 or ``BALANCE`` 1), the controller's energy E [J]), each of shape ``state.shape[:-1]``."""
    state = np.asarray(state, dtype=float)
    theta, phi, theta_dot, phi_dot = np.moveaxis(state, -1, 0)
    energy = quanser_energy(params, theta, theta_dot)
    direction = np.sign(theta_dot * np.cos(theta))
    direction = np.where(direction == 0.0, float(params.rest_direction), direction)
    acceleration = np.clip(
        params.energy_gain * (energy - params.reference_energy) * direction - params.arm_position_gain * phi,
        -params.acceleration_limit,
        params.acceleration_limit,
    )
    swing = params.volts_per_acceleration * acceleration
    k_theta, k_phi, k_thetadot, k_phidot = params.balance_gains
    balance = k_theta * wrap_angle(theta) + k_phi * phi + k_thetadot * theta_dot + k_phidot * phi_dot
    mode = balancing(params, theta)
    voltage = np.clip(np.where(mode, balance, swing), -params.voltage_limit, params.voltage_limit)
    return voltage, np.where(mode, BALANCE, SWING), energy


class QuanserSwingUpController(LeafSystem):
    """:func:`quanser_command` as a Drake system: input ``state_estimate`` (paper order, theta unwrapped, [rad,
    rad/s]); outputs ``voltage_V`` (clipped at +-``voltage_limit``), ``swingup_mode`` (0 swing, 1 balance) and
    ``pendulum_energy_J``, all with direct feedthrough and no state: fed by a sampled estimate, the command of
    sample k is computed from that sample and held with it (no computation delay, as the rig's logs record it)."""

    LOGGED_OUTPUTS = ("swingup_mode", "pendulum_energy_J")

    def __init__(self, params: QuanserSwingUpParameters | None = None):
        super().__init__()
        params = params or QuanserSwingUpParameters()
        params.validate()
        self.params = params
        self._estimate = self.DeclareVectorInputPort("state_estimate", 4)
        for index, name in enumerate(("voltage_V",) + self.LOGGED_OUTPUTS):
            self.DeclareVectorOutputPort(name, 1, self._output(index), prerequisites_of_calc={self._estimate.ticket()})

    def _output(self, index: int):
        def calc(context, output: BasicVector):
            output.SetAtIndex(0, float(quanser_command(self.params, self._estimate.Eval(context))[index]))

        return calc


__all__ = ["QuanserSwingUpParameters", "quanser_energy", "balancing", "quanser_command", "QuanserSwingUpController"]
