"""The effect vocabulary as candidates: the forms each effect comes in, their parameters, bounds and starts, and
how a fitted effect changes the surrogate model.

Every parameter is in SI units and is the effect's own level (not an increment over the rig file), as the
report's ranking lists it. Real hardware has more than one form of an effect, so a candidate may hold several
:class:`Form` s; the fit keeps the form that explains the train data best and the report names it:

- arm friction (Coulomb, asymmetric, Stribeck) ``presliding``: Dahl friction (Eq. 7), or LuGre with the Stribeck
  curve, with a fitted presliding displacement (the bristle spring a real joint shows at every velocity
  reversal; a static law with stiction is its small end); ``smooth``: the static law with a fitted
  regularisation velocity, F = -g(v) tanh(v / v_reg) (a joint that never sticks, as simulators often write it);
- dead zone ``subtract``: u - sat_w(u) (the width is taken off every larger command, Simulink's Dead Zone);
  ``threshold``: u where |u| > w, else 0 (small commands are dropped, larger ones pass whole);
- input delay ``fixed``: the command held ``delay`` late; ``jitter``: a delay drawn anew every sample (a USB link,
  a scheduler), uniform on delay +- sqrt(3) delay_spread, whose expected command the model applies;
- saturation ``hard``: a clip at the limit; ``smooth``: L tanh(u / L) (a drive that saturates gradually);
- measurement noise ``white``; ``correlated``: first-order low-passed with a ``correlation_time`` (an interface that
  filters before it logs), both read from the angles' second differences;
- spring ``linear``: -k (phi - phi_0); ``cubic``: -(k x + k3 x^3), x = phi - phi_0 (a cable that stiffens);
- a drive's backlash (half-width b) and compliance (a spring k and damper c between its rotor and the arm), of
  :mod:`furuta_drake.drive`'s laws: offered only for a rig file that states a drive, whose gear ratio and rotor
  inertia give the rotor's inertia (a fitted inertia would trade against the stiffness at the rates logs have).

Scales come from the rig: torques from m g l and the logged commands, damping from the lumped inertias, times
from the sample period.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from furuta_drake.drive import CONTACT_FREQUENCY
from furuta_drake.effects.surrogate import LUMPED_CONSTANTS, Model
from furuta_drake.effects.torque_library import library_terms
from furuta_drake.friction import JointFrictionParameters


@dataclass(frozen=True)
class Scales:
    """Physical scales of a rig and its logs that set bounds and starts."""

    torque: float  # m g l [N m]
    command: float  # largest |command| in the train logs [N m]
    arm_inertia: float  # a [kg m^2]
    pendulum_inertia: float  # b [kg m^2]
    period: float  # [s]
    command_levels: tuple[float, ...] = ()  # quantiles COMMAND_QUANTILES of |command| in the train logs [N m]
    regressed: dict = field(default_factory=dict)  # effect -> {param: value}: the train logs' equation-error
    # estimates, a start of each form that has those parameters (:func:`form_starts`)
    drive_inertia: float = 0.0  # mu = J (a - J) / a [kg m^2]: the reduced inertia of the rig file's drive's rotor J
    # and the arm side (0: the rig file states no drive)


@dataclass(frozen=True)
class Form:
    """One form of an effect: its parameters, their search bounds and starts, and its change of the model."""

    name: str
    params: tuple[str, ...]
    bounds: Callable[[Scales], tuple[list[float], list[float]]]
    starts: Callable[[Scales], list[list[float]]]
    apply: Callable[[Model, np.ndarray], Model]
    jump: int | None = None  # the parameter at which the cost jumps, found by a line search (fit's jumps module)
    simpler: str | None = None  # the form this one nests (its last parameter at its lower bound): named instead
    # unless that parameter's interval stays off the bound


@dataclass(frozen=True)
class Candidate:
    """An effect of the vocabulary. ``main``: the parameter whose size the detection limit states, with the
    value the nominal model has (``neutral``); ``fit`` False: estimated from the data directly (sensor
    effects). ``vanishes``: the parameters that set the effect's size, each with the value at which the effect
    vanishes ("upper": the end of its search range); ``nested``: (parameter, "lower" | "upper", the simpler law)
    for a search range's end at which the law is a simpler one of the vocabulary (presliding at zero is a sticking
    Coulomb law), not a law stretched beyond its shape."""

    name: str
    forms: tuple[Form, ...]
    main: str
    neutral: float = 0.0
    fit: bool = True
    vanishes: tuple[tuple[str, float | str], ...] = ()
    nested: tuple[tuple[str, str, str], ...] = ()
    drive: bool = False  # an effect of the rig file's drive (its rotor's inertia read there): offered with one only
    look_alike: tuple[tuple[str, str], ...] = ()  # (another effect, why the two look alike on logs): the report
    # names the pair beside the accepted effect, with what the other removes on its own

    def offered(self, model: Model) -> bool:
        """Whether the effect can act in ``model``: a drive's needs the rig file's drive (a rotor of its own)."""
        return not self.drive or model.rotor_share > 0

    def form(self, name: str) -> Form:
        return next(f for f in self.forms if f.name == name)

    def is_null(self, effect: Effect, scales: Scales) -> bool:
        """Whether ``effect`` is at zero size: every parameter of ``vanishes`` its form has within
        ``NULL_TOLERANCE`` of its search range from the value at which the effect vanishes."""
        form = self.form(effect.form)
        low, high = form.bounds(scales)
        values = dict(zip(form.params, effect.values))
        spans = {param: (lo, hi) for param, lo, hi in zip(form.params, low, high)}
        checked = [(param, null) for param, null in self.vanishes if param in values]
        return bool(checked) and all(
            abs(values[param] - (spans[param][1] if null == "upper" else null))
            <= NULL_TOLERANCE * (spans[param][1] - spans[param][0])
            for param, null in checked
        )

    def nested_law(self, param: str, end: str) -> str | None:
        """The simpler law this candidate is with ``param`` at the ``end`` ("lower" | "upper") of its range, or None."""
        return next((law for name, side, law in self.nested if name == param and side == end), None)

    @property
    def params(self) -> tuple[str, ...]:
        """The first form's parameters."""
        return self.forms[0].params


