"""Joint friction of the Furuta pendulum: laws (vectorised numpy) and the ``JointFriction`` Drake system.

Sign convention of the whole package: a friction torque is the torque friction EXERTS on its joint, opposite
to the velocity: the paper's F in tau = [F_theta, u + F_phi] (Eq. 3). The Dahl bristle state z follows Eq. 7,
dz/dt = v - sigma0 |v| z / Fc (so z -> Fc sign(v) / sigma0), and the exerted torque is F = -sigma0 z; with
this sign the adaptation law Eq. 18 is a gradient descent as printed.

Models per joint (``JointFrictionParameters.model``):

- ``static``: F = -(g(v) tanh(v / v_reg) + b v), g the Stribeck curve g(v) = Fc + (Fs - Fc) exp(-(v/vs)^2),
  with per-direction levels. The regularisation velocity v_reg keeps the law smooth, so Drake's AutoDiffXd
  (``Linearize``) passes through it and error-controlled integrators can step across velocity reversals.
- ``dahl`` (Eq. 7): F = -sigma0 z, dz/dt = v - sigma0 |v| z / Fc(v), Fc per direction; plus viscous b v.
- ``lugre``: dz/dt = v - sigma0 |v| z / g(v), F = -(sigma0 z + sigma1 dz/dt + sigma2 v), sigma2 = ``viscous``.

The bristle state is stiff (rate sigma0 |v| / Fc, NOTES.md): :func:`dahl_exact_step` is its exact step at
frozen velocity, stable at any step size, used by the discrete friction observers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.autodiffutils import AutoDiffXd
from pydrake.systems.framework import LeafSystem_
from pydrake.systems.scalar_conversion import TemplateSystem

from furuta_drake.errors import ConfigError

MODELS = ("none", "static", "dahl", "lugre")


@dataclass
class JointFrictionParameters:
    """Friction on one joint (SI units; levels are positive magnitudes)."""

    model: str = "none"
    coulomb_pos: float = 0.0  # Coulomb level for v > 0 [N m]
    coulomb_neg: float = 0.0  # Coulomb level for v < 0 [N m]
    static_pos: float | None = None  # Stribeck breakaway level for v > 0 [N m]; None: equal to Coulomb
    static_neg: float | None = None  # for v < 0 [N m]
    stribeck_velocity: float = 0.05  # [rad/s]
    viscous: float = 0.0  # [N m s/rad] (sigma2 of LuGre)
    sigma0: float = 10.0  # bristle stiffness [N m/rad] (dahl, lugre)
    sigma1: float = 0.0  # bristle damping [N m s/rad] (lugre)
    regularization_velocity: float = 1e-3  # [rad/s] (static model)

    @classmethod
    def coulomb(cls, level: float, viscous: float = 0.0) -> "JointFrictionParameters":
        return cls(model="static", coulomb_pos=level, coulomb_neg=level, viscous=viscous)

    @classmethod
    def dahl(cls, coulomb_pos: float, coulomb_neg: float, sigma0: float) -> "JointFrictionParameters":
        return cls(model="dahl", coulomb_pos=coulomb_pos, coulomb_neg=coulomb_neg, sigma0=sigma0)

    @property
    def has_bristles(self) -> bool:
        return self.model in ("dahl", "lugre")

    @property
    def static_levels(self) -> tuple[float, float]:
        """Breakaway levels (v > 0, v < 0) [N m]: the Coulomb levels where no Stribeck level is given."""
        return (self.coulomb_pos if self.static_pos is None else self.static_pos,
                self.coulomb_neg if self.static_neg is None else self.static_neg)

    def validate(self, where: str = "friction.joint") -> None:
        if self.model not in MODELS:
            raise ConfigError(f"{where}.model must be one of {list(MODELS)}, got {self.model!r}")
        for name in ("coulomb_pos", "coulomb_neg", "viscous", "sigma1"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0):
                raise ConfigError(f"{where}.{name} must be a non-negative finite number, got {value!r}")
        for name in ("stribeck_velocity", "regularization_velocity"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{where}.{name} must be > 0, got {value!r}")
        for name, coulomb in (("static_pos", self.coulomb_pos), ("static_neg", self.coulomb_neg)):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value >= coulomb):
                raise ConfigError(f"{where}.{name} must be >= the Coulomb level {coulomb}, got {value!r}")
        if self.has_bristles:
            if not (math.isfinite(self.sigma0) and self.sigma0 > 0):
                raise ConfigError(f"{where}.sigma0 must be > 0 for the {self.model} model, got {self.sigma0!r}")
            if min(self.coulomb_pos, self.coulomb_neg) <= 0:
                raise ConfigError(f"{where}: the {self.model} model needs Coulomb levels > 0 in both directions")


@dataclass
class FrictionParameters:
    """Friction on the Furuta's two joints."""

    arm: JointFrictionParameters = field(default_factory=JointFrictionParameters)
    pendulum: JointFrictionParameters = field(default_factory=JointFrictionParameters)

    def validate(self, where: str = "friction") -> None:
        self.arm.validate(f"{where}.arm")
        self.pendulum.validate(f"{where}.pendulum")


def _by_direction(v, positive, negative):
    """``positive`` where v > 0, ``negative`` elsewhere (numpy arrays or scalars, AutoDiffXd included)."""
    if isinstance(v, np.ndarray):
        return np.where(v > 0, positive, negative)
    return positive if v > 0 else negative


