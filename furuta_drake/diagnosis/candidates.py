"""The effect vocabulary of the spec as candidates: parameters, bounds, starts, and how each one changes the
surrogate model and a simulate config.

Every parameter is in SI units and is the effect's own level (not an increment over the rig file), as the
report's ranking lists it. The Coulomb and asymmetry candidates are Dahl friction (Eq. 7) and the Stribeck
candidate is LuGre friction (Dahl's bristle saturating at the Stribeck curve g(v)): real arm friction has
presliding (a bristle spring of a few mrad before gross sliding) that a static law misses at every velocity
reversal, so its presliding displacement is fitted with the levels (a static-like law is its small end). Scales come from the rig: torques from m g l and the logged commands, damping
from the lumped inertias, times from the sample period.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable

import numpy as np

from furuta_drake.diagnosis.surrogate import REGULARIZATION_VELOCITY, Model
from furuta_drake.friction import JointFrictionParameters


@dataclass(frozen=True)
class Scales:
    """Physical scales of a rig and its logs that set bounds and starts."""

    torque: float  # m g l [N m]
    command: float  # largest |command| in the train logs [N m]
    arm_inertia: float  # a [kg m^2]
    pendulum_inertia: float  # b [kg m^2]
    period: float  # [s]


@dataclass(frozen=True)
class Candidate:
    name: str
    params: tuple[str, ...]
    bounds: Callable[[Scales], tuple[list[float], list[float]]]
    starts: Callable[[Scales], list[list[float]]]
    apply: Callable[[Model, np.ndarray], Model]
    fit: bool = True  # False: estimated from the data directly (sensor effects)


PRESLIDING = (1e-4, 0.05)  # bounds of the presliding displacement Fc / sigma0 of the Dahl arm friction [rad]
PRESLIDING_STARTS = (1e-3, 1e-2)  # [rad]
# Starts of the arm friction levels [m g l]: the cost is multimodal in the level (a level far too low leaves the
# arm free to move in the model where it sticks in the data, and the fit stalls), so they span two decades up to
# the 0.2 m g l of the Lund rig's own friction.
FRICTION_LEVEL_STARTS = (0.005, 0.02, 0.06, 0.2)


def _dahl_arm(model: Model, coulomb_pos: float, coulomb_neg: float, presliding: float) -> Model:
    """The arm's friction replaced by Dahl's (Eq. 7): Coulomb levels per direction, bristle stiffness
    sigma0 = mean level / presliding displacement, the rig file's viscous term kept."""
    sigma0 = max(0.5 * (coulomb_pos + coulomb_neg), 1e-9) / presliding
    return model.replace(arm_friction=JointFrictionParameters(
        model="dahl", coulomb_pos=max(coulomb_pos, 1e-12), coulomb_neg=max(coulomb_neg, 1e-12), sigma0=sigma0,
        viscous=model.arm_friction.viscous))


def _lugre_arm(model: Model, coulomb: float, static: float, stribeck_velocity: float, presliding: float) -> Model:
    """The arm's friction replaced by LuGre's without bristle damping: the Stribeck curve g(v) from the
    Coulomb to the static level, sigma0 = Coulomb level / presliding displacement, the rig's viscous term."""
    coulomb = max(coulomb, 1e-12)
    return model.replace(arm_friction=JointFrictionParameters(
        model="lugre", coulomb_pos=coulomb, coulomb_neg=coulomb, static_pos=static, static_neg=static,
        stribeck_velocity=stribeck_velocity, sigma0=coulomb / presliding, sigma1=0.0,
        viscous=model.arm_friction.viscous))


def _arm(model: Model, **changes) -> Model:
    return model.replace(arm_friction=dataclasses.replace(model.arm_friction, **changes))


