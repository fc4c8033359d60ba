"""Dahl friction observer of the arm, paper Eq. 8-9 with the adaptive gain of Eq. 16:

    z_hat' = v - sigma0 |v| z_hat / Fc(v) + K_z(v),
    K_z    = -(sigma0 / rho) (1 + s1 sigma1 |v| / Fc) [eps_phi + rho2 eps_v],
    F_hat  = -K_sigma sigma0 z_hat.

v is the nested velocity estimate (the VFE's arm velocity, an input port), eps_phi = phi - phi_ref and
eps_v = v - v_ref the controller's tracking errors (reference zero when balancing). F_hat is the friction
torque exerted on the arm (opposite to the velocity, the package's convention), so Eq. 16's printed
"d/dt F_hat" is read as F_hat = K_sigma sigma0 z_hat with that sign (NOTES.md), which makes Eq. 18 a gradient
descent as printed. The sign s1 of the sigma1 term is a parameter (NOTES.md: printed +; sigma1 = 0 by default,
where it does not matter).

Discrete at the control period: z_hat takes the EXACT exponential step of the Dahl equation at frozen v
(:func:`furuta_drake.friction.dahl_exact_step`), stable at 1 kHz for any stiffness sigma0 |v| / Fc, plus the
K_z term held over the period.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from furuta_drake.errors import ConfigError
from furuta_drake.friction import dahl_exact_step


@dataclass
class DahlObserverParameters:
    """The observer's Dahl model (levels [N m] per direction, sigma0 [N m/rad]), Eq. 9's design constants."""

    coulomb_pos: float = 0.012  # Fc used for v > 0 [N m]
    coulomb_neg: float = 0.018  # Fc used for v < 0 [N m]
    sigma0: float = 10.0  # [N m/rad]
    sigma1: float = 0.0  # [N m s/rad]
    sigma1_sign: int = 1
    rho: float = 100.0  # [N m s / rad]... scales the tracking-error injection K_z
    rho2: float = 0.1  # [s]
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
    """Eq. 8-9, 16. Inputs ``arm_velocity_estimate_rad_per_s`` (v), ``measured_angles_rad`` (phi is entry 1),
    ``arm_reference_rad`` ([phi_ref, v_ref], zero if unconnected), ``K_sigma`` (1 if unconnected); outputs
    ``friction_estimate_Nm`` (F_hat) and ``bristle_state_rad`` (z_hat)."""

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
                                     prerequisites_of_calc={self.xd_ticket(),
                                                            self._k_sigma.ticket()})
        self.DeclareStateOutputPort("bristle_state_rad", state)

    def _gain(self, context) -> float:
        return self._k_sigma.Eval(context)[0] if self._k_sigma.HasValue(context) else 1.0

    def _calc_friction(self, context, output: BasicVector):
        z = context.get_discrete_state_vector().GetAtIndex(0)
        output.SetAtIndex(0, -self._gain(context) * self.params.sigma0 * z)

    def _update(self, context, discrete_state):
        p = self.params
        v = self._velocity.Eval(context)[0]
        phi = self._angles.Eval(context)[1]
        phi_ref, v_ref = self._reference.Eval(context) if self._reference.HasValue(context) else (0.0, 0.0)
        z = context.get_discrete_state_vector().GetAtIndex(0)
        level = p.coulomb_pos if v > 0 else p.coulomb_neg
        k_z = -(p.sigma0 / p.rho) * (1.0 + p.sigma1_sign * p.sigma1 * abs(v) / level) * (
            (phi - phi_ref) + p.rho2 * (v - v_ref))
        z_next = float(dahl_exact_step(np.float64(z), np.float64(v), p.period, p.sigma0, level)) + p.period * k_z
        discrete_state.get_mutable_vector().SetAtIndex(0, z_next)
