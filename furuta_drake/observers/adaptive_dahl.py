"""Adapting sigma0 and Fc, not one gain (Sec. VII's open point): the Dahl observer of Eq. 8-9 whose parameters
theta = [Fc+, Fc-, sigma0] follow a gradient law on the VFE's friction-error estimate, with a
persistence-of-excitation check that freezes what the data cannot identify.

Eq. 17 with e = F_hat - F ~ -eps_hat_F (the VFE's estimate of F - F_hat, arm entry) and the sensitivities
of F_hat = -sigma0 z_hat instead of the single K_sigma:

    d ln(theta_i)/dt = -gamma_i e psi_i,   psi_i = theta_i dF_hat/dtheta_i,

in logarithms so that Fc (~0.01 N m) and sigma0 (~10 N m/rad) adapt at comparable relative rates and stay
positive. The sensitivities s_i = dz_hat/dtheta_i follow the derivative of Eq. 8 along the trajectory,

    s_c' = -r s_c + sigma0 |v| z_hat / Fc^2   (the Fc of v's direction; the other's decays: s' = -r s),
    s_s' = -r s_s - |v| z_hat / Fc + K_z / sigma0,     r = sigma0 |v| / Fc,

so dF_hat/dFc = -sigma0 s_c and dF_hat/dsigma0 = -z_hat - sigma0 s_s; they take the same exact exponential
step as z_hat (frozen inputs over a period). The error eps_hat_F is not F - F_hat itself but its response
through the VFE's error dynamics H (``vfe.friction_error_response``, DC gain 1, poles eig(G) of Eq. 12), so
each regressor is passed through the same H (the filtered-regressor form of Eq. 17): with the raw regressors a
presliding transient of a few tens of ms meets an error that arrives later, and sigma0 settles 35-40 % low on
the paper's rig. In steady sliding F_hat = -Fc sign(v) does not depend on sigma0:
only the presliding transients after a velocity reversal carry sigma0, and only sliding in one direction
carries that direction's Fc. The excitation check is the windowed mean of psi_i^2 (exponential window
``excitation_window``); a parameter adapts only while it exceeds ``excitation_threshold`` times the square of
the observer's own Coulomb level, i.e. while the data say something about it. The one-gain law (Eq. 18)
scales Fc and sigma0 together and so cannot move their ratio, the presliding displacement Fc / sigma0.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import BasicVector

from furuta_drake.controllers.lqr import zero_order_hold
from furuta_drake.errors import ConfigError
from furuta_drake.friction import dahl_exact_step
from furuta_drake.observers.dahl import DahlFrictionObserver, DahlObserverParameters, held_input_gain, injection

# State layout: the bristle, the log-parameters, their sensitivities, the excitation measures, then the three
# regressors' filter states (6 each, H's state w per parameter, in parameter order).
Z, LOG_FC_POS, LOG_FC_NEG, LOG_SIGMA0, S_FC_POS, S_FC_NEG, S_SIGMA0, PE_FC_POS, PE_FC_NEG, PE_SIGMA0 = range(10)
LOGS = [LOG_FC_POS, LOG_FC_NEG, LOG_SIGMA0]
FILTERS = slice(10, 28)


@dataclass
class DahlAdaptationParameters:
    """Gains and excitation check of the two-parameter (three with the two directions) adaptation."""

    gamma_coulomb: float = 3.0e4  # gain of d ln Fc / dt [1/((N m)^2 s)]
    gamma_sigma0: float = 1.0e5  # gain of d ln sigma0 / dt [1/((N m)^2 s)]
    enable_time: float = 7.8  # [s] as the paper's K_sigma adaptation (Sec. V-D)
    velocity_threshold: float = 0.02  # adapt only while |v| > this [rad/s]
    excitation_window: float = 1.0  # time constant of the windowed mean of psi^2 [s]
    excitation_threshold: float = 0.02  # adapt theta_i while mean(psi_i^2) > this * Fc^2 [-]

    def validate(self, where: str = "observers.dahl_adaptation") -> None:
        for name in ("gamma_coulomb", "gamma_sigma0", "velocity_threshold", "excitation_window",
                     "excitation_threshold"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{where}.{name} must be > 0, got {value!r}")
        if not (math.isfinite(self.enable_time) and self.enable_time >= 0):
            raise ConfigError(f"{where}.enable_time must be >= 0, got {self.enable_time!r}")


class AdaptiveDahlObserver(DahlFrictionObserver):
    """The arm's Dahl observer (Eq. 8-9) with on-line [Fc+, Fc-, sigma0] (module docstring); the initial values
    are ``params``'. ``error_response`` is (M, N) of ``vfe.friction_error_response`` for the VFE observer that
    feeds eps_hat_F. Ports as :class:`DahlFrictionObserver`, plus input ``friction_error_estimate_Nm`` (the
    VFE's eps_hat_F = [pendulum, arm]) and outputs ``dahl_parameters`` ([Fc+ [N m], Fc- [N m], sigma0
    [N m/rad]]) and ``parameter_excitation`` (the windowed mean of psi^2 per parameter, [(N m)^2])."""

    def __init__(self, params: DahlObserverParameters, adaptation: DahlAdaptationParameters, error_response):
        if params.sigma1 > 0 or params.sigma2 > 0 or params.static_pos is not None or params.static_neg is not None:
            raise ConfigError("observers.dahl: parameter adaptation adapts a Dahl model (no Stribeck levels, "
                              "sigma1 or sigma2)")
        adaptation.validate()
        DahlFrictionObserver.__init__(self, params)
        self.adaptation = adaptation
        self._error = self.DeclareVectorInputPort("friction_error_estimate_Nm", 2)
        self.DeclareVectorOutputPort("dahl_parameters", 3, self._calc_parameters,
                                     prerequisites_of_calc={self.xd_ticket()})
        self.DeclareVectorOutputPort("parameter_excitation", 3, self._calc_excitation,
                                     prerequisites_of_calc={self.xd_ticket()})
        self._forget = math.exp(-params.period / adaptation.excitation_window)
        M, N = error_response
        self._filter_a, filter_b = zero_order_hold(M, N, params.period)
        self._filter_b = filter_b[:, 0]

    def _initial_state(self, params: DahlObserverParameters) -> list[float]:
        state = [0.0] * FILTERS.stop
        state[LOG_FC_POS], state[LOG_FC_NEG] = math.log(params.coulomb_pos), math.log(params.coulomb_neg)
        state[LOG_SIGMA0] = math.log(params.sigma0)
        return state

    def _calc_friction(self, context, output: BasicVector):
        k_sigma = self._k_sigma.Eval(context)[0] if self._k_sigma.HasValue(context) else 1.0
        x = context.get_discrete_state_vector().value()
        output.SetAtIndex(0, -k_sigma * math.exp(x[LOG_SIGMA0]) * x[Z])

    def _calc_parameters(self, context, output: BasicVector):
        x = context.get_discrete_state_vector().value()
        output.SetFromVector(np.exp(x[[LOG_FC_POS, LOG_FC_NEG, LOG_SIGMA0]]))

    def _calc_excitation(self, context, output: BasicVector):
        output.SetFromVector(context.get_discrete_state_vector().value()[[PE_FC_POS, PE_FC_NEG, PE_SIGMA0]])

    def _update(self, context, discrete_state):
        p, a, h = self.params, self.adaptation, self.params.period
        x = context.get_discrete_state_vector().value().copy()
        v = self._velocity.Eval(context)[0]
        z = x[Z]
        sigma0 = math.exp(x[LOG_SIGMA0])
        log_fc, s_fc, pe_fc = (LOG_FC_POS, S_FC_POS, PE_FC_POS) if v > 0 else (LOG_FC_NEG, S_FC_NEG, PE_FC_NEG)
        level = math.exp(x[log_fc])
        # Regressors psi = theta dF_hat/dtheta (log-parameters), filtered by H like eps_hat_F, and the excitation.
        psi = np.zeros(3)
        psi[LOGS.index(log_fc)] = -sigma0 * level * x[s_fc]
        psi[2] = -sigma0 * (z + sigma0 * x[S_SIGMA0])
        filters = x[FILTERS].reshape(6, 3)  # column i: H's state for parameter i
        filtered = filters[5]  # H's output, the arm entry of eps_hat_F
        x[FILTERS] = (self._filter_a @ filters + np.outer(self._filter_b, psi)).ravel()
        x[[PE_FC_POS, PE_FC_NEG, PE_SIGMA0]] = (self._forget * x[[PE_FC_POS, PE_FC_NEG, PE_SIGMA0]]
                                                + (1.0 - self._forget) * filtered**2)
        # Propagate z_hat and the sensitivities over the period with the current parameters (exact steps).
        rate = sigma0 * abs(v) / level
        gain = held_input_gain(rate, h)
        decay = math.exp(-rate * h)
        k_z = injection(p, sigma0, v, level, *self.tracking_errors(context)) if p.rho is not None else 0.0
        x[Z] = float(dahl_exact_step(z, v, h, sigma0, level)) + gain * k_z
        x[S_FC_POS] *= decay
        x[S_FC_NEG] *= decay
        x[s_fc] += gain * sigma0 * abs(v) * z / level**2
        x[S_SIGMA0] = decay * x[S_SIGMA0] + gain * (-abs(v) * z / level + k_z / sigma0)
        # Eq. 17 on the log-parameters, e = F_hat - F ~ -eps_hat_F, where the data excite them.
        if context.get_time() >= a.enable_time and abs(v) > a.velocity_threshold:
            e = -self._error.Eval(context)[1]
            floor = a.excitation_threshold * level * level
            for i, (index, gamma) in enumerate(zip(LOGS, (a.gamma_coulomb, a.gamma_coulomb, a.gamma_sigma0))):
                if x[PE_FC_POS + i] > floor:
                    x[index] -= h * gamma * e * filtered[i]
        discrete_state.get_mutable_vector().SetFromVector(x)