CANDIDATES: dict[str, Candidate] = {c.name: c for c in [
    Candidate("arm_coulomb_friction", ("coulomb", "presliding"),
              lambda s: ([0.0, PRESLIDING[0]], [0.5 * s.torque, PRESLIDING[1]]),
              lambda s: [[level * s.torque, z] for level in FRICTION_LEVEL_STARTS for z in PRESLIDING_STARTS],
              lambda m, p: _dahl_arm(m, p[0], p[0], p[1])),
    Candidate("arm_viscous_friction", ("viscous",),
              lambda s: ([0.0], [50.0 * s.arm_inertia]), lambda s: [[0.1 * s.arm_inertia], [1.0 * s.arm_inertia],
                                                                  [5.0 * s.arm_inertia]],
              lambda m, p: _arm(m, viscous=p[0])),
    Candidate("arm_stribeck", ("coulomb", "static", "stribeck_velocity", "presliding"),
              lambda s: ([0.0, 0.0, 0.01, PRESLIDING[0]], [0.5 * s.torque, 1.0 * s.torque, 1.0, PRESLIDING[1]]),
              lambda s: [[level * s.torque, 2.5 * level * s.torque, 0.1, z] for level in FRICTION_LEVEL_STARTS
                         for z in PRESLIDING_STARTS],
              lambda m, p: _lugre_arm(m, p[0], max(p[1], p[0]), p[2], p[3])),
    Candidate("friction_asymmetry", ("coulomb_pos", "coulomb_neg", "presliding"),
              lambda s: ([0.0, 0.0, PRESLIDING[0]], [0.5 * s.torque, 0.5 * s.torque, PRESLIDING[1]]),
              lambda s: [[level * s.torque, level * s.torque, z] for level in FRICTION_LEVEL_STARTS
                         for z in PRESLIDING_STARTS]
              + [[level * ratio * s.torque, level / ratio * s.torque, PRESLIDING_STARTS[0]]
                 for level in FRICTION_LEVEL_STARTS for ratio in (0.8, 1.25)],
              lambda m, p: _dahl_arm(m, p[0], p[1], p[2])),
    Candidate("pendulum_friction", ("coulomb", "viscous"),
              lambda s: ([0.0, 0.0], [0.1 * s.torque, 20.0 * s.pendulum_inertia]),
              lambda s: [[0.0005 * s.torque, 0.02 * s.pendulum_inertia], [0.005 * s.torque, 0.2 * s.pendulum_inertia]],
              lambda m, p: m.replace(pendulum_friction=dataclasses.replace(
                  m.pendulum_friction, coulomb_pos=p[0], coulomb_neg=p[0], viscous=p[1]))),
    Candidate("encoder_quantization", ("counts_per_rev",), lambda s: ([4.0], [1e7]), lambda s: [],
              lambda m, p: m.replace(counts_per_rev=int(round(p[0]))), fit=False),
    Candidate("measurement_noise", ("noise_std",), lambda s: ([0.0], [1.0]), lambda s: [],
              lambda m, p: m.replace(noise_std=float(p[0])), fit=False),
    Candidate("input_delay", ("delay",),
              lambda s: ([0.0], [20.0 * s.period]), lambda s: [[0.5 * s.period], [2.0 * s.period], [5.0 * s.period]],
              lambda m, p: m.replace(delay=p[0])),
    Candidate("torque_gain_error", ("gain",), lambda s: ([0.2], [5.0]), lambda s: [[1.0]],
              lambda m, p: m.replace(gain=p[0])),
    Candidate("actuator_deadzone", ("deadzone",),
              lambda s: ([0.0], [0.5 * s.command]), lambda s: [[0.01 * s.command], [0.05 * s.command], [0.15 * s.command]],
              lambda m, p: m.replace(deadzone=p[0])),
    Candidate("actuator_lag", ("time_constant",),
              lambda s: ([0.0], [0.1]), lambda s: [[0.5 * s.period], [2.0 * s.period], [0.01]],
              lambda m, p: m.replace(lag=p[0])),
    Candidate("actuator_saturation", ("limit",),
              lambda s: ([0.05 * s.command], [1.0 * s.command]), lambda s: [[0.95 * s.command], [0.7 * s.command], [0.4 * s.command]],
              lambda m, p: m.replace(saturation=p[0])),
    Candidate("arm_spring", ("stiffness", "equilibrium"),
              lambda s: ([0.0, -1.0], [5.0 * s.torque, 1.0]), lambda s: [[0.01 * s.torque, 0.0], [0.1 * s.torque, 0.0]],
              lambda m, p: m.replace(spring_stiffness=p[0], spring_equilibrium=p[1])),
    Candidate("inertia_mismatch", ("arm_inertia_scale", "pendulum_inertia_scale", "coupling_scale",
                                   "gravity_scale"),
              lambda s: ([0.3] * 4, [3.0] * 4), lambda s: [[1.0] * 4],
              lambda m, p: m.replace(a=m.a * p[0], b=m.b * p[1], c=m.c * p[2], d=m.d * p[3])),
]}


def apply_effects(model: Model, effects: dict[str, np.ndarray]) -> Model:
    """``model`` with every (effect name -> parameter vector) applied in turn."""
    for name, params in effects.items():
        model = CANDIDATES[name].apply(model, np.asarray(params, dtype=float))
    return model


def describe(name: str, params, nominal: Model) -> dict[str, float]:
    """SI parameters for the report; inertia scales are also given as the lumped constants they produce."""
    values = {key: float(v) for key, v in zip(CANDIDATES[name].params, params)}
    if name == "inertia_mismatch":
        values.update(arm_inertia_total=nominal.a * values["arm_inertia_scale"],
                      pendulum_inertia_total=nominal.b * values["pendulum_inertia_scale"],
                      coupling=nominal.c * values["coupling_scale"],
                      gravity_torque=nominal.d * values["gravity_scale"])
    return values
