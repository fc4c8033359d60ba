"""K_sigma adaptation, paper Eq. 16-18 and Sec. V-C.

The Dahl observer's estimate is scaled by K_sigma (F_hat = -K_sigma sigma0 z_hat, Eq. 16); the gradient law
Eq. 18, dK_sigma/dt = -gamma eps_hat_F sigma0 z_hat, drives the VFE's friction-error estimate eps_hat_F (arm
entry) to zero. As in Sec. V-C there are two gains, K_sigma+ used while the velocity estimate is positive and
K_sigma- while it is negative; each adapts only while |v| exceeds ``velocity_threshold`` (enough excitation,
one sign held) and after ``enable_time``. Discrete at the control period (explicit Euler: the law's rate
gamma (sigma0 z_hat)^2 is far below 2 / period for the gains used here, so the step is stable).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pydrake.systems.framework import BasicVector, LeafSystem

from furuta_drake.errors import ConfigError


@dataclass
class KSigmaAdaptationParameters:
    gamma: float = 5000.0  # adaptation gain [1 / (N m)^2 / s]
    velocity_threshold: float = 0.1  # [rad/s]
    enable_time: float = 0.0  # [s]
    initial: float = 1.0
    period: float = 1e-3  # [s]

    def validate(self, where: str = "observers.adaptation") -> None:
        for name in ("gamma", "velocity_threshold", "enable_time"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"{where}.{name} must be >= 0, got {value!r}")
        for name in ("initial", "period"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{where}.{name} must be > 0, got {value!r}")


class KSigmaAdapter(LeafSystem):
    """Inputs ``arm_velocity_estimate_rad_per_s``, ``friction_error_estimate_Nm`` (the VFE's eps_hat_F, the arm
    entry is used) and ``bristle_state_rad`` (z_hat); state [K_sigma+, K_sigma-]; outputs ``K_sigma`` (the
    branch of the velocity's sign) and ``K_sigma_branches``."""

    def __init__(self, params: KSigmaAdaptationParameters | None = None, *, sigma0: float):
        LeafSystem.__init__(self)
        params = params or KSigmaAdaptationParameters()
        params.validate()
        if not (math.isfinite(sigma0) and sigma0 > 0):
            raise ConfigError(f"observers.dahl.sigma0 must be > 0, got {sigma0!r}")
        self.params, self.sigma0 = params, sigma0
        self._velocity = self.DeclareVectorInputPort("arm_velocity_estimate_rad_per_s", 1)
        self._error = self.DeclareVectorInputPort("friction_error_estimate_Nm", 2)
        self._bristle = self.DeclareVectorInputPort("bristle_state_rad", 1)
        state = self.DeclareDiscreteState([params.initial, params.initial])
        self.DeclarePeriodicDiscreteUpdateEvent(params.period, 0.0, self._update)
        self.DeclareVectorOutputPort("K_sigma", 1, self._calc_gain,
                                     prerequisites_of_calc={self.xd_ticket(), self._velocity.ticket()})
        self.DeclareStateOutputPort("K_sigma_branches", state)

    def _calc_gain(self, context, output: BasicVector):
        branches = context.get_discrete_state_vector()
        output.SetAtIndex(0, branches.GetAtIndex(0 if self._velocity.Eval(context)[0] > 0 else 1))

    def _update(self, context, discrete_state):
        p = self.params
        v = self._velocity.Eval(context)[0]
        if context.get_time() < p.enable_time or abs(v) <= p.velocity_threshold:
            return
        branch = 0 if v > 0 else 1
        state = discrete_state.get_mutable_vector()
        rate = -p.gamma * self._error.Eval(context)[1] * self.sigma0 * self._bristle.Eval(context)[0]
        state.SetAtIndex(branch, state.GetAtIndex(branch) + p.period * rate)
