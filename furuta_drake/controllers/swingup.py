"""Swing-up and catch (the paper's last open point, Sec. VII): energy pumping from the hanging position, then the
LQR of Sec. IV-A near the top.

Swing (Astrom and Furuta 2000): the pendulum's energy E = 1/2 J_p theta_dot^2 + m g l (cos theta - 1) (J_p about
the joint; zero at the upright at rest, -2 m g l hanging) changes at the rate dE/dt = -m l r cos(theta)
theta_dot phi_ddot (the arm acceleration is what the pendulum feels), so with b = sign(beta4) (the sign of the
arm torque's effect on theta_ddot at the upright, negative on both shipped rigs) the law

    u = sat(k (E_ref - E) sign(b theta_dot cos theta) - k_phi phi - k_phidot phi_dot)

pumps E toward E_ref, the arm-centering terms keeping the arm near phi = 0 so that the LQR catches it within
its torque limit. Catch: once the wrapped pendulum angle theta_w (the encoder counts turns, so theta is not
wrapped) is within ``catch_angle`` of the upright and |E| < ``catch_energy``, the command becomes the
LQR's u = -K [theta_w, phi, theta_dot, phi_dot]; it falls back to pumping only when |theta_w| exceeds
``release_angle`` (hysteresis, so the hand-over does not chatter at the window's edge).

Velocity estimate: the paper's HG observer (Eq. 4) carries the upright linearization, whose gravity term
alpha1 theta is wrong away from the upright (at theta = pi it predicts 150 rad/s^2 where the truth is 0) and
grows with every turn theta makes, so a catch at theta = 2 pi n fails. The swing-up loop therefore estimates
velocities with the same high-gain structure on the kinematic model (theta_ddot = phi_ddot = 0: no gravity, no
input, :func:`kinematic_model`; ``controller.velocity_source = 'kinematic_hg'``), which is invariant to whole
turns; its bias is a1 eps / a2 times the true acceleration. :mod:`furuta_drake.paper.studies.swingup_study` measures
both against the truth.

In a simulate config the swing-up is ``controller.mode = 'swingup'`` with its parameters in
``controller.swingup``; :func:`furuta_drake.config.swingup_config` makes one that starts hanging.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import LeafSystem

from furuta_drake.errors import ConfigError
from furuta_drake.rig import RigParameters, _require_nonnegative, _require_positive, linearized_upright

SWING, BALANCE = 0.0, 1.0  # values of the ``swingup_mode`` output


@dataclass
class SwingUpParameters:
    """Energy pumping, arm centering and the catch window. Defaults suit the Lund rig at 0.2 N m."""

    energy_gain: float = 5.0  # k [N m/J]
    energy_reference: float = 0.1  # E_ref / (m g l) [-]: a little above the upright at rest (0), for the losses
    arm_position_gain: float = 0.1  # k_phi / torque limit [1/rad]
    arm_velocity_gain: float = 0.025  # k_phidot / torque limit [s/rad]
    catch_angle: float = 0.3  # [rad] hand over to the LQR when |theta_w| < catch_angle ...
    catch_energy: float = 0.4  # ... and |E| / (m g l) < catch_energy [-]
    catch_torque_ratio: float = 1.0  # ... and the LQR's command (arm term aside) below this times the limit [-]
    release_angle: float = 0.8  # [rad] back to pumping when |theta_w| > release_angle
    velocity_eps: float = 0.005  # [s] scale of the kinematic high-gain velocity observer (poles -1/eps)
    arm_return_time: float = 2.0  # [s] time constant of the LQR's arm reference, from phi at the catch to 0
    swing_torque_limit: float | None = None  # [N m] cap of the pumping torque (None: the rig's torque limit)

    def validate(self, where: str = "controller.swingup") -> None:
        for name in (
            "energy_gain",
            "catch_angle",
            "catch_energy",
            "release_angle",
            "velocity_eps",
            "arm_return_time",
            "catch_torque_ratio",
        ):
            _require_positive(getattr(self, name), f"{where}.{name}")
        if self.swing_torque_limit is not None:
            _require_positive(self.swing_torque_limit, f"{where}.swing_torque_limit")
        for name in ("arm_position_gain", "arm_velocity_gain"):
            _require_nonnegative(getattr(self, name), f"{where}.{name}")
        if not math.isfinite(self.energy_reference):
            raise ConfigError(f"{where}.energy_reference must be finite, got {self.energy_reference!r}")
        if not self.catch_angle < self.release_angle < math.pi:
            raise ConfigError(
                f"{where}: need catch_angle < release_angle < pi (hysteresis), got "
                f"{self.catch_angle}, {self.release_angle}"
            )


def pendulum_energy(rig: RigParameters, theta, theta_dot):
    """E = 1/2 J_p theta_dot^2 + m g l (cos theta - 1) [J], J_p the pendulum's inertia about its joint."""
    return 0.5 * rig.pendulum_inertia_total * np.square(theta_dot) + rig.gravity_torque * (np.cos(theta) - 1.0)


def wrap_angle(angle):
    """Angle in [-pi, pi) [rad]."""
    return np.mod(np.asarray(angle) + math.pi, 2.0 * math.pi) - math.pi


