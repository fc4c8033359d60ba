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
law runs inside the Dahl observer (:class:`furuta_drake.observers.dahl.DahlFrictionObserver`), whose state holds
[z_hat, K_sigma+, K_sigma-].
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from furuta_drake.errors import ConfigError

K_SIGMA_POS, K_SIGMA_NEG = 1, 2  # the branches' places in the Dahl observer's state, after z_hat


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


__all__ = ["KSigmaAdaptationParameters", "adapting_branch", "k_sigma_step", "K_SIGMA_POS", "K_SIGMA_NEG"]