@dataclass(frozen=True)
class Effect:
    """A fitted (or stated) effect: the form and its parameter values in the form's order (SI)."""

    form: str
    values: tuple[float, ...] = field(default=())

    def __post_init__(self):
        object.__setattr__(self, "values", tuple(float(v) for v in self.values))


NULL_TOLERANCE = 1e-3  # a size parameter within this fraction of its range from its null value is zero
PRESLIDING = (1e-5, 0.05)  # bounds of the presliding displacement Fc / sigma0 of the arm friction [rad]
# Starts of the presliding displacement and the regularisation velocity: each sets the travel or the velocity at
# which the friction torque turns, a bend the cost is non-convex in, so a log grid spans their bounds' middle.
PRESLIDING_STARTS = (1e-3, 3e-3, 1e-2)  # [rad]
REGULARIZATION = (1e-4, 1.0)  # bounds of the smooth form's regularisation velocity [rad/s]
REGULARIZATION_STARTS = (3e-3, 0.01, 0.03, 0.1)  # [rad/s]
# Starts of the Stribeck curve: its velocity sets where the torque falls from the static level to Coulomb's (from
# one start, 0.1 rad/s, the fit of a fast curve stalls on a slow one or on the smooth form), so a log grid spans
# its bounds; the static level starts at twice the Coulomb level.
STRIBECK_VELOCITY_STARTS = (0.03, 0.1, 0.3)  # [rad/s]
# Starts of the arm friction levels [m g l]: the cost is multimodal in the level (a level far too low leaves the
# arm free to move in the model where it sticks in the data, and the fit stalls), so they span two decades.
FRICTION_LEVEL_STARTS = (0.005, 0.02, 0.06, 0.2)
UNITS = {
    "coulomb": "N m",
    "coulomb_pos": "N m",
    "coulomb_neg": "N m",
    "static": "N m",
    "presliding": "rad",
    "regularization_velocity": "rad/s",
    "stribeck_velocity": "rad/s",
    "viscous": "N m s/rad",
    "counts_per_rev": "counts/rev",
    "noise_std": "rad",
    "delay": "s",
    "delay_spread": "s",
    "gain": "-",
    "deadzone": "N m",
    "time_constant": "s",
    "correlation_time": "s",
    "limit": "N m",
    "stiffness": "N m/rad",
    "cubic_stiffness": "N m/rad^3",
    "equilibrium": "rad",
    "arm_inertia_scale": "-",
    "pendulum_inertia_scale": "-",
    "coupling_scale": "-",
    "gravity_scale": "-",
    "arm_inertia_total": "kg m^2",
    "backlash": "rad",
    "damping": "N m s/rad",
    "pendulum_inertia_total": "kg m^2",
    "coupling": "kg m^2",
    "gravity_torque": "N m",
}


