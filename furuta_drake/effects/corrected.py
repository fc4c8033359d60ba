"""The corrected model: a diagnosis model as the world's parameters (its rigid body, actuator and spring for the
Drake world, :func:`~furuta_drake.world.add_furuta_world`), the whole model as a simulate config
(:func:`model_config`; :func:`rig_config` for the model a rig file states, effects included, the one conversion
``simulate``, ``tune``, ``design`` and the diagnosis share), and a rig file with the accepted effects (what
``fitted_model.yaml`` and ``fitted_rig.yaml`` hold)."""

from __future__ import annotations

import dataclasses

import numpy as np

from furuta_drake.actuator import ActuatorParameters, DisturbanceParameters
from furuta_drake.config import SimulationConfig
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.torque_library import torque_parameters_of
from furuta_drake.effects.vocabulary import CANDIDATES, DRIVE_KEYS, Effect, describe, effect_from_params, rig_model
from furuta_drake.encoder import EncoderParameters
from furuta_drake.friction import FrictionParameters
from furuta_drake.rig import RigParameters
from furuta_drake.unmodelled import UnmodelledTorqueParameters


def model_rig(model: Model, rig: RigParameters) -> RigParameters:
    """A rigid body with the model's lumped constants a = J_arm + m r^2, b = J_p + m l^2, c = m l r, d = m g l
    (gravity kept): m l = d / g, r = c g / d, the pendulum mass kept where the inertias allow it; a drive's rotor
    inertia scaled with a (the model's a over the rig file's), so that the arm and its rotor keep their shares, and
    its backlash, stiffness and damping the model's."""
    ml = model.gravity_torque / rig.gravity
    r = model.coupling / ml
    drive = rig.drive
    if drive is not None:
        drive = dataclasses.replace(
            drive,
            rotor_inertia=drive.rotor_inertia * model.arm_inertia_total / rig.arm_inertia_total,
            backlash=model.drive_backlash,
            stiffness=model.drive_stiffness if model.drive_stiffness > 0 else None,
            damping=model.drive_damping if model.drive_stiffness > 0 else 0.0,
        )
    arm = model.arm_inertia_total - (0.0 if drive is None else drive.reflected_inertia)  # J_arm + m r^2 but the rotor
    mass = float(np.clip(rig.pendulum_mass, 1.0001 * ml**2 / model.pendulum_inertia_total, 0.9999 * arm / r**2))
    com = ml / mass
    return dataclasses.replace(
        rig,
        arm_length=r,
        pendulum_mass=mass,
        pendulum_com=com,
        pendulum_inertia=model.pendulum_inertia_total - mass * com**2,
        arm_inertia=arm - mass * r**2,
        drive=drive,
        arm_coulomb=0.0,
        arm_viscous=0.0,
        pendulum_coulomb=0.0,
        pendulum_viscous=0.0,
        motor=None,
    )


def model_disturbance(model: Model) -> DisturbanceParameters:
    """The model's arm spring as the world's disturbance parameters."""
    return DisturbanceParameters(
        arm_spring_stiffness=model.spring_stiffness,
        arm_spring_equilibrium=model.spring_equilibrium,
        arm_spring_cubic_stiffness=model.spring_cubic,
    )


def model_actuator(model: Model) -> ActuatorParameters:
    """The actuator blocks of the model other than the delay (a time shift of the replayed command)."""
    return ActuatorParameters(
        gain=model.gain,
        deadzone=model.deadzone,
        deadzone_form=model.deadzone_form,
        saturation_form=model.saturation_form,
        saturation=None if not np.isfinite(model.saturation) else model.saturation,
        delay=0.0,
        lag_time_constant=model.lag,
    )


def model_config(
    rig: RigParameters, model: Model, unmodelled_torque: UnmodelledTorqueParameters | None = None
) -> SimulationConfig:
    """The Drake model of ``model`` (a diagnosis model of ``rig``) as a simulate config, open loop: users add
    their controller. ``unmodelled_torque``: the expressions of the model's torque beyond the vocabulary (by
    default those of its own ``unmodelled_terms``). The simulate world's delay is fixed and its noise white: a
    jittering delay enters as its mean, correlated noise as white noise of its size (the rig file written beside it
    keeps both forms). Every section is the model's, given to :meth:`SimulationConfig.from_rig` at once."""
    bodies = model_rig(model, rig).replace(motor=rig.motor, effects=None, unmodelled_torque=None)
    return SimulationConfig.from_rig(
        bodies,
        unmodelled_torque=unmodelled_torque or torque_parameters_of(model.unmodelled_terms),
        friction=FrictionParameters(arm=model.arm_friction, pendulum=model.pendulum_friction),
        actuator=dataclasses.replace(model_actuator(model), delay=model.delay),
        disturbance=model_disturbance(model),
        encoder=EncoderParameters(
            counts_per_rev=model.counts_per_rev, sample_period=bodies.sample_period, noise_std=model.noise_std
        ),
    )


def rig_config(rig: RigParameters) -> SimulationConfig:
    """The model a rig file states as an open-loop simulate config: its bodies, friction, motor and drive, the
    effects of its ``effects:`` section and its torque beyond the vocabulary (:func:`model_config` of the rig's
    model, the torque's expressions kept as the rig file writes them). A ``fitted_rig.yaml`` gives the corrected
    model of its diagnosis; the rig's ongoing ``disturbance`` becomes the config's ``disturbance.arm_torque``."""
    return model_config(rig, rig_model(rig), rig.unmodelled_torque).with_arm_torque(rig.disturbance)


def rig_entry(name: str, params: dict) -> dict:
    """The rig file's ``effects:`` entry of an effect reported as ``params`` (:func:`describe`'s form): its form
    and the form's own parameters (derived entries left out)."""
    form = effect_from_params(name, params).form
    keep = CANDIDATES[name].form(form).params
    return {key: value for key, value in params.items() if key == "form" or key in keep}


def fitted_rig(
    rig: RigParameters,
    effects: dict[str, Effect],
    nominal: Model,
    unmodelled_torque: UnmodelledTorqueParameters | None = None,
) -> RigParameters:
    """The rig file with the accepted effects added to (or replacing those of) its ``effects:`` section, a drive's
    (backlash, compliance) written as the keys of its ``drive:`` section, and the ``unmodelled_torque`` expressions
    (when given) replacing its own."""
    stated = dict(rig.effects or {})
    for name, effect in effects.items():
        params = describe(name, effect, nominal)
        if name in DRIVE_KEYS:
            rig = rig.replace(drive=dataclasses.replace(rig.drive, **{key: params[key] for key in DRIVE_KEYS[name]}))
        else:
            stated[name] = rig_entry(name, params)
    if unmodelled_torque is not None:
        rig = rig.replace(unmodelled_torque=None if unmodelled_torque.is_empty else unmodelled_torque)
    return rig.replace(effects=stated or None)
