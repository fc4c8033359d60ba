"""The parameter adaptation law of the Dahl observer (Sec. VII's open point): adapting sigma0 and Fc, not one
gain. The observer's parameters theta = [Fc+, Fc-, sigma0] follow a gradient law on the VFE's friction-error
estimate, with a persistence-of-excitation check that freezes what the data cannot identify.

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
presliding transient of a few tens of ms meets an error that arrives later, and sigma0 settles low. In steady
sliding F_hat = -Fc sign(v) does not depend on sigma0: only the presliding transients after a velocity reversal
carry sigma0, and only sliding in one direction carries that direction's Fc. The excitation check is the
windowed mean of psi_i^2 (exponential window ``excitation_window``); a parameter adapts only while it exceeds
``excitation_threshold`` times the square of the observer's own Coulomb level, i.e. while the data say
something about it. The one-gain law (Eq. 18) scales Fc and sigma0 together and so cannot move their ratio, the
presliding displacement Fc / sigma0.

The law is its own system, :class:`DahlParameterAdapter`, beside the Dahl observer
(:class:`furuta_drake.observers.dahl.DahlFrictionObserver`): it reads the observer's z_hat and injection K_z and
gives it the adapted [Fc+, Fc-, sigma0].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem

from furuta_drake.controllers.lqr import zero_order_hold
from furuta_drake.errors import ConfigError
from furuta_drake.friction import held_input_gain

# The adapter's state: the log-parameters, their sensitivities, the excitation measures, then the three
# regressors' filter states (6 each, H's state w per parameter, in parameter order).
LOG_FC_POS, LOG_FC_NEG, LOG_SIGMA0, S_FC_POS, S_FC_NEG, S_SIGMA0, PE_FC_POS, PE_FC_NEG, PE_SIGMA0 = range(9)
LOGS = [LOG_FC_POS, LOG_FC_NEG, LOG_SIGMA0]
EXCITATION = [PE_FC_POS, PE_FC_NEG, PE_SIGMA0]
FILTERS = slice(9, 27)


@dataclass
class ParameterAdaptationParameters:
    """Gains and excitation check of the adaptation of [Fc+, Fc-, sigma0]."""

    gamma_coulomb: float = 3.0e4  # gain of d ln Fc / dt [1/((N m)^2 s)]
    gamma_sigma0: float = 1.0e5  # gain of d ln sigma0 / dt [1/((N m)^2 s)]
    enable_time: float = 7.8  # [s] as the paper's K_sigma adaptation (Sec. V-D)
    velocity_threshold: float = 0.02  # adapt only while |v| > this [rad/s]
    excitation_window: float = 1.0  # time constant of the windowed mean of psi^2 [s]
    excitation_threshold: float = 0.02  # adapt theta_i while mean(psi_i^2) > this * Fc^2 [-]

    def validate(self, where: str = "observers.dahl.adaptation.parameters") -> None:
        for name in (
            "gamma_coulomb",
            "gamma_sigma0",
            "velocity_threshold",
            "excitation_window",
            "excitation_threshold",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{where}.{name} must be > 0, got {value!r}")
        if not (math.isfinite(self.enable_time) and self.enable_time >= 0):
            raise ConfigError(f"{where}.enable_time must be >= 0, got {self.enable_time!r}")


def initial_state(coulomb_pos: float, coulomb_neg: float, sigma0: float) -> list[float]:
    """The adapter's state at t = 0: the log-parameters of the observer's Dahl model [N m, N m, N m/rad], zero
    sensitivities, excitation measures and filter states."""
    state = [0.0] * FILTERS.stop
    state[LOG_FC_POS], state[LOG_FC_NEG] = math.log(coulomb_pos), math.log(coulomb_neg)
    state[LOG_SIGMA0] = math.log(sigma0)
    return state


def adapted_model(x: np.ndarray, v: float) -> tuple[float, float]:
    """(sigma0 [N m/rad], the Coulomb level of v's direction [N m]) that the state ``x`` holds."""
    return math.exp(x[LOG_SIGMA0]), math.exp(x[LOG_FC_POS if v > 0 else LOG_FC_NEG])


class ParameterAdaptationLaw:
    """One period of the law (module docstring) for an observer sampled at ``period`` [s] whose eps_hat_F comes
    from a VFE observer with error response ``error_response`` = (M, N) of ``vfe.friction_error_response``."""

    def __init__(self, params: ParameterAdaptationParameters, error_response, period: float):
        params.validate()
        self.params, self.period = params, period
        self._forget = math.exp(-period / params.excitation_window)
        M, N = error_response
        self._filter_a, filter_b = zero_order_hold(M, N, period)
        self._filter_b = filter_b[:, 0]

    def step(
        self,
        x: np.ndarray,
        *,
        z: float,
        v: float,
        sigma0: float,
        level: float,
        k_z: float,
        time: float,
        friction_error: float,
    ) -> None:
        """Advance the state ``x`` (in place) over one period from ``time`` [s] along the observer's z_hat ``z``
        [rad] and its injection ``k_z`` [rad/s] of Eq. 9: the sensitivities, filters and excitation measures, and
        the log-parameters where the data excite them. ``sigma0`` and ``level`` are :func:`adapted_model` of
        ``x``, v [rad/s] the velocity estimate, ``friction_error`` [N m] the arm entry of eps_hat_F."""
        a, h = self.params, self.period
        log_fc, s_fc = (LOG_FC_POS, S_FC_POS) if v > 0 else (LOG_FC_NEG, S_FC_NEG)
        # Regressors psi = theta dF_hat/dtheta (log-parameters), filtered by H like eps_hat_F, and the excitation.
        psi = np.zeros(3)
        psi[LOGS.index(log_fc)] = -sigma0 * level * x[s_fc]
        psi[2] = -sigma0 * (z + sigma0 * x[S_SIGMA0])
        filters = x[FILTERS].reshape(6, 3)  # column i: H's state for parameter i (a view of x)
        filtered = filters[5]  # H's output, the arm entry of eps_hat_F: read after the filters' step below
        x[FILTERS] = (self._filter_a @ filters + np.outer(self._filter_b, psi)).ravel()
        x[EXCITATION] = self._forget * x[EXCITATION] + (1.0 - self._forget) * filtered**2
        # Propagate the sensitivities over the period with the current parameters (exact steps, as z_hat's).
        rate = sigma0 * abs(v) / level
        gain = held_input_gain(rate, h)
        decay = math.exp(-rate * h)
        x[S_FC_POS] *= decay
        x[S_FC_NEG] *= decay
        x[s_fc] += gain * sigma0 * abs(v) * z / level**2
        x[S_SIGMA0] = decay * x[S_SIGMA0] + gain * (-abs(v) * z / level + k_z / sigma0)
        # Eq. 17 on the log-parameters, e = F_hat - F ~ -eps_hat_F, where the data excite them.
        if time >= a.enable_time and abs(v) > a.velocity_threshold:
            e = -friction_error
            floor = a.excitation_threshold * level * level
            for i, (index, gamma) in enumerate(zip(LOGS, (a.gamma_coulomb, a.gamma_coulomb, a.gamma_sigma0))):
                if x[PE_FC_POS + i] > floor:
                    x[index] -= h * gamma * e * filtered[i]


class DahlParameterAdapter(LeafSystem):
    """The law of the module docstring as a system, discrete at the control period ``period`` [s], for the Dahl
    observer of ``coulomb_pos``, ``coulomb_neg`` [N m] and ``sigma0`` [N m/rad] whose eps_hat_F comes from a VFE
    observer with error response ``error_response`` (M, N).

    Inputs: ``arm_velocity_estimate_rad_per_s`` (v), ``bristle_state_rad`` (z_hat), ``bristle_injection_rad_per_s``
    (K_z) and ``friction_error_estimate_Nm`` (eps_hat_F = [pendulum, arm] [N m]). Discrete state: the entries
    above. Outputs: ``dahl_parameters`` ([Fc+ [N m], Fc- [N m], sigma0 [N m/rad]], which the observer runs on)
    and ``parameter_excitation`` (the windowed mean of psi^2 per parameter [(N m)^2]).
    """

    def __init__(
        self,
        params: ParameterAdaptationParameters,
        *,
        period: float,
        coulomb_pos: float,
        coulomb_neg: float,
        sigma0: float,
        error_response,
    ):
        LeafSystem.__init__(self)
        self._law = ParameterAdaptationLaw(params, error_response, period)
        self._velocity = self.DeclareVectorInputPort("arm_velocity_estimate_rad_per_s", 1)
        self._bristle = self.DeclareVectorInputPort("bristle_state_rad", 1)
        self._injection = self.DeclareVectorInputPort("bristle_injection_rad_per_s", 1)
        self._error = self.DeclareVectorInputPort("friction_error_estimate_Nm", 2)
        self.DeclareDiscreteState(initial_state(coulomb_pos, coulomb_neg, sigma0))
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        xd = {self.xd_ticket()}
        self.DeclareVectorOutputPort("dahl_parameters", 3, self._calc_parameters, prerequisites_of_calc=xd)
        self.DeclareVectorOutputPort("parameter_excitation", 3, self._calc_excitation, prerequisites_of_calc=xd)

    def _calc_parameters(self, context, output: BasicVector):
        x = context.get_discrete_state_vector().value()
        output.SetFromVector([math.exp(x[index]) for index in LOGS])

    def _calc_excitation(self, context, output: BasicVector):
        output.SetFromVector(context.get_discrete_state_vector().value()[EXCITATION])

    def _update(self, context, discrete_state):
        x = context.get_discrete_state_vector().value().copy()
        v = self._velocity.Eval(context)[0]
        sigma0, level = adapted_model(x, v)
        self._law.step(
            x,
            z=self._bristle.Eval(context)[0],
            v=v,
            sigma0=sigma0,
            level=level,
            k_z=self._injection.Eval(context)[0],
            time=context.get_time(),
            friction_error=self._error.Eval(context)[1],
        )
        discrete_state.get_mutable_vector().SetFromVector(x)


__all__ = [
    "DahlParameterAdapter",
    "ParameterAdaptationParameters",
    "ParameterAdaptationLaw",
    "adapted_model",
    "initial_state",
]