def _bristle_arm(
    model: Model,
    coulomb_pos: float,
    coulomb_neg: float,
    presliding: float,
    static: float | None = None,
    stribeck_velocity: float = 0.05,
) -> Model:
    """The arm's friction replaced by Dahl's (Eq. 7; levels per direction) or, with a ``static`` level, LuGre's
    without bristle damping: sigma0 = the largest saturation level / ``presliding``, the viscous term kept."""
    coulomb_pos, coulomb_neg = max(coulomb_pos, 1e-12), max(coulomb_neg, 1e-12)
    if static is None:
        return model.replace(
            arm_friction=JointFrictionParameters(
                model="dahl",
                coulomb_pos=coulomb_pos,
                coulomb_neg=coulomb_neg,
                sigma0=max(coulomb_pos, coulomb_neg) / presliding,
                viscous=model.arm_friction.viscous,
            )
        )
    static = max(static, coulomb_pos)
    return model.replace(
        arm_friction=JointFrictionParameters(
            model="lugre",
            coulomb_pos=coulomb_pos,
            coulomb_neg=coulomb_pos,
            static_pos=static,
            static_neg=static,
            stribeck_velocity=stribeck_velocity,
            sigma0=static / presliding,
            sigma1=0.0,
            viscous=model.arm_friction.viscous,
        )
    )


def _smooth_arm(
    model: Model,
    coulomb_pos: float,
    coulomb_neg: float,
    regularization: float,
    static: float | None = None,
    stribeck_velocity: float = 0.05,
) -> Model:
    """The arm's friction replaced by the static law -(g(v) tanh(v / v_reg) + b v), the viscous term kept."""
    return model.replace(
        arm_friction=JointFrictionParameters(
            model="static",
            coulomb_pos=coulomb_pos,
            coulomb_neg=coulomb_neg,
            static_pos=None if static is None else max(static, coulomb_pos),
            static_neg=None if static is None else max(static, coulomb_pos),
            stribeck_velocity=stribeck_velocity,
            regularization_velocity=regularization,
            viscous=model.arm_friction.viscous,
        )
    )


def form_starts(name: str, form: Form, scales: Scales) -> list[list[float]]:
    """The starts of ``form`` of the effect ``name`` and, where ``scales`` carries an equation-error estimate of the
    effect (``Scales.regressed``), each start with the estimated parameters put in (once each): a fit can then start
    where a large error lies."""
    starts = form.starts(scales)
    regressed = scales.regressed.get(name)
    if not regressed:
        return starts
    extra = []
    for start in starts:
        moved = [float(regressed.get(param, value)) for param, value in zip(form.params, start)]
        if moved not in extra and moved not in starts:
            extra.append(moved)
    return starts + extra


def _arm(m: Model, **changes) -> Model:
    return m.replace(arm_friction=dataclasses.replace(m.arm_friction, **changes))


def _friction_forms(
    params: tuple[str, ...], bounds: Callable, starts: Callable, bristle: Callable, smooth: Callable
) -> tuple[Form, ...]:
    """The ``presliding`` and ``smooth`` forms of an arm friction candidate: its ``params`` (levels, then any
    Stribeck parameters) with ``bounds(s)`` and ``starts(s)``, then the presliding displacement or the
    regularisation velocity, each with its own bounds and starts."""

    def form(name, last, last_bounds, last_starts, apply):
        return Form(
            name,
            params + (last,),
            lambda s: (bounds(s)[0] + [last_bounds[0]], bounds(s)[1] + [last_bounds[1]]),
            lambda s: [start + [value] for start in starts(s) for value in last_starts],
            apply,
        )

    return (
        form("presliding", "presliding", PRESLIDING, PRESLIDING_STARTS, bristle),
        form("smooth", "regularization_velocity", REGULARIZATION, REGULARIZATION_STARTS, smooth),
    )


