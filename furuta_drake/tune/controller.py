"""A balancing controller as ``tune`` designs it, and its closed loop on a model as a simulate config.

A :class:`Controller` is what a lab's controller holds: the LQ gain K on [theta, phi, theta_dot, phi_dot]
(u = -K x_hat - K_sigma F_hat, paper Sec. IV-A, IV-C), its velocity source with the observer's gains, the Dahl
friction observer's model and the initial K_sigma of the compensation, and the torque limit.

- The **nominal** controller is what a lab designs on its rig file today: the package's LQ weights on the rig file's
  rigid body, the HG observer at its default gains (paper diagram (i)), no friction compensation.
- A **tuned** controller's observer follows the corrected model's time scale, the upright's unstable pole p
  (:func:`observer_for`): the observer's slowest pole at w = max(2 p, ``SLOWEST_OBSERVER``), which gives the
  package's defaults on the Lund rig. With arm friction in the model, the VFE observer (Eq. 11-13) with its six
  eigenvalues spread as the package's defaults (w x 1 to x 1.75) and the Dahl observer (Eq. 8-9) with the fitted
  Coulomb levels and a bristle stiffness from the fitted presliding displacement, sigma0 = max(Fc+, Fc-) / z_ss
  (one encoder count for a smooth law, which has none); the compensation's K_sigma adapts by Eq. 18 at the
  paper's rate gamma Fc^2 (``ADAPTATION_RATE``). Without arm friction, the HG observer with its error poles
  ``HG_SPEED`` times faster (the high-gain separation of Eq. 4-6), eps at least ``HG_PERIODS`` sample periods;
  with arm friction the HG is the alternative the search also tries (its Dahl observer then reads the HG's
  arm velocity), since the VFE's estimate leans on the fitted friction law and the HG's does not.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field

import numpy as np

from furuta_drake.config import ObserverConfig, SimulationConfig
from furuta_drake.controllers.lqr import LqrParameters
from furuta_drake.errors import ConfigError
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.observers.dahl import DahlAdaptation, DahlObserverParameters
from furuta_drake.observers.hg import HighGainParameters
from furuta_drake.observers.k_sigma import KSigmaAdaptationParameters
from furuta_drake.observers.vfe import VfeParameters
from furuta_drake.rig import RigParameters

VFE_SPREAD = (1.0, 1.15, 1.3, 1.45, 1.6, 1.75)  # the package's default VFE eigenvalues over their slowest
SLOWEST_OBSERVER = 20.0  # [rad/s] the VFE's slowest eigenvalue at the least (the package's default)
HG_SPEED = 10.0  # HG error poles over the observer's time scale
HG_PERIODS = 2.5  # the HG's eps is at least this many sample periods (the package's default at 500 Hz)
ADAPTATION_RATE = 5000.0 * 0.015**2  # [1/s] gamma Fc^2 of the paper's K_sigma law (Sec. V-D)
DISTURBANCE = 0.05  # [rad] the largest initial pendulum angle of a predicted balancing run


@dataclass(frozen=True)
class Controller:
    """A balancing controller: ``gain`` K [N m/rad, N m s/rad] in paper order (u = -K x), the velocity source
    ``observer`` ('hg' or 'vfe') with its ``hg`` or ``vfe`` gains, the Dahl observer ``dahl`` (None without arm
    friction in the design), ``compensation`` the initial K_sigma of u = u_LQ - K_sigma F_hat (0: none), the
    controller's ``torque_limit`` [N m], the LQ weights it was designed with and the rig file its observer's model
    is linearized from (``model``; None: the model it balances, the corrected one)."""

    gain: tuple[float, float, float, float]
    observer: str
    torque_limit: float
    lqr: LqrParameters
    hg: HighGainParameters = field(default_factory=HighGainParameters)
    vfe: VfeParameters = field(default_factory=VfeParameters)
    dahl: DahlObserverParameters | None = None
    compensation: float = 0.0
    model: RigParameters | None = None

    def observer_dict(self) -> dict:
        """The observer's settings as ``tune.json`` states them."""
        if self.observer == "hg":
            out = {"kind": "hg", "eps_theta": self.hg.eps_theta, "eps_phi": self.hg.eps_phi}
        else:
            out = {"kind": "vfe", "eigenvalues": list(self.vfe.eigenvalues)}
        if self.dahl is not None:
            out["dahl"] = {
                "coulomb_pos": self.dahl.coulomb_pos,
                "coulomb_neg": self.dahl.coulomb_neg,
                "sigma0": self.dahl.sigma0,
                "static_pos": self.dahl.static_pos,
                "static_neg": self.dahl.static_neg,
                "stribeck_velocity": self.dahl.stribeck_velocity,
                "k_sigma_initial": self.compensation,
                "k_sigma_gamma": self.dahl.adaptation.k_sigma.gamma if self.dahl.adaptation else 0.0,
            }
        return out


def upright_rate(A: np.ndarray) -> float:
    """The upright's unstable pole [1/s]: the largest real part of the eigenvalues of the rigid body's A (the
    first four states)."""
    return float(np.max(np.linalg.eigvals(A[:4, :4]).real))


