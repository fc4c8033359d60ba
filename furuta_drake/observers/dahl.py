"""Dahl friction observer of the arm, paper Eq. 8-9 with the gain K_sigma of Eq. 16, and its adaptation:

    z_hat' = v - sigma0 |v| z_hat / Fc(v) + K_z,
    K_z    = -(sigma0 / rho) (1 + s1 sigma1 |v| / Fc(v)) [eps_phi + rho2 eps_v],
    F_hat  = -K_sigma sigma0 z_hat.

v is the nested velocity estimate (the VFE's arm velocity, an input port: the rig measures angles only),
eps_phi = phi - phi_ref and eps_v = v - v_ref the controller's tracking errors (reference zero when
balancing), Fc(v) the observer's Coulomb level for the sign of v. F_hat is the friction torque EXERTED on the
arm (opposite to the velocity, the package's convention), so Eq. 8's F_hat = sigma0 z_hat and Eq. 16's printed
"d/dt F_hat" are read as F_hat = -K_sigma sigma0 z_hat (``docs/paper.md``); with this sign Eq. 18 is a gradient descent
as printed. A controller compensates with u = u_LQ - F_hat; with the printed sign of K_z an arm displaced to
phi > phi_ref at rest makes z_hat fall and F_hat grow, so u pushes the arm back: an integral action of gain
K_sigma sigma0^2 / rho. On a free arm that restores; in the balancing loop it does not: the LQR moves the arm
through the pendulum (K_phi < 0), and the linearized loop at rest (:mod:`furuta_drake.paper.stability`) has a slow
unstable mode with the printed sign and none with ``injection_sign = -1``. In the nonlinear loop the stick-slip
limit cycle hides it, so the default stays the paper's.

Sign s1 of the sigma1 term (``sigma1_sign``, ``docs/paper.md``): Eq. 9 prints +. The cited design (Freidovich et al.
2006) is for LuGre, F = sigma0 z + sigma1 z' + sigma2 v = sigma0 (1 - sigma1 |v| / g(v)) z + (sigma1 + sigma2) v,
so the observer error z - z_hat reaches the motion through sigma0 (1 - sigma1 |v| / g) and the injection that
cancels that cross term in a Lyapunov function must carry the same factor: the default is s1 = -1. (The paper
was not available to check its printed form; both signs are offered.) A Dahl model has no sigma1, and the
default sigma1 = 0 makes the choice moot.

Discrete at the control period h with the inputs frozen over the period: the z equation is then linear with a
constant input, dz/dt = (v + K_z) - r z, r = sigma0 |v| / Fc, and it takes its EXACT step, the Dahl part by
:func:`furuta_drake.friction.dahl_exact_step` plus K_z (1 - e^(-r h)) / r (K_z h when v = 0). An exact
exponential step is stable at any stiffness r (the Dahl state's rate reaches 1e4 1/s at a few rad/s) where an
explicit Euler step at 1 kHz diverges once r h > 2, and it settles to the continuous steady state exactly. The
step (:func:`dahl_step`) is written once for floats and symbolic expressions; the observer evaluates its
expression in C++ (:mod:`furuta_drake.symbolic_system`), no Python call at a sample.

LuGre (Sec. VII's open point, Freidovich et al. 2006): with Stribeck levels (``static_pos/neg``,
``stribeck_velocity``), ``sigma1`` and ``sigma2`` the same system is the LuGre observer: Fc(v) becomes the
Stribeck curve g(v) in the z equation and F_hat = -K_sigma (sigma0 z_hat + sigma1 z_hat' + sigma2 v), z_hat' the
model's bristle rate (friction.bristle_friction_torque). Without them it is exactly Dahl. ``joint='pendulum'``
observes the pendulum's friction F_theta from the pendulum velocity estimate; nothing can compensate it (the
pendulum has no actuator), so it feeds the VFE observer only and, with ``rho = None``, runs without injection.

Adaptation (``DahlObserverParameters.adaptation``, an optional section): none (K_sigma = 1), the paper's
K_sigma law (Eq. 16-18, :class:`~furuta_drake.observers.k_sigma.KSigmaAdapter`) or the adaptation of Fc+/- and
sigma0 (Sec. VII, :class:`~furuta_drake.observers.parameter_adaptation.DahlParameterAdapter`). Each law is its
own system beside this one (:func:`add_dahl_adaptation` wires it): it reads z_hat, v and the VFE observer's
eps_hat_F and gives this observer its gain or its parameters.

Defaults: the paper's measured arm levels (0.012 N m for v > 0, 0.018 for v < 0, Sec. V-D), sigma0 = 10 N m/rad
(``docs/paper.md``), and rho = 100 N m s/rad, rho2 = 0.1 s: a gentle injection (K_z / v of a few percent over Table I's
motion, eps_phi ~ 0.05 rad, v ~ 0.5 rad/s), so that F_hat reflects the Dahl model's calibration, as in Fig. 5.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from pydrake.symbolic import MakeVectorVariable, Variable
from pydrake.systems.framework import Diagram, DiagramBuilder, OutputPort, System
from pydrake.systems.primitives import PassThrough

from furuta_drake.errors import ConfigError, require_control_period
from furuta_drake.friction import (
    JointFrictionParameters,
    bristle_friction_torque,
    dahl_exact_step,
    held_input_gain,
    stribeck_curve,
)
from furuta_drake.observers.k_sigma import KSigmaAdaptationParameters, KSigmaAdapter
from furuta_drake.observers.parameter_adaptation import DahlParameterAdapter, ParameterAdaptationParameters
from furuta_drake.symbolic_system import build_into, discrete_symbolic_system, where

JOINTS = ("arm", "pendulum")


@dataclass
class DahlAdaptation:
    """How the arm's Dahl observer adapts: exactly one of ``k_sigma`` (the paper's one-gain law, Eq. 16-18) and
    ``parameters`` (Fc+/- and sigma0, Sec. VII)."""

    k_sigma: KSigmaAdaptationParameters | None = None
    parameters: ParameterAdaptationParameters | None = None

    def validate(self, where: str = "observers.dahl.adaptation") -> None:
        if (self.k_sigma is None) == (self.parameters is None):
            raise ConfigError(
                f"{where} must give exactly one of k_sigma (Eq. 18) and parameters (Fc and sigma0, "
                f"Sec. VII); null switches adaptation off"
            )
        if self.k_sigma is not None:
            self.k_sigma.validate(f"{where}.k_sigma")
        else:
            self.parameters.validate(f"{where}.parameters")


@dataclass
class DahlObserverParameters:
    """The observer's Dahl model (Eq. 8), or LuGre model with Stribeck levels, Eq. 9's design constants and the
    optional adaptation."""

    coulomb_pos: float = 0.012  # Fc used while v > 0 [N m]
    coulomb_neg: float = 0.018  # Fc used while v <= 0 [N m]
    sigma0: float = 10.0  # bristle stiffness [N m/rad]
    sigma1: float = 0.0  # bristle damping [N m s/rad] (LuGre; also Eq. 9's injection factor)
    sigma1_sign: int = -1  # sign of the sigma1 term of Eq. 9 (printed +1; see the module docstring)
    rho: float | None = 100.0  # injection scale [N m s/rad]: K_z = -(sigma0/rho) (...) [eps + rho2 eps_v]; None: off
    rho2: float = 0.1  # velocity-error weight [s]
    injection_sign: int = 1  # sign of K_z (Eq. 9 printed: +1); -1 reverses it (see furuta_drake.paper.stability)
    period: float | None = None  # [s] optional: the observer runs at the control period; a stated one must equal it
    static_pos: float | None = None  # LuGre Stribeck breakaway level Fs+ [N m]; None: no Stribeck (Dahl)
    static_neg: float | None = None  # Fs- [N m]
    stribeck_velocity: float = 0.05  # vs [rad/s]
    sigma2: float = 0.0  # viscous coefficient [N m s/rad] (LuGre)
    adaptation: DahlAdaptation | None = None  # None: K_sigma = 1 and the parameters fixed

    def validate(self, where: str = "observers.dahl") -> None:
        for name in ("coulomb_pos", "coulomb_neg", "sigma0", "stribeck_velocity"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ConfigError(f"{where}.{name} must be > 0, got {value!r}")
        if self.period is not None and not (math.isfinite(self.period) and self.period > 0):
            raise ConfigError(f"{where}.period must be > 0 (or null: the control period), got {self.period!r}")
        if self.rho is not None and not (math.isfinite(self.rho) and self.rho > 0):
            raise ConfigError(f"{where}.rho must be > 0 (or null: no injection), got {self.rho!r}")
        for name in ("sigma1", "rho2", "sigma2"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value >= 0):
                raise ConfigError(f"{where}.{name} must be >= 0, got {value!r}")
        for name in ("sigma1_sign", "injection_sign"):
            if getattr(self, name) not in (1, -1):
                raise ConfigError(f"{where}.{name} must be 1 or -1, got {getattr(self, name)!r}")
        self.friction_law().validate(where)
        if self.adaptation is not None:
            self.adaptation.validate(f"{where}.adaptation")
            if self.adaptation.parameters is not None and (
                self.sigma1 > 0 or self.sigma2 > 0 or self.static_pos is not None or self.static_neg is not None
            ):
                raise ConfigError(
                    f"{where}.adaptation.parameters adapts a Dahl model: {where} must have no Stribeck "
                    f"levels, sigma1 or sigma2"
                )

    def friction_law(self) -> JointFrictionParameters:
        """The observer's model as a friction law of :mod:`furuta_drake.friction` (LuGre; Dahl without
        Stribeck levels, sigma1 and sigma2)."""
        return JointFrictionParameters(
            model="lugre",
            coulomb_pos=self.coulomb_pos,
            coulomb_neg=self.coulomb_neg,
            static_pos=self.static_pos,
            static_neg=self.static_neg,
            stribeck_velocity=self.stribeck_velocity,
            viscous=self.sigma2,
            sigma0=self.sigma0,
            sigma1=self.sigma1,
        )


class DahlFrictionObserver(Diagram):
    """Eq. 8-9, 16 of one joint (the arm by default), discrete at the control period ``period`` [s] (exact step,
    see the module docstring), evaluated in C++ (:func:`~furuta_drake.symbolic_system.discrete_symbolic_system`
    of :func:`dahl_step` and :func:`model_torque`). An adapting observer reads its adapted model from its adapter
    (arm only; wired by :func:`add_dahl_adaptation`).

    Inputs: ``{joint}_velocity_estimate_rad_per_s`` (v), ``measured_angles_rad`` ([theta, phi]; the joint's
    angle gives eps), ``arm_reference_rad`` (arm only: [phi_ref [rad], v_ref [rad/s]]; connect [0, 0] to regulate
    about the upright) and, when adapting, ``K_sigma`` (Eq. 16's gain of v's sign,
    :class:`~furuta_drake.observers.k_sigma.KSigmaAdapter`) or ``dahl_parameters`` ([Fc+ [N m], Fc- [N m], sigma0
    [N m/rad]] of :class:`~furuta_drake.observers.parameter_adaptation.DahlParameterAdapter`). Discrete state
    z_hat [rad]. Outputs: ``friction_estimate_Nm`` (F_hat = -K_sigma sigma0 z_hat [N m] for Dahl; feeds through
    K_sigma, and v for LuGre's sigma1, sigma2), ``bristle_state_rad`` (z_hat, no feedthrough) and, with
    ``dahl_parameters``, ``bristle_injection_rad_per_s`` (K_z of Eq. 9, which the parameter law's sensitivities
    follow).
    """

    def __init__(self, params: DahlObserverParameters | None = None, *, period: float, joint: str = "arm"):
        Diagram.__init__(self)
        params = params or DahlObserverParameters()
        _check(params, period, joint)
        self.params, self.joint, self.period = params, joint, period
        build_into(self, _observer_law(params, period, joint))


def _check(params: DahlObserverParameters, period: float, joint: str) -> None:
    """Raise :class:`ConfigError` unless ``params`` fit an observer of ``joint`` at the control ``period``."""
    params.validate()
    section = "observers.dahl" if joint == "arm" else "observers.pendulum_friction"
    require_control_period(params.period, period, f"{section}.period")
    if joint not in JOINTS:
        raise ConfigError(f"DahlFrictionObserver joint must be one of {list(JOINTS)}, got {joint!r}")
    if params.adaptation is not None and joint != "arm":
        raise ConfigError(f"DahlFrictionObserver: only the arm's observer adapts, got an adaptation for the {joint}'s")


def _observer_law(params: DahlObserverParameters, period: float, joint: str):
    """The observer's C++ system: :func:`dahl_step` and the outputs as expressions of its ports' variables."""
    v, z = Variable(f"{joint}_velocity"), Variable("z_hat")
    angles = list(MakeVectorVariable(2, "measured_angle"))
    inputs = [(f"{joint}_velocity_estimate_rad_per_s", [v]), ("measured_angles_rad", angles)]
    eps, eps_v = angles[1 if joint == "arm" else 0], v
    if joint == "arm":
        reference = list(MakeVectorVariable(2, "arm_reference"))
        inputs.append(("arm_reference_rad", reference))
        eps, eps_v = eps - reference[0], v - reference[1]
    adaptation, gain, adapted = params.adaptation, None, None
    if adaptation is not None and adaptation.k_sigma is not None:
        gain = Variable("K_sigma")
        inputs.append(("K_sigma", [gain]))
    elif adaptation is not None:
        adapted = list(MakeVectorVariable(3, "dahl_parameter"))
        inputs.append(("dahl_parameters", adapted))
    sigma0, level = observer_model(params, v, adapted)
    torque = model_torque(params, z, v, sigma0)
    outputs = [("friction_estimate_Nm", [torque if gain is None else gain * torque]), ("bristle_state_rad", [z])]
    if adapted is not None:
        outputs.append(("bristle_injection_rad_per_s", [injection(params, sigma0, v, level, eps, eps_v)]))
    return discrete_symbolic_system(
        name=f"{joint}_dahl_law",
        period=period,
        state=[z],
        initial=[0.0],
        update=[dahl_step(params, period, z, v, sigma0, level, eps, eps_v)],
        inputs=inputs,
        outputs=outputs,
    )


def observer_model(p: DahlObserverParameters, v, adapted=None) -> tuple:
    """(sigma0 [N m/rad], the level g(v) [N m]) of the observer's model at v: ``adapted`` = [Fc+, Fc-, sigma0]
    when it adapts them (the Coulomb level of v's direction), else its own (the Stribeck curve for LuGre)."""
    if adapted is not None:
        return adapted[2], where(v > 0, adapted[0], adapted[1])
    return p.sigma0, stribeck_curve(v, p.friction_law())


def model_torque(p: DahlObserverParameters, z, v, sigma0):
    """F of the observer's model at z [rad]: -sigma0 z (Dahl, sigma0 [N m/rad] the adapted one when adapting) or
    the LuGre torque at v [N m]."""
    if p.sigma1 > 0 or p.sigma2 > 0:
        return bristle_friction_torque(z, v, p.friction_law())
    return -sigma0 * z


def dahl_step(p: DahlObserverParameters, period: float, z, v, sigma0, level, eps, eps_v):
    """Eq. 8-9 over one ``period`` [s] from z_hat = z [rad]: the exact step with K_z held (module docstring).
    Floats, or symbolic expressions for the C++ observer."""
    z_next = dahl_exact_step(z, v, period, sigma0, level)
    if p.rho is None:
        return z_next
    return z_next + held_input_gain(sigma0 * abs(v) / level, period) * injection(p, sigma0, v, level, eps, eps_v)


def injection(p: DahlObserverParameters, sigma0, v, level, eps, eps_v):
    """K_z of Eq. 9 [rad/s]: -s (sigma0 / rho) (1 + s1 sigma1 |v| / g(v)) (eps + rho2 eps_v), s = injection_sign,
    at v [rad/s] with the model's sigma0 [N m/rad] and level g(v) [N m] and Eq. 9's errors eps [rad], eps_v
    [rad/s]; 0 without injection (rho None)."""
    if p.rho is None:
        return 0.0
    return (
        -p.injection_sign
        * (sigma0 / p.rho)
        * (1.0 + p.sigma1_sign * p.sigma1 * abs(v) / level)
        * (eps + p.rho2 * eps_v)
    )


def add_dahl_adaptation(
    builder: DiagramBuilder,
    dahl: DahlFrictionObserver,
    *,
    velocity: OutputPort,
    friction_error: OutputPort,
    name: str,
    error_response=None,
) -> System | None:
    """The adapter of ``dahl``'s ``params.adaptation`` added to ``builder`` as ``name`` (None without one), on the
    observer's arm ``velocity`` estimate [rad/s] and the VFE's ``friction_error`` eps_hat_F [N m], wired to the
    observer both ways. ``error_response``: that VFE's ``friction_error_response`` (the Fc and sigma0 law)."""
    p = dahl.params
    if p.adaptation is None:
        return None
    if p.adaptation.k_sigma is not None:
        adapter = builder.AddNamedSystem(name, KSigmaAdapter(p.adaptation.k_sigma, period=dahl.period, sigma0=p.sigma0))
        builder.Connect(adapter.GetOutputPort("K_sigma"), dahl.GetInputPort("K_sigma"))
    else:
        if error_response is None:
            raise ConfigError(
                "observers.dahl.adaptation.parameters needs the VFE observer's error response (error_response)"
            )
        adapter = builder.AddNamedSystem(
            name,
            DahlParameterAdapter(
                p.adaptation.parameters,
                period=dahl.period,
                coulomb_pos=p.coulomb_pos,
                coulomb_neg=p.coulomb_neg,
                sigma0=p.sigma0,
                error_response=error_response,
            ),
        )
        builder.Connect(adapter.GetOutputPort("dahl_parameters"), dahl.GetInputPort("dahl_parameters"))
        builder.Connect(
            dahl.GetOutputPort("bristle_injection_rad_per_s"), adapter.GetInputPort("bristle_injection_rad_per_s")
        )
    builder.Connect(velocity, adapter.GetInputPort("arm_velocity_estimate_rad_per_s"))
    builder.Connect(dahl.GetOutputPort("bristle_state_rad"), adapter.GetInputPort("bristle_state_rad"))
    builder.Connect(friction_error, adapter.GetInputPort("friction_error_estimate_Nm"))
    return adapter


def adapting_dahl_observer(
    params: DahlObserverParameters, *, period: float, error_response=None
) -> tuple[Diagram, DahlFrictionObserver, System | None]:
    """The arm's Dahl observer and its adapter (:func:`add_dahl_adaptation`) as one Diagram, to run the pair on
    its own: inputs ``arm_velocity_estimate_rad_per_s``, ``measured_angles_rad``, ``arm_reference_rad`` and
    ``friction_error_estimate_Nm``; outputs the observer's and the adapter's, under their own names. Returns
    (diagram, observer, adapter or None)."""
    builder = DiagramBuilder()
    dahl = builder.AddNamedSystem("dahl_observer", DahlFrictionObserver(params, period=period))
    velocity = builder.AddNamedSystem("arm_velocity", PassThrough(1))
    error = builder.AddNamedSystem("friction_error", PassThrough(2))
    builder.ExportInput(velocity.get_input_port(), "arm_velocity_estimate_rad_per_s")
    builder.Connect(velocity.get_output_port(), dahl.GetInputPort("arm_velocity_estimate_rad_per_s"))
    for name in ("measured_angles_rad", "arm_reference_rad"):
        builder.ExportInput(dahl.GetInputPort(name), name)
    builder.ExportInput(error.get_input_port(), "friction_error_estimate_Nm")
    adapter = add_dahl_adaptation(
        builder,
        dahl,
        velocity=velocity.get_output_port(),
        friction_error=error.get_output_port(),
        name="adapter",
        error_response=error_response,
    )
    for system in (dahl, adapter) if adapter is not None else (dahl,):
        for i in range(system.num_output_ports()):
            builder.ExportOutput(system.get_output_port(i), system.get_output_port(i).get_name())
    return builder.Build(), dahl, adapter