def _command_grid(fixed: tuple[float, ...], low: float, high: float) -> Callable[[Scales], list[list[float]]]:
    """Starts of a parameter that sets where the command map is discontinuous (a dead zone's width, a saturation's
    limit): ``fixed`` fractions of the largest command and every logged command level (``Scales.command_levels``)
    within [``low``, ``high``] of it. The cost changes only where the parameter crosses a logged command, and a
    gradient step cannot cross a jump, so the starts cover the commands the data hold and the best is refined."""

    def starts(s: Scales) -> list[list[float]]:
        levels = [level for level in s.command_levels if low * s.command <= level <= high * s.command]
        return [[k * s.command] for k in fixed] + [[level] for level in levels]

    return starts


def _deadzone(form: str) -> Form:
    return Form(
        form,
        ("deadzone",),
        lambda s: ([0.0], [0.5 * s.command]),
        _command_grid((0.01, 0.05, 0.15), 0.0, 0.5),
        lambda m, p: m.replace(deadzone=p[0], deadzone_form=form),
        jump=0 if form == "threshold" else None,  # the subtracting form is continuous in its width
    )


def _saturation(form: str) -> Form:
    return Form(
        form,
        ("limit",),
        lambda s: ([0.05 * s.command], [1.0 * s.command]),
        _command_grid((0.95, 0.7, 0.4), 0.05, 1.0),
        lambda m, p: m.replace(saturation=p[0], saturation_form=form),
    )


# The presliding displacement and the regularisation velocity at the low end of their ranges: a Coulomb law that sticks
_STICKING = (
    ("presliding", "lower", "a Coulomb law that sticks (no presliding displacement)"),
    ("regularization_velocity", "lower", "a Coulomb law that sticks (a sharp sign)"),
)
DELAY_STARTS = (0.5, 1.0, 2.0, 3.5, 6.0, 10.0)  # starts of the input delay [sample periods]
SPREAD_BOUNDS = (0.25, 5.0)  # bounds of a jittering delay's spread [sample periods]: a smaller spread is the fixed
# form (its effect on the applied command is second order in the spread)
SPREAD_STARTS = (0.5, 1.0, 2.0)  # [sample periods]


def _fixed_delay() -> Form:
    return Form(
        "fixed",
        ("delay",),
        lambda s: ([0.0], [20.0 * s.period]),
        lambda s: [[k * s.period] for k in DELAY_STARTS],
        lambda m, p: m.replace(delay=p[0], delay_spread=0.0),
    )


def causal_spread(delay: float) -> float:
    """The largest spread [s] of a jittering delay of mean ``delay`` [s]: uniform on delay +- sqrt(3) spread, it then
    reaches down to zero (a larger one would read commands not yet sent)."""
    return delay / math.sqrt(3.0)


def _jittering_delay() -> Form:
    """A delay drawn anew every sample, uniform on delay +- sqrt(3) delay_spread: the model applies its expected
    command (:func:`~furuta_drake.effects.surrogate.expected_command`)."""
    return Form(
        "jitter",
        ("delay", "delay_spread"),
        lambda s: ([0.0, SPREAD_BOUNDS[0] * s.period], [20.0 * s.period, SPREAD_BOUNDS[1] * s.period]),
        lambda s: [[k * s.period, j * s.period] for k in DELAY_STARTS[1:-1] for j in SPREAD_STARTS],
        lambda m, p: m.replace(delay=p[0], delay_spread=p[1]),
        simpler="fixed",
    )


def _single(params, bounds, starts, apply) -> tuple[Form, ...]:
    return (Form("", params, bounds, starts, apply),)


BACKLASH_BOUNDS = (0.0, 0.2)  # [rad] half-width of a drive's free play, arm side (0.2 rad: 11 degrees)
# Starts of the backlash: the cost is non-convex in it (a reversal's free travel either spans a sample or not), so a
# log grid spans from a count of a fine encoder to a few degrees.
BACKLASH_STARTS = (0.002, 0.006, 0.02, 0.06)  # [rad]
COMPLIANCE_FREQUENCIES = (0.5, CONTACT_FREQUENCY)  # [Hz] bounds of the stiffness as the pair's ringing
# sqrt(k / mu) / (2 pi): stiffer than a gear's tooth contact is a rigid drive at any log's rate
COMPLIANCE_STARTS = (3.0, 8.0, 20.0, 50.0)  # [Hz]: the ringing sets where the response bends, a log grid
COMPLIANCE_DAMPING_RATIOS = (0.1, 0.5)  # starts of the damping, as damping ratios c / (2 sqrt(k mu))
COMPLIANCE_DAMPING_RATIO_MAX = 2.0  # the damping's upper bound, as a ratio at the stiffest coupling


