"""Dahl friction observer of the arm, paper Eq. 8-9 with the adaptive gain K_sigma of Eq. 16:

    z_hat' = v - sigma0 |v| z_hat / Fc(v) + K_z,
    K_z    = -(sigma0 / rho) (1 + s1 sigma1 |v| / Fc(v)) [eps_phi + rho2 eps_v],
    F_hat  = -K_sigma sigma0 z_hat.

v is the nested velocity estimate (the VFE's arm velocity, an input port: the rig measures angles only),
eps_phi = phi - phi_ref and eps_v = v - v_ref the controller's tracking errors (reference zero when
balancing), Fc(v) the observer's Coulomb level for the sign of v. F_hat is the friction torque EXERTED on the
arm (opposite to the velocity, the package's convention), so Eq. 8's F_hat = sigma0 z_hat and Eq. 16's printed
"d/dt F_hat" are read as F_hat = -K_sigma sigma0 z_hat (NOTES.md); with this sign Eq. 18 is a gradient descent
as printed. A controller compensates with u = u_LQ - F_hat; then the printed sign of K_z is the stabilising
one: an arm displaced to phi > phi_ref at rest makes z_hat fall and F_hat grow, so u pushes it back (integral
action of gain K_sigma sigma0^2 / rho), and eps_v > 0 likewise brakes (damping).

Sign s1 of the sigma1 term (``sigma1_sign``, NOTES.md): Eq. 9 prints +. The cited design (Freidovich et al.
2006) is for LuGre, F = sigma0 z + sigma1 z' + sigma2 v = sigma0 (1 - sigma1 |v| / g(v)) z + (sigma1 + sigma2) v,
so the observer error z - z_hat reaches the motion through sigma0 (1 - sigma1 |v| / g) and the injection that
cancels that cross term in a Lyapunov function must carry the same factor: the default is s1 = -1. (The paper
was not available to check its printed form; both signs are offered.) A Dahl model has no sigma1, and the
default sigma1 = 0 makes the choice moot.

Discrete at the control period h with the inputs frozen over the period: the z equation is then linear with a
constant input, dz/dt = (v + K_z) - r z, r = sigma0 |v| / Fc, and it takes its EXACT step, the Dahl part by
:func:`furuta_drake.friction.dahl_exact_step` plus K_z (1 - e^(-r h)) / r (K_z h when v = 0). An exact
exponential step is stable at any stiffness r (the Dahl state's rate reaches 1e4 1/s at a few rad/s) where an
explicit Euler step at 1 kHz diverges once r h > 2, and it settles to the continuous steady state exactly.

Defaults: the paper's measured arm levels (0.012 N m for v > 0, 0.018 for v < 0, Sec. V-D), sigma0 = 10 N m/rad
(NOTES.md), and rho = 100 N m s/rad, rho2 = 0.1 s: a gentle injection (K_z / v of a few percent over Table I's
motion, eps_phi ~ 0.05 rad, v ~ 0.5 rad/s), so that F_hat reflects the Dahl model's calibration, as in Fig. 5.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pydrake.systems.framework import BasicVector, LeafSystem

from furuta_drake.errors import ConfigError
from furuta_drake.friction import dahl_exact_step


@dataclass
class DahlObserverParameters:
    """The observer's Dahl model (Eq. 8) and Eq. 9's design constants."""

    coulomb_pos: float = 0.012  # Fc used while v > 0 [N m]
    coulomb_neg: float = 0.018  # Fc used while v <= 0 [N m]
    sigma0: float = 10.0  # bristle stiffness [N m/rad]
    sigma1: float = 0.0  # Eq. 9's bristle damping [N m s/rad]
    sigma1_sign: int = -1  # sign of the sigma1 term of Eq. 9 (printed +1; see the module docstring)
    rho: float = 100.0  # injection scale [N m s/rad]: K_z = -(sigma0/rho) (...) [eps_phi + rho2 eps_v]
    rho2: float = 0.1  # velocity-error weight [s]
    period: float = 1e-3  # [s]

    def validate(self, where: str = "observers.dahl") -> None:
        for name in ("coulomb_pos", "coulomb_neg", "sigma0", "rho", "period"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{where}.{name} must be > 0, got {value!r}")
        for name in ("sigma1", "rho2"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"{where}.{name} must be >= 0, got {value!r}")
        if self.sigma1_sign not in (1, -1):
            raise ConfigError(f"{where}.sigma1_sign must be 1 or -1, got {self.sigma1_sign!r}")


class DahlFrictionObserver(LeafSystem):
    """Eq. 8-9, 16 of the arm joint, discrete at ``params.period`` (exact step, see the module docstring).

    Inputs: ``arm_velocity_estimate_rad_per_s`` (v), ``measured_angles_rad`` ([theta, phi]; phi gives
    eps_phi), ``arm_reference_rad`` ([phi_ref [rad], v_ref [rad/s]], zero if unconnected), ``K_sigma`` (1 if
    unconnected; the adapter drives it). State z_hat [rad]. Outputs: ``friction_estimate_Nm`` (F_hat =
    -K_sigma sigma0 z_hat [N m], the arm friction; feeds through K_sigma only) and ``bristle_state_rad``.
    """

    def __init__(self, params: DahlObserverParameters | None = None):
        LeafSystem.__init__(self)
        params = params or DahlObserverParameters()
        params.validate()
        self.params = params
        self._velocity = self.DeclareVectorInputPort("arm_velocity_estimate_rad_per_s", 1)
        self._angles = self.DeclareVectorInputPort("measured_angles_rad", 2)
        self._reference = self.DeclareVectorInputPort("arm_reference_rad", 2)
        self._k_sigma = self.DeclareVectorInputPort("K_sigma", 1)
        state = self.DeclareDiscreteState(1)
        self.DeclarePeriodicDiscreteUpdateEvent(params.period, 0.0, self._update)
        self.DeclareVectorOutputPort("friction_estimate_Nm", 1, self._calc_friction,
                                     prerequisites_of_calc={self.xd_ticket(), self._k_sigma.ticket()})
        self.DeclareStateOutputPort("bristle_state_rad", state)

    def _calc_friction(self, context, output: BasicVector):
        k_sigma = self._k_sigma.Eval(context)[0] if self._k_sigma.HasValue(context) else 1.0
        output.SetAtIndex(0, -k_sigma * self.params.sigma0 * context.get_discrete_state_vector().GetAtIndex(0))

    def _update(self, context, discrete_state):
        p = self.params
        v = self._velocity.Eval(context)[0]
        phi = self._angles.Eval(context)[1]
        phi_ref, v_ref = self._reference.Eval(context) if self._reference.HasValue(context) else (0.0, 0.0)
        z = context.get_discrete_state_vector().GetAtIndex(0)
        level = p.coulomb_pos if v > 0 else p.coulomb_neg
        k_z = -(p.sigma0 / p.rho) * (1.0 + p.sigma1_sign * p.sigma1 * abs(v) / level) * (
            (phi - phi_ref) + p.rho2 * (v - v_ref))
        rate = p.sigma0 * abs(v) / level
        held_input_gain = -math.expm1(-rate * p.period) / rate if rate > 0 else p.period  # int_0^h e^(-r s) ds
        z_next = float(dahl_exact_step(z, v, p.period, p.sigma0, level)) + held_input_gain * k_z
        discrete_state.get_mutable_vector().SetAtIndex(0, z_next)
