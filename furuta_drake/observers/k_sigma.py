"""The K_sigma adaptation law of the Dahl observer, paper Eq. 16-18 and Sec. V-C.

The Dahl observer's estimate is scaled by K_sigma (F_hat = -K_sigma sigma0 z_hat, Eq. 16 as ``docs/paper.md``
reads it). The VFE observer's eps_hat_F estimates the friction error e = F - F_hat, whose sensitivity is
de/dK_sigma = sigma0 z_hat, so the gradient law Eq. 17, dK_sigma/dt = -gamma e de/dK_sigma, is Eq. 18 as
printed: dK_sigma/dt = -gamma eps_hat_F sigma0 z_hat. As in Sec. V-C there are two gains, K_sigma+ used while
the velocity estimate is positive and K_sigma- otherwise; the active one adapts only while |v| exceeds
``velocity_threshold`` (enough excitation, one sign held) and from ``enable_time`` on (t = 7.8 s in Sec. V-D).

Discrete at the control period h, explicit Euler (:func:`k_sigma_update`). Near steady
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

from pydrake.symbolic import MakeVectorVariable, Variable
from pydrake.systems.framework import Diagram

from furuta_drake.errors import ConfigError
from furuta_drake.symbolic_system import both, build_into, discrete_symbolic_system, negation, where

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


def k_sigma_update(
    p: KSigmaAdaptationParameters, period: float, sigma0: float, *, time, v, friction_error, bristle, gains
):
    """Eq. 18 over one ``period`` [s] from ``time`` [s] (explicit Euler): the next [K_sigma+, K_sigma-] from
    ``gains``. The branch of v's sign [rad/s] (v > 0: K_sigma+, else K_sigma-) moves by
    -h gamma eps_hat_F sigma0 z_hat, eps_hat_F [N m] the arm entry of the VFE's friction error, sigma0 [N m/rad] and
    z_hat [rad] the Dahl observer's; neither moves before ``enable_time`` or while |v| <= the threshold. Floats, or
    symbolic expressions for the C++ adapter."""
    step = period * (-p.gamma * friction_error * sigma0 * bristle)
    active = both(time >= p.enable_time, abs(v) > p.velocity_threshold)
    positive = v > 0
    return [
        where(both(active, positive), gains[K_SIGMA_POS] + step, gains[K_SIGMA_POS]),
        where(both(active, negation(positive)), gains[K_SIGMA_NEG] + step, gains[K_SIGMA_NEG]),
    ]


def active_gain(v, gains):
    """The K_sigma of v's sign [rad/s] (Sec. V-C): K_sigma+ while v > 0, else K_sigma-."""
    return where(v > 0, gains[K_SIGMA_POS], gains[K_SIGMA_NEG])


class KSigmaAdapter(Diagram):
    """Eq. 18 with Sec. V-C's two branches (:func:`k_sigma_update`), discrete at the control period ``period``
    [s], for a Dahl observer of bristle stiffness ``sigma0`` [N m/rad], evaluated in C++
    (:func:`~furuta_drake.symbolic_system.discrete_symbolic_system`).

    Inputs: ``arm_velocity_estimate_rad_per_s`` (v, the Dahl observer's), ``bristle_state_rad`` (its z_hat) and
    ``friction_error_estimate_Nm`` (the VFE's eps_hat_F = [pendulum, arm] [N m]). Discrete state
    [K_sigma+, K_sigma-]. Outputs: ``K_sigma`` (the gain of v's sign, which the observer's F_hat carries; feeds
    through v) and ``K_sigma_branches`` ([K_sigma+, K_sigma-]).
    """

    def __init__(self, params: KSigmaAdaptationParameters, *, period: float, sigma0: float):
        Diagram.__init__(self)
        params.validate()
        self.params, self.period, self.sigma0 = params, period, sigma0
        time, v, bristle = Variable("t"), Variable("arm_velocity"), Variable("z_hat")
        error, gains = MakeVectorVariable(2, "friction_error"), list(MakeVectorVariable(2, "K_sigma"))
        update = k_sigma_update(
            params, period, sigma0, time=time, v=v, friction_error=error[1], bristle=bristle, gains=gains
        )
        law = discrete_symbolic_system(
            name="k_sigma_law",
            period=period,
            state=gains,
            initial=[params.initial, params.initial],
            update=update,
            inputs=[
                ("arm_velocity_estimate_rad_per_s", [v]),
                ("bristle_state_rad", [bristle]),
                ("friction_error_estimate_Nm", list(error)),
            ],
            outputs=[("K_sigma", [active_gain(v, gains)]), ("K_sigma_branches", gains)],
            time=time,
        )
        build_into(self, law)


__all__ = ["KSigmaAdaptationParameters", "KSigmaAdapter", "active_gain", "k_sigma_update"]