def _stiffness_at(frequency: float, scales: Scales) -> float:
    """k [N m/rad] at which the rotor-arm pair of ``scales`` rings at ``frequency`` [Hz]: mu (2 pi f)^2."""
    return scales.drive_inertia * (2.0 * math.pi * frequency) ** 2


def _compliance_bounds(s: Scales) -> tuple[list[float], list[float]]:
    low, high = (_stiffness_at(f, s) for f in COMPLIANCE_FREQUENCIES)
    return [low, 0.0], [high, 2.0 * COMPLIANCE_DAMPING_RATIO_MAX * math.sqrt(high * s.drive_inertia)]


def _compliance_starts(s: Scales) -> list[list[float]]:
    return [
        [_stiffness_at(f, s), 2.0 * zeta * math.sqrt(_stiffness_at(f, s) * s.drive_inertia)]
        for f in COMPLIANCE_STARTS
        for zeta in COMPLIANCE_DAMPING_RATIOS
    ]


DRIVE_KEYS = {"drive_backlash": ("backlash",), "drive_compliance": ("stiffness", "damping")}  # the drive effects'
# parameters, each the rig file's ``drive:`` key of its name


CANDIDATES: dict[str, Candidate] = {
    c.name: c
    for c in [
        Candidate(
            "arm_coulomb_friction",
            _friction_forms(
                ("coulomb",),
                lambda s: ([0.0], [0.5 * s.torque]),
                lambda s: [[level * s.torque] for level in FRICTION_LEVEL_STARTS],
                lambda m, p: _bristle_arm(m, p[0], p[0], p[1]),
                lambda m, p: _smooth_arm(m, p[0], p[0], p[1]),
            ),
            main="coulomb",
            vanishes=(("coulomb", 0.0),),
            nested=_STICKING,
        ),
        Candidate(
            "arm_viscous_friction",
            _single(
                ("viscous",),
                lambda s: ([0.0], [50.0 * s.arm_inertia]),
                lambda s: [[0.1 * s.arm_inertia], [1.0 * s.arm_inertia], [5.0 * s.arm_inertia]],
                lambda m, p: _arm(
                    m, model="static" if m.arm_friction.model == "none" else m.arm_friction.model, viscous=p[0]
                ),
            ),
            main="viscous",
            vanishes=(("viscous", 0.0),),
        ),
        Candidate(
            "arm_stribeck",
            _friction_forms(
                ("coulomb", "static", "stribeck_velocity"),
                lambda s: ([0.0, 0.0, 0.01], [0.5 * s.torque, s.torque, 1.0]),
                lambda s: [
                    [level * s.torque, 2.0 * level * s.torque, velocity]
                    for level in FRICTION_LEVEL_STARTS
                    for velocity in STRIBECK_VELOCITY_STARTS
                ],
                lambda m, p: _bristle_arm(m, p[0], p[0], p[3], static=max(p[1], p[0]), stribeck_velocity=p[2]),
                lambda m, p: _smooth_arm(m, p[0], p[0], p[3], static=max(p[1], p[0]), stribeck_velocity=p[2]),
            ),
            main="static",
            vanishes=(("coulomb", 0.0), ("static", 0.0)),
            nested=_STICKING + (("static", "lower", "Coulomb friction without a breakaway level"),),
        ),
        Candidate(
            "friction_asymmetry",
            _friction_forms(
                ("coulomb_pos", "coulomb_neg"),
                lambda s: ([0.0, 0.0], [0.5 * s.torque, 0.5 * s.torque]),
                lambda s: [
                    [level * ratio * s.torque, level / ratio * s.torque]
                    for level in FRICTION_LEVEL_STARTS
                    for ratio in (1.0, 0.8, 1.25)
                ],
                lambda m, p: _bristle_arm(m, p[0], p[1], p[2]),
                lambda m, p: _smooth_arm(m, p[0], p[1], p[2]),
            ),
            main="coulomb_neg",
            vanishes=(("coulomb_pos", 0.0), ("coulomb_neg", 0.0)),
            nested=_STICKING,
        ),
        Candidate(
            "pendulum_friction",
            _single(
                ("coulomb", "viscous"),
                lambda s: ([0.0, 0.0], [0.1 * s.torque, 20.0 * s.pendulum_inertia]),
                lambda s: [
                    [0.0005 * s.torque, 0.02 * s.pendulum_inertia],
                    [0.005 * s.torque, 0.2 * s.pendulum_inertia],
                ],
                lambda m, p: m.replace(
                    pendulum_friction=dataclasses.replace(
                        m.pendulum_friction, coulomb_pos=p[0], coulomb_neg=p[0], viscous=p[1]
                    )
                ),
            ),
            main="coulomb",
            vanishes=(("coulomb", 0.0), ("viscous", 0.0)),
            nested=(("coulomb", "lower", "viscous friction alone"), ("viscous", "lower", "Coulomb friction alone")),
        ),
        Candidate(
            "encoder_quantization",
            _single(
                ("counts_per_rev",),
                lambda s: ([4.0], [1e7]),
                lambda s: [],
                lambda m, p: m.replace(counts_per_rev=int(round(p[0]))),
            ),
            main="counts_per_rev",
            fit=False,
        ),
        Candidate(
            "measurement_noise",
            (
                Form(
                    "white",
                    ("noise_std",),
                    lambda s: ([0.0], [1.0]),
                    lambda s: [],
                    lambda m, p: m.replace(noise_std=float(p[0]), noise_correlation_time=0.0),
                ),
                Form(
                    "correlated",
                    ("noise_std", "correlation_time"),
                    lambda s: ([0.0, 0.0], [1.0, 1.0]),
                    lambda s: [],
                    lambda m, p: m.replace(noise_std=float(p[0]), noise_correlation_time=float(p[1])),
                ),
            ),
            main="noise_std",
            fit=False,
        ),
        Candidate(
            "input_delay",
            (_fixed_delay(), _jittering_delay()),
            main="delay",
            vanishes=(("delay", 0.0),),
            nested=(("delay_spread", "lower", "a fixed delay"),),
        ),
        Candidate(
            "torque_gain_error",
            _single(
                ("gain",), lambda s: ([0.2], [5.0]), lambda s: [[0.7], [1.0], [1.4]], lambda m, p: m.replace(gain=p[0])
            ),
            main="gain",
            neutral=1.0,
            vanishes=(("gain", 1.0),),
        ),
        Candidate(
            "actuator_deadzone",
            (_deadzone("subtract"), _deadzone("threshold")),
            main="deadzone",
            vanishes=(("deadzone", 0.0),),
        ),
        Candidate(
            "actuator_lag",
            _single(
                ("time_constant",),
                lambda s: ([0.0], [0.1]),
                lambda s: [[k * s.period] for k in (0.5, 1.0, 2.0, 4.0, 8.0)] + [[0.01], [0.03]],
                lambda m, p: m.replace(lag=p[0]),
            ),
            main="time_constant",
            vanishes=(("time_constant", 0.0),),
        ),
        Candidate(
            "actuator_saturation",
            (_saturation("hard"), _saturation("smooth")),
            main="limit",
            vanishes=(("limit", "upper"),),
        ),
        Candidate(
            "arm_spring",
            (
                Form(
                    "linear",
                    ("stiffness", "equilibrium"),
                    lambda s: ([0.0, -1.0], [5.0 * s.torque, 1.0]),
                    lambda s: [[0.01 * s.torque, 0.0], [0.1 * s.torque, 0.0]],
                    lambda m, p: m.replace(spring_stiffness=p[0], spring_equilibrium=p[1], spring_cubic=0.0),
                ),
                Form(
                    "cubic",
                    ("stiffness", "cubic_stiffness", "equilibrium"),
                    lambda s: ([0.0, 0.0, -1.0], [5.0 * s.torque, 20.0 * s.torque, 1.0]),
                    lambda s: [[0.01 * s.torque, 0.1 * s.torque, 0.0], [0.1 * s.torque, 1.0 * s.torque, 0.0]],
                    lambda m, p: m.replace(spring_stiffness=p[0], spring_cubic=p[1], spring_equilibrium=p[2]),
                ),
            ),
            main="stiffness",
            vanishes=(("stiffness", 0.0), ("cubic_stiffness", 0.0)),
            nested=(("cubic_stiffness", "lower", "a linear spring"),),
        ),
        Candidate(
            "drive_backlash",
            _single(
                ("backlash",),
                lambda s: ([BACKLASH_BOUNDS[0]], [BACKLASH_BOUNDS[1]]),
                lambda s: [[b] for b in BACKLASH_STARTS],
                lambda m, p: m.replace(drive_backlash=p[0]),
            ),
            main="backlash",
            vanishes=(("backlash", 0.0),),
            drive=True,
            look_alike=(
                (
                    "arm_coulomb_friction",
                    "both act at the arm's velocity reversals: friction brakes the arm by a torque, backlash leaves "
                    "it free while the rotor crosses the play and then jerks it",
                ),
                (
                    "actuator_deadzone",
                    "both take the command's effect away around its reversals: a dead zone below a torque, backlash "
                    "for the time the rotor needs to cross the play",
                ),
            ),
        ),
        Candidate(
            "drive_compliance",
            _single(
                ("stiffness", "damping"),
                _compliance_bounds,
                _compliance_starts,
                lambda m, p: m.replace(drive_stiffness=p[0], drive_damping=p[1]),
            ),
            main="stiffness",
            vanishes=(("stiffness", "upper"),),
            nested=(("stiffness", "upper", "a rigid drive (as stiff as a gear's tooth contact)"),),
            drive=True,
            look_alike=(
                (
                    "actuator_lag",
                    "both make the arm follow a step of the command late; a spring rings at its frequency while a "
                    "lag does not, and logs slower than twice that frequency see the spring as a lag",
                ),
            ),
        ),
        Candidate(
            "inertia_mismatch",
            _single(  # scales of the rig file's a, b, c, d (Model.rig_constants)
                ("arm_inertia_scale", "pendulum_inertia_scale", "coupling_scale", "gravity_scale"),
                lambda s: ([0.3] * 4, [3.0] * 4),
                lambda s: [[1.0] * 4],
                lambda m, p: m.replace(
                    **{key: base * scale for key, base, scale in zip(LUMPED_CONSTANTS, m.rig_constants, p)}
                ),
            ),
            main="arm_inertia_scale",
            neutral=1.0,
            vanishes=tuple(
                (f"{name}_scale", 1.0) for name in ("arm_inertia", "pendulum_inertia", "coupling", "gravity")
            ),
        ),
    ]
}
# Variants of one law (each holds the arm's Coulomb level): one model never holds two of them.
SAME_LAW = (frozenset({"arm_coulomb_friction", "arm_stribeck", "friction_asymmetry"}),)


