"""K_sigma adaptation, paper Eq. 16-18 and Sec. V-C.

The Dahl observer's estimate is scaled by K_sigma (F_hat = -K_sigma sigma0 z_hat, Eq. 16 as NOTES.md reads
it). The VFE observer's eps_hat_F estimates the friction error e = F - F_hat, whose sensitivity is
de/dK_sigma = sigma0 z_hat, so the gradient law Eq. 17, dK_sigma/dt = -gamma e de/dK_sigma, is Eq. 18 as
printed: dK_sigma/dt = -gamma eps_hat_F sigma0 z_hat. As in Sec. V-C there are two gains, K_sigma+ used while
the velocity estimate is positive and K_sigma- otherwise; the active one adapts only while |v| exceeds
``velocity_threshold`` (enough excitation, one sign held) and from ``enable_time`` on (t = 7.8 s in Sec. V-D).

Discrete at the control period h, explicit Euler (:func:`adapting_branch`, :func:`k_sigma_step`). Near steady
sliding sigma0 z_hat ~ Fc sign(v) and e ~ F - K_sigma sigma0 z_hat, so the law is linear in K_sigma with rate
gamma (sigma0 z_hat)^2 ~ gamma Fc^2: Euler is stable for h gamma Fc^2 < 2 and monotone below 1. The default
gamma = 5000 / ((N m)^2 s) gives 0.7-1.6 1/s at the paper's 0.012-0.018 N m (h gamma Fc^2 ~ 1e-3, far inside
the bound), an adaptation much slower than the VFE's eps_hat_F (eigenvalues of 20 1/s and faster), as Sec. V-B
requires. In a closed loop the diagram runs Eq. 18 inside the Dahl observer (:class:`KSigmaDahlObserver`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pydrake.systems.framework import BasicVector, LeafSystem

from furuta_drake.errors import ConfigError
from furuta_drake.observers.dahl import DahlFrictionObserver, DahlObserverParameters


@dataclass
class KSigmaAdaptationParameters:
    """Eq. 18's gain and the Sec. V-C activation conditions."""

    gamma: float = 5000.0  # adaptation gain [1 / ((N m)^2 s)]
    velocity_threshold: float = 0.1  # adapt only while |v| > this [rad/s]
    enable_time: float = 0.0  # adapt only from this time on [s]
    initial: float = 1.0  # K_sigma+ and K_sigma- at t = 0 [-]
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
    """Eq. 18 with the Sec. V-C branches, discrete at ``params.period``; ``sigma0`` [N m/rad] is the Dahl
    observer's bristle stiffness.

    Inputs: ``arm_velocity_estimate_rad_per_s`` (v), ``friction_error_estimate_Nm`` (the VFE's eps_hat_F =
    [pendulum, arm]; the arm entry drives the law), ``bristle_state_rad`` (the Dahl observer's z_hat). State
    [K_sigma+, K_sigma-]. Outputs: ``K_sigma`` (K_sigma+ while v > 0, else K_sigma-; feeds through v only) and
    ``K_sigma_branches`` ([K_sigma+, K_sigma-]).
    """

    def __init__(self, params: KSigmaAdaptationParameters | None = None, *, sigma0: float):
        LeafSystem.__init__(self)
        params = params or KSigmaAdaptationParameters()
        params.validate()
        if not (math.isfinite(sigma0) and sigma0 > 0):
            raise ConfigError(f"KSigmaAdapter sigma0 (the Dahl observer's) must be > 0, got {sigma0!r}")
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
        branch = 0 if self._velocity.Eval(context)[0] > 0 else 1
        output.SetAtIndex(0, context.get_discrete_state_vector().GetAtIndex(branch))

    def _update(self, context, discrete_state):
        branch = adapting_branch(self.params, context.get_time(), self._velocity.Eval(context)[0])
        if branch is None:
            return
        state = discrete_state.get_mutable_vector()
        state.SetAtIndex(branch, state.GetAtIndex(branch) + k_sigma_step(
            self.params, self.sigma0, self._error.Eval(context)[1], self._bristle.Eval(context)[0]))


class KSigmaDahlObserver(DahlFrictionObserver):
    """The arm's Dahl observer (Eq. 8-9, 16) and its K_sigma adaptation (Eq. 18, Sec. V-C) in one system: the
    same laws as a :class:`DahlFrictionObserver` driven by a :class:`KSigmaAdapter`, and the same values (both
    steps read the values held before the sample), for one Python update per sample instead of two updates and
    an output. Ports: the Dahl observer's without its ``K_sigma`` input (K_sigma is state here), plus the
    adapter's input ``friction_error_estimate_Nm`` (eps_hat_F) and output ``K_sigma_branches``. The estimate
    F_hat feeds through v, which picks the branch."""

    K_SIGMA_INPUT = False

    def __init__(self, params: DahlObserverParameters, adaptation: KSigmaAdaptationParameters):
        adaptation.validate()
        self.adaptation = adaptation
        DahlFrictionObserver.__init__(self, params)
        self._error = self.DeclareVectorInputPort("friction_error_estimate_Nm", 2)
        self._branches = self.DeclareDiscreteState([adaptation.initial, adaptation.initial])
        self.DeclareStateOutputPort("K_sigma_branches", self._branches)

    def _friction_prerequisites(self) -> set:
        return {self.xd_ticket(), self._velocity.ticket()}

    def _k_sigma_value(self, context) -> float:
        branch = 0 if self._velocity.Eval(context)[0] > 0 else 1
        return context.get_discrete_state(self._branches).GetAtIndex(branch)

    def _update(self, context, discrete_state):
        DahlFrictionObserver._update(self, context, discrete_state)
        branch = adapting_branch(self.adaptation, context.get_time(), self._velocity.Eval(context)[0])
        if branch is None:
            return
        state = discrete_state.get_mutable_vector(self._branches)
        state.SetAtIndex(branch, state.GetAtIndex(branch) + k_sigma_step(
            self.adaptation, self.params.sigma0, self._error.Eval(context)[1],
            context.get_discrete_state(0).GetAtIndex(0)))


def adapting_branch(p: KSigmaAdaptationParameters, time: float, v: float) -> int | None:
    """The K_sigma that Eq. 18 adapts over the period from ``time`` [s] at velocity estimate v [rad/s]: 0
    (K_sigma+) for v > 0, 1 (K_sigma-) for v < 0, None before ``enable_time`` or while |v| <= the threshold."""
    if time < p.enable_time or abs(v) <= p.velocity_threshold:
        return None
    return 0 if v > 0 else 1


def k_sigma_step(p: KSigmaAdaptationParameters, sigma0: float, friction_error: float, bristle: float) -> float:
    """Eq. 18 over one period (explicit Euler): -h gamma eps_hat_F sigma0 z_hat, eps_hat_F the arm entry."""
    return p.period * (-p.gamma * friction_error * sigma0 * bristle)
