"""The K_sigma adaptation law of the Dahl observer, paper Eq. 16-18 and Sec. V-C.

The Dahl observer's estimate is scaled by K_sigma (F_hat = -K_sigma sigma0 z_hat, Eq. 16 as ``docs/paper.md``
reads it). The VFE observer's eps_hat_F estimates the friction error e = F - F_hat, whose sensitivity is
de/dK_sigma = sigma0 z_hat, so the gradient law Eq. 17, dK_sigma/dt = -gamma e de/dK_sigma, is Eq. 18 as
printed: dK_sigma/dt = -gamma eps_hat_F sigma0 z_hat. As in Sec. V-C there are two gains, K_sigma+ used while
the velocity estimate is positive and K_sigma- otherwise; the active one adapts only while |v| exceeds
``velocity_threshold`` (enough excitation, one sign held) and from ``enable_time`` on (t = 7.8 s in Sec. V-D).

Discrete at the control period h, explicit Euler (:func:`adapting_branch`, :func:`k_sigma_step`). Near steady
sliding sigma0 z_hat ~ Fc sign(v) and e ~ F - K_sigma sigma0 z_hat, so the law is linear in K_sigma with rate
gamma (sigma0 z_hat)^2 ~ gamma Fc^2: Euler is stable for h gamma Fc^2 < 2 and monotone below 1. The default
gamma = 5000 / ((N m)^2 s) puts that rate at gamma Fc^2 for the paper's Coulomb levels, far inside the bound
at 1 kHz, and slower than the VFE's eps_hat_F (eigenvalues of 20 1/s and faster), as Sec. V-B requires. The
law is its own system, :class:`KSigmaAdapter`, beside the Dahl observer
(:class:`furuta_drake.observers.dahl.DahlFrictionObserver`): it reads the observer's z_hat and sets its gain.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pydrake.systems.framework import BasicVector, LeafSystem

from furuta_drake.errors import ConfigError

K_SIGMA_POS, K_SIGMA_NEG = 0, 1  # the branches' places in the adapter's state


@dataclass
class KSigmaAdaptationParameters:
    """Eq. 18's gain and the Sec. V-C activation conditions."""

    gamma: float = 5000.0  # adaptation gain [1 / ((N m)^2 s)]; 0 holds K_sigma at ``initial``
    velocity_threshold: float = 0.1  # adapt only while |v| > this [rad/s]
    enable_time: float = 0.0  # adapt only from this time on [s]
    initial: float = 1.0  # K_sigma+ and K_sigma- at t = 0 [-]

    def validate(self, where: str = "observers.dahl.adaptation.k_sigma") -> None:
        for name in ("gamma", "velocity_threshold", "enable_time"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"{where}.{name} must be >= 0, got {value!r}")
        if not (math.isfinite(self.initial) and self.initial > 0):
            raise ConfigError(f"{where}.initial must be > 0, got {self.initial!r}")


def adapting_branch(p: KSigmaAdaptationParameters, time: float, v: float) -> int | None:
    """The K_sigma that Eq. 18 adapts over the period from ``time`` [s] at velocity estimate v [rad/s]: 0
    (K_sigma+) for v > 0, 1 (K_sigma-) for v < 0, None before ``enable_time`` or while |v| <= the threshold."""
    if time < p.enable_time or abs(v) <= p.velocity_threshold:
        return None
    return 0 if v > 0 else 1


def k_sigma_step(
    p: KSigmaAdaptationParameters, period: float, sigma0: float, friction_error: float, bristle: float
) -> float:
    """Eq. 18 over one ``period`` [s] (explicit Euler): -h gamma eps_hat_F sigma0 z_hat, eps_hat_F [N m] the arm
    entry of the VFE's friction error, sigma0 [N m/rad] and z_hat [rad] the Dahl observer's."""
    return period * (-p.gamma * friction_error * sigma0 * bristle)


class KSigmaAdapter(LeafSystem):
    """Eq. 18 with Sec. V-C's two branches, discrete at the control period ``period`` [s], for a Dahl observer of
    bristle stiffness ``sigma0`` [N m/rad].

    Inputs: ``arm_velocity_estimate_rad_per_s`` (v, the Dahl observer's), ``bristle_state_rad`` (its z_hat) and
    ``friction_error_estimate_Nm`` (the VFE's eps_hat_F = [pendulum, arm] [N m]). Discrete state
    [K_sigma+, K_sigma-]. Outputs: ``K_sigma`` (the gain of v's sign, which the observer's F_hat carries; feeds
    through v) and ``K_sigma_branches`` ([K_sigma+, K_sigma-]).
    """

    def __init__(self, params: KSigmaAdaptationParameters, *, period: float, sigma0: float):
        LeafSystem.__init__(self)
        params.validate()
        self.params, self.period, self.sigma0 = params, period, sigma0
        self._velocity = self.DeclareVectorInputPort("arm_velocity_estimate_rad_per_s", 1)
        self._bristle = self.DeclareVectorInputPort("bristle_state_rad", 1)
        self._error = self.DeclareVectorInputPort("friction_error_estimate_Nm", 2)
        branches = self.DeclareDiscreteState([params.initial, params.initial])
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        xd = self.xd_ticket()
        self.DeclareVectorOutputPort("K_sigma", 1, self._calc_gain, prerequisites_of_calc={xd, self._velocity.ticket()})
        self.DeclareStateOutputPort("K_sigma_branches", branches)

    def _calc_gain(self, context, output: BasicVector):
        branch = K_SIGMA_POS if self._velocity.Eval(context)[0] > 0 else K_SIGMA_NEG
        output.SetAtIndex(0, context.get_discrete_state_vector().GetAtIndex(branch))

    def _update(self, context, discrete_state):
        """Eq. 18 on the branch of v's sign, from the inputs before the sample."""
        v = float(self._velocity.Eval(context)[0])
        branch = adapting_branch(self.params, context.get_time(), v)
        if branch is None:
            return
        state = discrete_state.get_mutable_vector(0)
        index = K_SIGMA_POS + branch
        step = k_sigma_step(
            self.params, self.period, self.sigma0, self._error.Eval(context)[1], self._bristle.Eval(context)[0]
        )
        state.SetAtIndex(index, state.GetAtIndex(index) + step)


__all__ = ["KSigmaAdaptationParameters", "KSigmaAdapter", "adapting_branch", "k_sigma_step"]