def law_of(name: str) -> frozenset[str]:
    """The candidates that are variants of ``name``'s law (``name`` alone for most effects)."""
    return next((law for law in SAME_LAW if name in law), frozenset({name}))


def apply_effects(model: Model, effects: dict[str, Effect]) -> Model:
    """``model`` with every (effect name -> :class:`Effect`) applied in turn."""
    for name, effect in effects.items():
        model = CANDIDATES[name].form(effect.form).apply(model, np.asarray(effect.values, dtype=float))
    return model


def describe(name: str, effect: Effect, nominal: Model) -> dict[str, float | str]:
    """SI parameters for the report (with the form when the effect has several); inertia scales are also given
    as the lumped constants they produce."""
    candidate = CANDIDATES[name]
    values: dict[str, float | str] = {
        key: float(v) for key, v in zip(candidate.form(effect.form).params, effect.values)
    }
    if name == "inertia_mismatch":  # the scales are of the rig file's lumped constants
        a, b, c, d = nominal.rig_constants
        values.update(
            arm_inertia_total=a * values["arm_inertia_scale"],
            pendulum_inertia_total=b * values["pendulum_inertia_scale"],
            coupling=c * values["coupling_scale"],
            gravity_torque=d * values["gravity_scale"],
        )
    if len(candidate.forms) > 1:
        values["form"] = effect.form
    return values