def stribeck_curve(v, p: JointFrictionParameters):
    """g(v) = Fc + (Fs - Fc) exp(-(v / vs)^2) per direction [N m]."""
    coulomb = _by_direction(v, p.coulomb_pos, p.coulomb_neg)
    static = _by_direction(v, *p.static_levels)
    return coulomb + (static - coulomb) * np.exp(-(v / p.stribeck_velocity) ** 2)


def static_friction_torque(v, p: JointFrictionParameters):
    """The static model's exerted torque -(g(v) tanh(v / v_reg) + b v) [N m]."""
    return -(stribeck_curve(v, p) * np.tanh(v / p.regularization_velocity) + p.viscous * v)


def bristle_derivative(z, v, p: JointFrictionParameters):
    """dz/dt of Eq. 7 (Dahl: g = Fc(v)) or of LuGre (g the Stribeck curve)."""
    level = _by_direction(v, p.coulomb_pos, p.coulomb_neg) if p.model == "dahl" else stribeck_curve(v, p)
    return v - p.sigma0 * abs(v) * z / level


def bristle_friction_torque(z, v, p: JointFrictionParameters):
    """Exerted torque of the Dahl (-sigma0 z - b v) or LuGre (-(sigma0 z + sigma1 dz + sigma2 v)) model."""
    damping = p.sigma1 * bristle_derivative(z, v, p) if p.model == "lugre" else 0.0
    return -(p.sigma0 * z + damping + p.viscous * v)


def dahl_exact_step(z, v, dt, sigma0, coulomb_level):
    """Exact solution over ``dt`` of dz/dt = v - (sigma0 |v| / Fc) z at frozen v: z_ss + (z - z_ss) e^(-rate dt),
    z_ss = Fc sign(v) / sigma0, rate = sigma0 |v| / Fc; z is held where v = 0. Stable at any step."""
    z_ss = coulomb_level * np.sign(v) / sigma0
    decay = np.exp(-sigma0 * np.abs(v) * dt / coulomb_level)
    return np.where(v == 0, z, z_ss + (z - z_ss) * decay)


@TemplateSystem.define("JointFriction_", T_list=(float, AutoDiffXd))
def JointFriction_(T):

    class Impl(LeafSystem_[T]):
        """Friction on the arm and pendulum joints of the Furuta ``MultibodyPlant``.

        Input ``plant_state`` (the plant's state output); outputs ``generalized_force_Nm`` (plant velocity
        order, for the plant's applied-generalized-force port) and ``friction_torque_Nm`` = [F_theta, F_phi].
        One continuous bristle state per joint with a Dahl or LuGre model. Scalar-convertible (AutoDiffXd), so
        ``Linearize`` works through it.
        """

        def _construct(self, plant=None, params: FrictionParameters | None = None, *, layout=None,
                       converter=None):
            LeafSystem_[T].__init__(self, converter)
            params = params or FrictionParameters()
            params.validate()
            if layout is None:
                nq = plant.num_positions()
                layout = {"nx": plant.num_multibody_states(), "nv": plant.num_velocities(),
                          "theta_v": plant.GetJointByName("pendulum").velocity_start(),
                          "phi_v": plant.GetJointByName("arm").velocity_start(), "nq": nq}
            self._layout, self._params = layout, params
            # Joints in the paper's order [theta, phi] with their parameters.
            self._joints = [(layout["theta_v"], params.pendulum), (layout["phi_v"], params.arm)]
            self._bristles = [i for i, (_, p) in enumerate(self._joints) if p.has_bristles]
            if self._bristles:
                self.DeclareContinuousState(len(self._bristles))
            self.DeclareVectorInputPort("plant_state", layout["nx"])
            self.DeclareVectorOutputPort("generalized_force_Nm", layout["nv"], self._calc_generalized_force)
            self.DeclareVectorOutputPort("friction_torque_Nm", 2, self._calc_friction_torque)

        def _construct_copy(self, other, converter=None):
            Impl._construct(self, None, other._params, layout=other._layout, converter=converter)

        def _velocities(self, context):
            x = self.get_input_port(0).Eval(context)
            nq = self._layout["nq"]
            return [x[nq + index] for index, _ in self._joints]

        def _torques(self, context):
            velocities = self._velocities(context)
            z = context.get_continuous_state_vector().CopyToVector() if self._bristles else ()
            torques = []
            for i, (_, p) in enumerate(self._joints):
                v = velocities[i]
                if p.model == "none":
                    torques.append(0.0 * v)
                elif p.model == "static":
                    torques.append(static_friction_torque(v, p))
                else:
                    torques.append(bristle_friction_torque(z[self._bristles.index(i)], v, p))
            return torques

        def _calc_friction_torque(self, context, output):
            output.SetFromVector(np.array(self._torques(context)))

        def _calc_generalized_force(self, context, output):
            force = np.zeros(self._layout["nv"], dtype=object if T != float else float)
            force[:] = 0.0
            for (index, _), torque in zip(self._joints, self._torques(context)):
                force[index] = torque
            output.SetFromVector(force)

        def DoCalcTimeDerivatives(self, context, derivatives):
            velocities = self._velocities(context)
            z = context.get_continuous_state_vector().CopyToVector()
            rates = [bristle_derivative(z[k], velocities[i], self._joints[i][1]) for k, i in enumerate(self._bristles)]
            derivatives.get_mutable_vector().SetFromVector(np.array(rates))

    return Impl


JointFriction = JointFriction_[None]
