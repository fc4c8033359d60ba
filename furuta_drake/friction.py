"""Joint friction of the Furuta pendulum: the laws (vectorised numpy) and the ``JointFriction`` Drake system.

Sign convention of the whole package: a friction torque is the torque friction EXERTS on its joint, opposite
to the velocity: the paper's F in tau = [F_theta, u + F_phi] (Eq. 3). The Dahl bristle state z follows Eq. 7,
dz/dt = v - sigma0 |v| z / Fc (so z -> Fc sign(v) / sigma0), and the exerted torque is F = -sigma0 z; with
this sign the adaptation law Eq. 18 is a gradient descent as printed, and the observers use the same F.

Models per joint (``JointFrictionParameters.model``), levels per direction of motion (v > 0, v < 0):

- ``static``: F = -(g(v) tanh(v / v_reg) + b v), g the Stribeck curve g(v) = Fc + (Fs - Fc) exp(-(v / vs)^2).
  tanh(v / v_reg) replaces sign(v) so that the law is smooth: Drake's AutoDiffXd (``Linearize``) differentiates
  it, and error-controlled integrators step across velocity reversals instead of chattering on a discontinuity.
  Near v = 0 it acts as a viscous damping g(0) / v_reg; it stops a sliding joint but does not hold it against
  a torque below the breakaway level (use ``dahl`` or ``lugre`` for true presliding).
- ``dahl`` (Eq. 7): F = -sigma0 z - b v, dz/dt = v - sigma0 |v| z / Fc(v), Fc(v) = Fc+ if v > 0 else Fc-.
- ``lugre``: dz/dt = v - sigma0 |v| z / g(v), F = -(sigma0 z + sigma1 dz/dt + sigma2 v), sigma2 = ``viscous``.

Dahl is passive: with the bristle energy sigma0 z^2 / 2, d/dt (E + sigma0 z^2 / 2) = -sigma0^2 |v| z^2 / Fc
- b v^2 <= 0. For LuGre the same storage is non-increasing whenever |v| <= 4 g(v) (sigma1 + sigma2) / sigma1^2
(a sufficient condition; Barabanov and Ortega 2000, the paper's [5], give the necessary and sufficient one).

The simulations' friction is :class:`JointFrictionSystem`, these laws as symbolic expressions evaluated in C++ (no
Python call at an integrator stage); :class:`JointFriction` evaluates the same laws in Python, for float and
AutoDiffXd: Drake's ``Linearize`` differentiates it (a symbolic derivative of a law that branches on the direction of
v is undefined at v = 0, where the linearizations are taken).

The bristle state is stiff (rate sigma0 |v| / Fc: about 800 |v| 1/s with the paper's sigma0 = 10 N m/rad and
Fc = 0.012 N m): :func:`dahl_exact_step` is its exact step at frozen velocity, stable at any step size, and
:func:`held_input_gain` what a constant input adds over that step, for discrete-time users (the friction
observers, which build them as symbolic expressions: :mod:`furuta_drake.symbolic_system`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from pydrake import symbolic
from pydrake.autodiffutils import AutoDiffXd
from pydrake.symbolic import Expression, MakeVectorVariable
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem_
from pydrake.systems.primitives import MatrixGain, SymbolicVectorSystem
from pydrake.systems.scalar_conversion import TemplateSystem

from furuta_drake.errors import ConfigError
from furuta_drake.plant import ARM_JOINT, PENDULUM_JOINT
from furuta_drake.rig import _require_nonnegative, _require_positive
from furuta_drake.symbolic_system import is_symbolic, where

MODELS = ("none", "static", "dahl", "lugre")


@dataclass
class JointFrictionParameters:
    """Friction on one joint (SI units; levels are positive magnitudes, the torque opposes the motion)."""

    model: str = "none"  # "none" | "static" | "dahl" | "lugre"
    coulomb_pos: float = 0.0  # Coulomb level Fc+ while v > 0 [N m]
    coulomb_neg: float = 0.0  # Coulomb level Fc- while v < 0 [N m]
    static_pos: float | None = None  # Stribeck breakaway level Fs+ [N m]; None: no Stribeck (= Coulomb)
    static_neg: float | None = None  # Fs- [N m]
    stribeck_velocity: float = 0.05  # vs [rad/s]
    viscous: float = 0.0  # b [N m s/rad] (sigma2 of LuGre)
    sigma0: float = 10.0  # bristle stiffness [N m/rad] (dahl, lugre)
    sigma1: float = 0.0  # bristle damping [N m s/rad] (lugre)
    regularization_velocity: float = 1e-3  # v_reg of tanh(v / v_reg) [rad/s] (static)

    @classmethod
    def coulomb(
        cls, level: float, viscous: float = 0.0, *, regularization_velocity: float = 1e-3
    ) -> JointFrictionParameters:
        """Symmetric Coulomb plus viscous friction (static model)."""
        return cls(
            model="static",
            coulomb_pos=level,
            coulomb_neg=level,
            viscous=viscous,
            regularization_velocity=regularization_velocity,
        )

    @classmethod
    def dahl(
        cls, coulomb_pos: float, coulomb_neg: float, sigma0: float, viscous: float = 0.0
    ) -> JointFrictionParameters:
        """Dahl model (Eq. 7) with per-direction Coulomb levels."""
        return cls(model="dahl", coulomb_pos=coulomb_pos, coulomb_neg=coulomb_neg, sigma0=sigma0, viscous=viscous)

    @property
    def has_bristles(self) -> bool:
        """True for the models with a bristle state z (dahl, lugre)."""
        return self.model in ("dahl", "lugre")

    @property
    def bristle_bound(self) -> float:
        """The largest |z| of the bristle state [rad]: its highest saturation level over sigma0. The interval
        [-bound, bound] is invariant under Eq. 7 (and LuGre's law): at z = bound, dz/dt <= 0 for either sign of v."""
        return max(self.coulomb_pos, self.coulomb_neg, *self.static_levels) / self.sigma0

    @property
    def static_levels(self) -> tuple[float, float]:
        """Breakaway levels (v > 0, v < 0) [N m]: the Coulomb levels where no Stribeck level is given."""
        return (
            self.coulomb_pos if self.static_pos is None else self.static_pos,
            self.coulomb_neg if self.static_neg is None else self.static_neg,
        )

    def validate(self, where: str = "friction.joint") -> None:
        """Raise :class:`ConfigError` naming the first non-physical field."""
        if not isinstance(self.model, str) or self.model not in MODELS:
            raise ConfigError(f"{where}.model must be one of {list(MODELS)}, got {self.model!r}")
        for name in ("coulomb_pos", "coulomb_neg", "viscous", "sigma1"):
            _require_nonnegative(getattr(self, name), f"{where}.{name}")
        for name in ("stribeck_velocity", "regularization_velocity"):
            _require_positive(getattr(self, name), f"{where}.{name}")
        for name, coulomb in (("static_pos", self.coulomb_pos), ("static_neg", self.coulomb_neg)):
            value = getattr(self, name)
            if value is not None:
                _require_nonnegative(value, f"{where}.{name}")
                if value < coulomb:
                    raise ConfigError(f"{where}.{name} must be >= the Coulomb level {coulomb}, got {value!r}")
        if self.has_bristles:
            # The bristle law divides by the Coulomb level (Eq. 7) and needs a stiffness.
            for name in ("sigma0", "coulomb_pos", "coulomb_neg"):
                value = getattr(self, name)
                if not (isinstance(value, (int, float)) and math.isfinite(value) and value > 0):
                    raise ConfigError(f"{where}.{name} must be > 0 for the {self.model} model, got {value!r}")


@dataclass
class FrictionParameters:
    """Friction on the Furuta's two joints."""

    arm: JointFrictionParameters = field(default_factory=JointFrictionParameters)  # F_phi
    pendulum: JointFrictionParameters = field(default_factory=JointFrictionParameters)  # F_theta

    def validate(self, where: str = "friction") -> None:
        self.arm.validate(f"{where}.arm")
        self.pendulum.validate(f"{where}.pendulum")


# --- The laws: the one place they are written. Scalars (float, AutoDiffXd or symbolic) or numpy arrays of v. -----


def _functions(v):
    """``math`` for a float (three to ten times cheaper on a scalar), ``pydrake.symbolic`` for a symbolic
    expression (the C++ observers' laws), ``numpy`` for arrays and AutoDiffXd."""
    if isinstance(v, float):
        return math
    return symbolic if is_symbolic(v) else np


def _by_direction(v, positive, negative):
    """``positive`` where v > 0, ``negative`` elsewhere (either when they are equal: no branch on v, whose
    symbolic derivative would be undefined at v = 0)."""
    if isinstance(positive, float) and isinstance(negative, float) and positive == negative:
        return positive
    if isinstance(v, np.ndarray):
        return np.where(v > 0, positive, negative)
    return where(v > 0, positive, negative)


def stribeck_curve(v, p: JointFrictionParameters):
    """g(v) = Fc + (Fs - Fc) exp(-(v / vs)^2) with the levels of the direction of v [N m] (g = Fc without
    Stribeck levels)."""
    coulomb = _by_direction(v, p.coulomb_pos, p.coulomb_neg)
    if p.static_pos is None and p.static_neg is None:
        return coulomb
    static = _by_direction(v, *p.static_levels)
    return coulomb + (static - coulomb) * _functions(v).exp(-((v / p.stribeck_velocity) ** 2))


def static_friction_torque(v, p: JointFrictionParameters):
    """Exerted torque of the static model, -(g(v) tanh(v / v_reg) + b v) [N m]."""
    return -(stribeck_curve(v, p) * _functions(v).tanh(v / p.regularization_velocity) + p.viscous * v)


def bristle_derivative(z, v, p: JointFrictionParameters):
    """dz/dt = v - sigma0 |v| z / Fc(v) (Dahl, Eq. 7) or v - sigma0 |v| z / g(v) (LuGre) [rad/s]."""
    level = _by_direction(v, p.coulomb_pos, p.coulomb_neg) if p.model == "dahl" else stribeck_curve(v, p)
    return v - p.sigma0 * abs(v) * z / level


def bristle_friction_torque(z, v, p: JointFrictionParameters):
    """Exerted torque of the Dahl (-sigma0 z - b v) or LuGre (-(sigma0 z + sigma1 dz/dt + sigma2 v)) model [N m]."""
    torque = p.sigma0 * z + p.viscous * v
    if p.model == "lugre" and p.sigma1 != 0.0:
        torque = torque + p.sigma1 * bristle_derivative(z, v, p)
    return -torque


def project_bristle(z, bound: float):
    """z clipped to its invariant interval [-bound, bound] (``bound``: :attr:`JointFrictionParameters.bristle_bound`).

    The exact flow never leaves it, but an explicit integrator's trial stage can: far outside it the bristle
    rate sigma0 |v| z / Fc and the torque sigma0 z feed each other (the torque accelerates the joint, whose speed
    scales the rate) and overflow within one rejected trial step. Evaluated on the projected state the law is
    bounded, so error control sees a large error and shrinks the step instead."""
    return where(z > bound, bound, where(z < -bound, -bound, z))


def joint_friction_torque(v, z, p: JointFrictionParameters):
    """Exerted torque of ``p``'s model at velocity v and bristle state z (ignored without bristles) [N m]."""
    if p.model == "static":
        return static_friction_torque(v, p)
    if p.has_bristles:
        return bristle_friction_torque(z, v, p)
    return 0.0 * v


def dahl_exact_step(z, v, dt, sigma0, coulomb_level):
    """Exact solution over ``dt`` of dz/dt = v - (sigma0 |v| / Fc) z at frozen v [rad]:
    z_ss + (z - z_ss) exp(-sigma0 |v| dt / Fc), z_ss = Fc sign(v) / sigma0. At v = 0 it holds z (z_ss = 0, no
    decay). Stable at any step: the result lies between z and z_ss. Floats take the math module, three times
    cheaper than numpy on scalars; a symbolic z or v gives the expression of the step."""
    if is_symbolic(z, v, sigma0, coulomb_level):
        level = coulomb_level / sigma0
        z_ss = where(v > 0, level, where(v < 0, -level, 0.0))
        return z_ss + (z - z_ss) * symbolic.exp(-sigma0 * abs(v) * dt / coulomb_level)
    if isinstance(z, float) and isinstance(v, float):
        z_ss = math.copysign(coulomb_level / sigma0, v) if v != 0.0 else 0.0
        return z_ss + (z - z_ss) * math.exp(-sigma0 * abs(v) * dt / coulomb_level)
    z_ss = coulomb_level * np.sign(v) / sigma0
    return z_ss + (z - z_ss) * np.exp(-sigma0 * np.abs(v) * dt / coulomb_level)


def held_input_gain(rate, period: float):
    """int_0^h e^(-r s) ds = -expm1(-r h) / r [s]: what a constant input adds over one ``period`` h [s] to
    dz/dt = -r z + input, r = ``rate`` [1/s] >= 0 (h itself at r = 0). A symbolic rate gives the expression
    2 tanh(r h / 2) / ((1 + tanh(r h / 2)) r), the same function to a few ulp at every r h (there is no symbolic
    expm1, and 1 - exp(-r h) loses its digits as r h -> 0)."""
    if is_symbolic(rate):
        half = symbolic.tanh(rate * period / 2.0)
        return where(rate > 0, 2.0 * half / ((1.0 + half) * rate), period)
    return -math.expm1(-rate * period) / rate if rate > 0 else period


# --- The Drake system ------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class _PlantLayout:
    """Where the two joints sit in a Furuta plant's state, read once so the system keeps no plant reference."""

    num_positions: int
    num_velocities: int
    theta_velocity: int  # index in v
    phi_velocity: int

    @classmethod
    def of(cls, plant) -> _PlantLayout:
        return cls(
            plant.num_positions(),
            plant.num_velocities(),
            plant.GetJointByName(PENDULUM_JOINT).velocity_start(),
            plant.GetJointByName(ARM_JOINT).velocity_start(),
        )


def _friction_joints(layout: _PlantLayout, params: FrictionParameters) -> tuple:
    """(state index of v, generalized-force index, parameters, bristle index or None) of the pendulum and the arm
    joint (paper order), the bristles numbered in that order."""
    joints, bristles = [], 0
    for velocity, p in ((layout.theta_velocity, params.pendulum), (layout.phi_velocity, params.arm)):
        joints.append((layout.num_positions + velocity, velocity, p, bristles if p.has_bristles else None))
        bristles += p.has_bristles
    return tuple(joints)


def _joint_torques(joints: tuple, bounds: tuple, x: list, z: list | None) -> list:
    """[F_theta, F_phi] [N m] (Eq. 3 order) of ``joints`` (:func:`_friction_joints`) at the plant state x and the
    bristles z, each read through :func:`project_bristle` with its ``bounds``."""
    return [
        joint_friction_torque(x[state], None if k is None else project_bristle(z[k], bounds[k]), p)
        for state, _, p, k in joints
    ]


def _bristle_rates(bristle_joints: tuple, bounds: tuple, x: list, z: list) -> list:
    """dz/dt [rad/s] (Eq. 7, or LuGre's) of the bristles of ``bristle_joints`` at the plant state x and the
    bristles z, each read through :func:`project_bristle` with its ``bounds``."""
    return [bristle_derivative(project_bristle(z[k], bounds[k]), x[state], p) for state, _, p, k in bristle_joints]


@TemplateSystem.define("JointFriction_", T_list=(float, AutoDiffXd))
def JointFriction_(T):

    class Impl(LeafSystem_[T]):
        """Friction on the arm (phi) and pendulum (theta) joints of the Furuta ``MultibodyPlant``.

        Input ``plant_state`` (connect the plant's state output). Outputs ``generalized_force_Nm`` (plant
        velocity order, for the plant's applied-generalized-force input) and ``friction_torque_Nm`` =
        [F_theta, F_phi] (Eq. 3 order). Continuous state: one bristle z [rad] per joint with a Dahl or LuGre
        model, pendulum before arm; the laws read it through :func:`project_bristle`, so an integrator's trial
        stage outside the bristle's physical range stays finite. Scalar-convertible to AutoDiffXd, so
        ``Linearize`` works through it.
        """

        def _construct(self, plant, params: FrictionParameters, converter=None):
            self._declare(_PlantLayout.of(plant), params, converter)

        def _construct_copy(self, other, converter=None):
            self._declare(other._layout, other._params, converter)

        def _declare(self, layout: _PlantLayout, params: FrictionParameters, converter):
            LeafSystem_[T].__init__(self, converter)
            params.validate()
            self._layout, self._params = layout, params
            self._joints = _friction_joints(layout, params)
            self._bristle_joints = tuple(j for j in self._joints if j[3] is not None)
            self._bounds = tuple(p.bristle_bound for _, _, p, _ in self._bristle_joints)
            self._dtype = float if T is float else object
            self._state_port = self.DeclareVectorInputPort("plant_state", layout.num_positions + layout.num_velocities)
            tickets = {self._state_port.ticket()}
            if self._bristle_joints:
                self.DeclareContinuousState(len(self._bristle_joints))
                tickets.add(self.xc_ticket())
            self.DeclareVectorOutputPort(
                "generalized_force_Nm",
                layout.num_velocities,
                self._calc_generalized_force,
                prerequisites_of_calc=tickets,
            )
            self.DeclareVectorOutputPort(
                "friction_torque_Nm", 2, self._calc_friction_torque, prerequisites_of_calc=tickets
            )

        def _plant_state_and_bristles(self, context):
            """The plant state and the bristles z [rad] (None without any) as lists: Python floats for T = float,
            so that the laws take math."""
            x = self._state_port.Eval(context).tolist()
            z = context.get_continuous_state_vector().CopyToVector().tolist() if self._bristle_joints else None
            return x, z

        def _torques(self, context):
            """[F_theta, F_phi] [N m] (Eq. 3 order)."""
            return _joint_torques(self._joints, self._bounds, *self._plant_state_and_bristles(context))

        def _calc_generalized_force(self, context, output):
            # Evaluated at every integrator stage: for floats, written through the output's array view.
            force = output.get_mutable_value() if T is float else np.empty(output.size(), dtype=object)
            force[:] = 0.0
            for (_, index, _, _), torque in zip(self._joints, self._torques(context)):
                force[index] = torque
            if T is not float:
                output.SetFromVector(force)

        def _calc_friction_torque(self, context, output):
            output.SetFromVector(np.array(self._torques(context), dtype=self._dtype))

        def DoCalcTimeDerivatives(self, context, derivatives):
            if not self._bristle_joints:
                return
            rates = _bristle_rates(self._bristle_joints, self._bounds, *self._plant_state_and_bristles(context))
            derivatives.get_mutable_vector().SetFromVector(np.array(rates, dtype=self._dtype))

    return Impl


JointFriction = JointFriction_[None]


class JointFrictionSystem(Diagram):
    """:class:`JointFriction`'s laws evaluated in C++: a ``SymbolicVectorSystem`` of the same expressions (the laws
    above on symbolic variables) and a ``MatrixGain`` to the plant's velocity order. Same ports, same continuous
    state (the bristles, pendulum before arm) and the same torques to rounding; float only (``Linearize`` takes
    :class:`JointFriction`).

    Input ``plant_state``; outputs ``generalized_force_Nm`` (plant velocity order) and ``friction_torque_Nm`` =
    [F_theta, F_phi] (Eq. 3 order). A law without bristles has no state: its block's dynamics are a placeholder
    0 of size zero (a stateless ``SymbolicVectorSystem`` refuses to give time derivatives, which a continuous
    diagram asks of every block)."""

    def __init__(self, plant, params: FrictionParameters):
        Diagram.__init__(self)
        params.validate()
        layout = _PlantLayout.of(plant)
        joints = _friction_joints(layout, params)
        bristle_joints = tuple(j for j in joints if j[3] is not None)
        bounds = tuple(p.bristle_bound for _, _, p, _ in bristle_joints)
        x_vars = list(MakeVectorVariable(layout.num_positions + layout.num_velocities, "x"))
        z_vars = list(MakeVectorVariable(len(bristle_joints), "z")) if bristle_joints else []
        x, z = ([Expression(v) for v in variables] for variables in (x_vars, z_vars))
        torques = _joint_torques(joints, bounds, x, z)
        rates = _bristle_rates(bristle_joints, bounds, x, z) if bristle_joints else [Expression(0.0)]
        law = SymbolicVectorSystem(
            state=z_vars,
            input=x_vars,
            dynamics=rates,
            output=torques,
        )
        to_generalized = np.zeros((layout.num_velocities, 2))
        for row, (_, index, _, _) in enumerate(joints):
            to_generalized[index, row] = 1.0
        builder = DiagramBuilder()
        law = builder.AddNamedSystem("law", law)
        force = builder.AddNamedSystem("to_generalized_force", MatrixGain(to_generalized))
        builder.Connect(law.get_output_port(), force.get_input_port())
        builder.ExportInput(law.get_input_port(), "plant_state")
        builder.ExportOutput(force.get_output_port(), "generalized_force_Nm")
        builder.ExportOutput(law.get_output_port(), "friction_torque_Nm")
        builder.BuildInto(self)