class EnergySwingUpController(LeafSystem):
    """Energy pumping with arm centering, handing over to u = -K x_w inside the catch window (module docstring).

    Input ``state_estimate`` (paper order, theta = 0 upright, unwrapped) and ``friction_compensation_Nm`` (F_hat,
    subtracted in both modes when ``friction_compensation``, as the LqrController does). Outputs, discrete state
    held from t_k to t_k+1: ``arm_torque_Nm`` (saturated at +-``torque_limit``), ``swingup_mode`` (0 pumping,
    1 LQR) and ``pendulum_energy_J`` (E of the estimate at t_k).
    """

    def __init__(
        self,
        rig: RigParameters,
        K,
        params: SwingUpParameters,
        *,
        period: float,
        torque_limit: float,
        friction_compensation: bool = False,
    ):
        super().__init__()
        rig.validate()
        params.validate()
        _require_positive(period, "EnergySwingUpController period")
        _require_positive(torque_limit, "EnergySwingUpController torque_limit")
        K = np.asarray(K, dtype=float).ravel()
        if K.size != 4 or not np.all(np.isfinite(K)):
            raise ConfigError(f"LQR gain must be 4 finite numbers, got {K.tolist()}")
        _, B_F = linearized_upright(rig)
        self._pump_sign = math.copysign(1.0, B_F[2, 1])  # sign(beta4)
        self._negative_gain = -K
        self._half_inertia = 0.5 * rig.pendulum_inertia_total
        self._mgl = rig.gravity_torque
        self._energy_reference = params.energy_reference * rig.gravity_torque
        self._catch_energy = params.catch_energy * rig.gravity_torque
        self._p = params
        self._limit = float(torque_limit)
        self._catch_torque = params.catch_torque_ratio * self._limit
        self._arm_position_gain = params.arm_position_gain * self._limit
        self._arm_velocity_gain = params.arm_velocity_gain * self._limit
        self._swing_limit = min(self._limit, params.swing_torque_limit or self._limit)
        self._compensate = bool(friction_compensation)
        self._estimate_port = self.DeclareVectorInputPort("state_estimate", 4)
        self._friction_port = self.DeclareVectorInputPort("friction_compensation_Nm", 1)
        self._command = self.DeclareDiscreteState(1)
        self._mode = self.DeclareDiscreteState(1)
        self._energy = self.DeclareDiscreteState(1)
        self._arm_reference = self.DeclareDiscreteState(1)
        self._arm_decay = math.exp(-period / params.arm_return_time)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.DeclareStateOutputPort("arm_torque_Nm", self._command)
        self.DeclareStateOutputPort("swingup_mode", self._mode)
        self.DeclareStateOutputPort("pendulum_energy_J", self._energy)

    def _update(self, context, discrete_state):
        theta, phi, theta_dot, phi_dot = self._estimate_port.Eval(context)
        p = self._p
        theta_w = (theta + math.pi) % (2.0 * math.pi) - math.pi
        cos_theta = math.cos(theta_w)
        energy = self._half_inertia * theta_dot * theta_dot + self._mgl * (cos_theta - 1.0)
        mode = context.get_discrete_state(self._mode).GetAtIndex(0)
        arm_reference = context.get_discrete_state(self._arm_reference).GetAtIndex(0) * self._arm_decay
        if mode == SWING and abs(theta_w) < p.catch_angle and abs(energy) < self._catch_energy:
            # Hand over only where the LQR, with its arm reference at the catch, is not saturated.
            u_catch = (
                self._negative_gain[0] * theta_w + self._negative_gain[2] * theta_dot + self._negative_gain[3] * phi_dot
            )
            if abs(u_catch) < self._catch_torque:
                mode, arm_reference = BALANCE, phi
        elif mode == BALANCE and abs(theta_w) > p.release_angle:
            mode = SWING
        if mode == BALANCE:
            u = (
                self._negative_gain[0] * theta_w
                + self._negative_gain[1] * (phi - arm_reference)
                + self._negative_gain[2] * theta_dot
                + self._negative_gain[3] * phi_dot
            )
        else:
            # sign(0) = +1: from rest at the bottom the first command is a kick, not an equilibrium.
            direction = 1.0 if self._pump_sign * theta_dot * cos_theta >= 0.0 else -1.0
            u = (
                p.energy_gain * (self._energy_reference - energy) * direction
                - self._arm_position_gain * phi
                - self._arm_velocity_gain * phi_dot
            )
            u = min(max(u, -self._swing_limit), self._swing_limit)
        if self._compensate and self._friction_port.HasValue(context):
            u -= self._friction_port.Eval(context)[0]
        u = min(max(u, -self._limit), self._limit)
        discrete_state.get_mutable_vector(self._command).SetAtIndex(0, u)
        discrete_state.get_mutable_vector(self._mode).SetAtIndex(0, mode)
        discrete_state.get_mutable_vector(self._energy).SetAtIndex(0, energy)
        discrete_state.get_mutable_vector(self._arm_reference).SetAtIndex(0, arm_reference)


def kinematic_model() -> tuple[np.ndarray, np.ndarray]:
    """(A, B_F) of two free double integrators in the paper's order: the gravity- and input-free model of the
    swing-up's high-gain velocity observer."""
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    return A, np.zeros((4, 2))


def catch_time(result) -> float:
    """Time [s] of the last hand-over to the LQR (``swingup_mode`` rising to 1) in a swing-up run's
    :class:`~furuta_drake.simulate.SimulationResult`, NaN when it never caught."""
    mode = result.signals["swingup_mode"][:, 0]
    if mode[-1] != BALANCE:
        return math.nan
    rises = np.flatnonzero(np.diff(mode) > 0)
    return float(result.time[rises[-1] + 1]) if rises.size else float(result.time[0])


__all__ = [
    "SwingUpParameters",
    "EnergySwingUpController",
    "pendulum_energy",
    "wrap_angle",
    "kinematic_model",
    "catch_time",
]