def arm_friction_observer(friction: JointFrictionParameters, count: float) -> DahlObserverParameters | None:
    """The Dahl (LuGre with Stribeck levels) observer of a fitted arm friction law (module docstring); None when
    the law has no Coulomb level. ``count``: one encoder count [rad]."""
    levels = (friction.coulomb_pos, friction.coulomb_neg)
    if friction.model == "none" or max(levels) <= 0:
        return None
    levels = tuple(max(level, 1e-6 * max(levels)) for level in levels)
    static = friction.static_pos is not None and friction.model != "dahl"
    sigma0 = friction.sigma0 if friction.has_bristles else max(levels) / count
    gamma = ADAPTATION_RATE / (0.5 * sum(levels)) ** 2
    return DahlObserverParameters(
        coulomb_pos=levels[0],
        coulomb_neg=levels[1],
        sigma0=sigma0,
        static_pos=max(friction.static_pos, levels[0]) if static else None,
        static_neg=max(friction.static_neg, levels[1]) if static else None,
        stribeck_velocity=friction.stribeck_velocity,
        adaptation=DahlAdaptation(k_sigma=KSigmaAdaptationParameters(gamma=gamma)),
    )


def observer_for(
    rate: float, period: float, dahl: DahlObserverParameters | None, scale: float = 1.0, kind: str | None = None
) -> tuple[str, HighGainParameters, VfeParameters]:
    """(velocity source, HG gains, VFE gains) of a tuned controller on a model whose upright pole is ``rate``
    [1/s] (module docstring), its time scale ``scale`` times the default's (2: every pole half as fast; the HG's
    eps stays at least ``HG_PERIODS`` sample periods). ``kind`` 'hg' or 'vfe' (the VFE needs the Dahl observer
    ``dahl``); None: the VFE with arm friction in the model, else the HG."""
    if kind not in (None, "hg", "vfe") or (kind == "vfe" and dahl is None):
        raise ConfigError(f"observer kind {kind!r}: 'hg', or 'vfe' with arm friction in the model")
    slowest = max(2.0 * rate, SLOWEST_OBSERVER) / scale
    if (kind or ("vfe" if dahl is not None else "hg")) == "vfe":
        return "vfe", HighGainParameters(), VfeParameters(eigenvalues=[-slowest * k for k in VFE_SPREAD])
    eps = max(1.0 / (HG_SPEED * slowest), HG_PERIODS * period)
    return "hg", HighGainParameters(eps_theta=eps, eps_phi=eps), VfeParameters()


def with_compensation(controller: Controller, gain: float) -> Controller:
    """``controller`` compensating ``gain`` times the Dahl observer's F_hat (its K_sigma starts there)."""
    if controller.dahl is None or gain == 0.0:
        return dataclasses.replace(controller, compensation=0.0)
    adaptation = dataclasses.replace(controller.dahl.adaptation.k_sigma, initial=gain)
    dahl = dataclasses.replace(controller.dahl, adaptation=DahlAdaptation(k_sigma=adaptation))
    return dataclasses.replace(controller, dahl=dahl, compensation=gain)


def initial_angle(seed: int) -> float:
    """The pendulum's seeded initial angle [rad] of a predicted balancing run: within +-``DISTURBANCE``, at least
    half of it."""
    draw = np.random.default_rng([seed, 17]).uniform(0.5, 1.0)
    sign = 1.0 if np.random.default_rng([seed, 19]).uniform() < 0.5 else -1.0
    return float(sign * DISTURBANCE * draw)


def closed_loop(world: SimulationConfig, controller: Controller, *, duration: float, seed: int) -> SimulationConfig:
    """``controller`` balancing the model ``world`` (an open-loop simulate config of the corrected model) from the
    seeded initial angle (:func:`initial_angle`), its observers started at that state, the encoder noise seeded."""
    compensate = controller.compensation > 0.0
    observers = ObserverConfig(
        hg=controller.hg,
        vfe=controller.vfe,
        dahl=controller.dahl or DahlObserverParameters(),
        start_at_initial_state=True,
        model=controller.model,
    )
    control = dataclasses.replace(
        world.controller,
        mode="lqr",
        velocity_source=controller.observer,
        friction_compensation=compensate,
        gain=[float(k) for k in controller.gain],
        lqr=dataclasses.replace(controller.lqr, torque_limit=controller.torque_limit),
    )
    return dataclasses.replace(
        world,
        controller=control,
        observers=observers,
        encoder=dataclasses.replace(world.encoder, seed=seed),
        initial_state=[initial_angle(seed), 0.0, 0.0, 0.0],
        duration=duration,
        seed=seed,
    )


def torque_per_volt(config: SimulationConfig) -> float | None:
    """kt / R [N m/V] of the rig's motor, None without one."""
    motor = config.rig.motor
    return None if motor is None else motor.torque_constant / motor.resistance


def volts_gain(K, config: SimulationConfig) -> list[float] | None:
    """The gain in volts of a motor rig, V = -K_V x: the torque-equivalent gain K over kt / R (the design model
    holds the motor's back-EMF damping kt ke / R phi_dot, which the motor adds by itself at the voltage the
    controller outputs); None without a motor."""
    scale = torque_per_volt(config)
    return None if scale is None else [float(k) / scale for k in np.ravel(K)]


def finite(value: float) -> float | None:
    """``value`` when finite, else None (JSON has no inf or NaN)."""
    return float(value) if value is not None and math.isfinite(value) else None