def effect_from_params(name: str, params: dict) -> Effect:
    """The :class:`Effect` that :func:`describe` reports as ``params`` (the form, then its parameters by name;
    derived entries are ignored); KeyError naming a missing parameter, ValueError an unknown form."""
    candidate = CANDIDATES[name]
    form_name = params.get("form", candidate.forms[0].name)
    if form_name not in {f.name for f in candidate.forms}:
        raise ValueError(f"{name}: unknown form {form_name!r} (known: {', '.join(f.name for f in candidate.forms)})")
    form = candidate.form(form_name)
    return Effect(form_name, tuple(float(params[key]) for key in form.params))


POSITIVE = {
    "presliding",
    "regularization_velocity",
    "stribeck_velocity",
    "gain",
    "arm_inertia_scale",
    "pendulum_inertia_scale",
    "coupling_scale",
    "gravity_scale",
    "counts_per_rev",
    "limit",
    "delay_spread",
    "correlation_time",
}
SIGNED = {"equilibrium"}


def drive_effects(rig) -> dict[str, Effect]:
    """The drive effects a rig file's ``drive:`` section states (``DRIVE_KEYS``: a backlash above 0, a stiffness
    given), as vocabulary effects in their single form."""
    drive, out = rig.drive, {}
    if drive is None:
        return out
    for name, keys in DRIVE_KEYS.items():
        values = [getattr(drive, key) for key in keys]
        if values[0]:
            out[name] = Effect(CANDIDATES[name].forms[0].name, tuple(values))
    return out


def rig_effects(rig) -> dict[str, Effect]:
    """The effects a rig file's optional ``effects:`` section states (vocabulary names -> parameters by name, with
    ``form`` for an effect of several forms), checked; ConfigError naming ``effects.<effect>.<param>``."""
    from furuta_drake.errors import ConfigError

    out = {}
    for name, params in (rig.effects or {}).items():
        where = f"effects.{name}"
        if name not in CANDIDATES:
            raise ConfigError(f"{where}: unknown effect {name!r} (the vocabulary: {', '.join(CANDIDATES)})")
        if name in DRIVE_KEYS:
            raise ConfigError(
                f"{where}: a drive's {' and '.join(DRIVE_KEYS[name])} are keys of the rig file's drive: section "
                f"(drive.{', drive.'.join(DRIVE_KEYS[name])}), beside its gear_ratio and rotor_inertia"
            )
        if not isinstance(params, dict):
            raise ConfigError(f"{where}: expected a mapping of parameter names to values")
        candidate = CANDIDATES[name]
        forms = [f.name for f in candidate.forms]
        form = params.get("form", forms[0])
        if form not in forms:
            raise ConfigError(f"{where}.form: {form!r} is not a form of {name} (forms: {', '.join(forms)})")
        expected = candidate.form(form).params
        for key, value in params.items():
            if key == "form":
                continue
            if key not in expected:
                raise ConfigError(
                    f"{where}.{key}: unknown parameter of {name} ({form or 'its'} form: {', '.join(expected)})"
                )
            if isinstance(value, bool) or not isinstance(value, (int, float)) or not np.isfinite(value):
                raise ConfigError(f"{where}.{key} must be a finite number [{UNITS[key]}], got {value!r}")
            if (key in POSITIVE and value <= 0) or (key not in SIGNED and value < 0):
                raise ConfigError(
                    f"{where}.{key} must be {'positive' if key in POSITIVE else 'non-negative'} "
                    f"[{UNITS[key]}], got {value!r}"
                )
        missing = [key for key in expected if key not in params]
        if missing:
            raise ConfigError(f"{where}: missing parameter {', '.join(missing)} of {name}")
        if form == "jitter" and params["delay_spread"] > causal_spread(params["delay"]):
            raise ConfigError(
                f"{where}.delay_spread must be at most delay / sqrt(3) [s] (the uniform delay would reach below "
                f"zero), got {params['delay_spread']!r} beside a delay of {params['delay']!r}"
            )
        out[name] = effect_from_params(name, params)
    return out


def rig_model(rig) -> Model:
    """The nominal model of a rig file: its bodies, friction and motor, the effects it states, and its torque
    beyond the vocabulary as the surrogate's fixed terms (:func:`~.torque_library.library_terms`)."""
    model = apply_effects(Model.from_rig(rig), rig_effects(rig))
    return model.replace(unmodelled_terms=library_terms(rig.unmodelled_torque))
