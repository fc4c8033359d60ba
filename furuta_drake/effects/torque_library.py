"""The library of candidate terms of a torque the effect vocabulary does not hold (the "unmodelled torque").

Each term is a function of the state alone, in the log conventions of ``docs/diagnose.md`` (``theta`` the pendulum
angle, 0 upright; ``phi`` the arm angle [rad]; their rates [rad/s]), written as a numpy expression in the names
``TORQUE_VARIABLES`` so that anyone can evaluate it. The same library serves both joints (``JOINTS``); a torque
is a sum of coefficients [N m] times terms:

- ``1``: a constant (a tilted base on the arm, an encoder zeroed off the upright on the pendulum);
- ``sin(k*phi)``, ``cos(k*phi)``, k = 1 .. ``HARMONICS``: position-periodic torques (cogging, a cable, a base tilt);
- ``sin(theta)``, ``cos(theta)``: a pendulum angle offset or a gravity error;
- per joint rate v: ``tanh(v/0.02)`` (the sign, smoothed as the vocabulary's friction laws), ``v``, ``abs(v)*v``
  (quadratic drag), ``tanh(v/1.0)`` (a friction that saturates at 1 rad/s);
- each of these rate terms times ``sin(phi)`` or ``cos(phi)``: a friction that varies with the arm angle.

The command is not a term: a torque proportional to it is the vocabulary's torque gain error, and the expression
of ``report.json`` holds the state alone so that a simulation adds it beside any controller.
:func:`term_value` is the same library compiled for the surrogate's kernel; a test pins it to the expressions.
"""

from __future__ import annotations

import ast
import math

import numpy as np
from numba import njit

from furuta_drake.errors import ConfigError
from furuta_drake.unmodelled import UnmodelledTorqueParameters, compile_torque

JOINTS = ("arm", "pendulum")  # the generalised force on phi, on theta
HARMONICS = 24
SIGN_VELOCITY = 0.02  # [rad/s] the smoothed sign, as REGULARIZATION_VELOCITY of the diagnosis models
SATURATION_VELOCITY = 1.0  # [rad/s] the rate at which the tanh term saturates

_RATE_TERMS = ("tanh({v}/0.02)", "{v}", "abs({v})*{v}", "tanh({v}/1.0)")
_RATES = ("phi_dot", "theta_dot")


def _terms() -> tuple[str, ...]:
    rates = [form.format(v=v) for v in _RATES for form in _RATE_TERMS]
    return (
        ("1",)
        + tuple(f"sin({k}*phi)" for k in range(1, HARMONICS + 1))
        + tuple(f"cos({k}*phi)" for k in range(1, HARMONICS + 1))
        + ("sin(theta)", "cos(theta)")
        + tuple(rates)
        + tuple(f"{rate}*{f}(phi)" for rate in rates for f in ("sin", "cos"))
    )


TERMS = _terms()
# (joint, term) of the shapes a listed effect's torque takes: the joints' Coulomb friction (the smooth sign at the
# regularisation velocity of any fit), their viscous friction, the pendulum's gravity torque (inertia_mismatch)
LISTED_SHAPES = frozenset(
    [(joint, form.format(v=v)) for joint, v in enumerate(_RATES) for form in ("tanh({v}/0.02)", "{v}", "tanh({v}/1.0)")]
    + [(1, "sin(theta)")]
)
_COMPILED = [compile_torque(term, f"torque term {term}") for term in TERMS]
_FIRST_RATE = 1 + 2 * HARMONICS + 2  # index of the first rate term
_FIRST_PRODUCT = _FIRST_RATE + len(_RATE_TERMS) * len(_RATES)


def term_values(theta, phi, theta_dot, phi_dot) -> np.ndarray:
    """Every term at the given states: (len(TERMS), *shape), each through the checked expression compiler
    (:func:`furuta_drake.unmodelled.compile_torque`) that a simulation of the torque uses."""
    state = np.broadcast_arrays(*map(np.asarray, (theta, phi, theta_dot, phi_dot)))
    shape = state[0].shape
    return np.stack([np.broadcast_to(_COMPILED[i](*state), shape) for i in range(len(TERMS))])


def expression(terms: list[tuple[int, float]]) -> str:
    """The numpy expression of a torque: (term index, coefficient [N m]) pairs summed."""
    parts = [f"{c:+.6g}" if TERMS[i] == "1" else f"{c:+.6g}*{TERMS[i]}" for i, c in terms]
    return " ".join(parts).lstrip("+") if parts else "0"


def merged(terms) -> tuple[tuple[int, int, float], ...]:
    """(joint, term index, coefficient) triples with the coefficients of a repeated (joint, term) summed, in the
    order each first appears."""
    out: dict[tuple[int, int], float] = {}
    for joint, term, c in terms:
        out[(joint, term)] = out.get((joint, term), 0.0) + float(c)
    return tuple((joint, term, c) for (joint, term), c in out.items())


def torque_parameters_of(terms) -> UnmodelledTorqueParameters:
    """The expressions (a rig file's or simulate config's ``unmodelled_torque``) of a surrogate model's
    ``unmodelled_terms``: (joint, term index, coefficient [N m]) triples."""
    per_joint = {name: [(t, c) for j, t, c in merged(terms) if j == joint] for joint, name in enumerate(JOINTS)}
    return UnmodelledTorqueParameters(**{name: expression(pairs) if pairs else "" for name, pairs in per_joint.items()})


def library_terms(parameters: UnmodelledTorqueParameters | None) -> tuple[tuple[int, int, float], ...]:
    """The (joint, term index, coefficient [N m]) triples of torque expressions written as
    :func:`expression` writes them: a sum of numbers times library terms (a number alone is the constant).
    ConfigError naming the joint's key and the part that is no number times a term of :data:`TERMS`."""
    if parameters is None:
        return ()
    out = []
    for joint, name in enumerate(JOINTS):
        text = getattr(parameters, name)
        if text.strip():
            out += [(joint, term, c) for term, c in _summands(text, f"unmodelled_torque.{name}")]
    return merged(out)


_TERM_INDEX = {ast.dump(ast.parse(term, mode="eval").body): i for i, term in enumerate(TERMS)}


def _summands(text: str, where: str) -> list[tuple[int, float]]:
    """(term index, coefficient) of each summand of ``text``."""
    compile_torque(text, where)  # the checked compiler's errors first
    parts, stack = [], [(ast.parse(text.strip(), mode="eval").body, 1.0)]
    while stack:
        node, sign = stack.pop()
        if isinstance(node, ast.BinOp) and isinstance(node.op, (ast.Add, ast.Sub)):
            stack += [(node.left, sign), (node.right, -sign if isinstance(node.op, ast.Sub) else sign)]
        elif isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            stack.append((node.operand, -sign if isinstance(node.op, ast.USub) else sign))
        else:
            parts.append(_summand(node, sign, text, where))
    return parts[::-1]


def _summand(node: ast.AST, sign: float, text: str, where: str) -> tuple[int, float]:
    """(term index, coefficient) of one product: its numbers multiplied, its other factors in order a term."""
    factors, stack = [], [node]
    while stack:
        part = stack.pop()
        if isinstance(part, ast.BinOp) and isinstance(part.op, ast.Mult):
            stack += [part.right, part.left]
        else:
            factors.append(part)
    numbers = [_number(f) for f in factors if _number(f) is not None]
    rest = "*".join(ast.unparse(f) for f in factors if _number(f) is None) or "1"
    index = _TERM_INDEX.get(ast.dump(ast.parse(rest, mode="eval").body))
    if index is None:
        raise ConfigError(
            f"{where}: {ast.get_source_segment(text.strip(), node)!r} is not a number times a term of the torque "
            "library (docs/diagnose.md, section 5): a diagnosis starts only from library terms"
        )
    return index, sign * math.prod(numbers)


def _number(node: ast.AST) -> float | None:
    """The value of a number written with or without a sign, else None."""
    if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
        value = _number(node.operand)
        return None if value is None else (-value if isinstance(node.op, ast.USub) else value)
    if isinstance(node, ast.Constant) and type(node.value) in (int, float):
        return float(node.value)
    return None


def carrier(term: str) -> str:
    """The variable a term varies with most directly: the plot's abscissa (the first state name in it)."""
    found = [(term.find(name), name) for name in ("phi_dot", "theta_dot", "phi", "theta") if name in term]
    if not found:
        return "phi"
    position = min(p for p, _ in found)
    return max((name for p, name in found if p == position), key=len)


@njit(cache=True, inline="always")
def _rate_term(form, v):
    if form == 0:
        return math.tanh(v / SIGN_VELOCITY)
    if form == 1:
        return v
    if form == 2:
        return abs(v) * v
    return math.tanh(v / SATURATION_VELOCITY)


@njit(cache=True, inline="always")
def _rate_slope(form, v):
    """d/dv of :func:`_rate_term`."""
    if form == 0:
        t = math.tanh(v / SIGN_VELOCITY)
        return (1.0 - t * t) / SIGN_VELOCITY
    if form == 1:
        return 1.0
    if form == 2:
        return 2.0 * abs(v)
    t = math.tanh(v / SATURATION_VELOCITY)
    return (1.0 - t * t) / SATURATION_VELOCITY


@njit(cache=True)
def term_slopes(index, theta, phi, theta_dot, phi_dot):
    """The partial derivatives (d/dtheta, d/dphi, d/dtheta_dot, d/dphi_dot) of :func:`term_value` at one state
    (the surrogate's tangent kernel)."""
    if index == 0:
        return 0.0, 0.0, 0.0, 0.0
    if index <= HARMONICS:
        return 0.0, index * math.cos(index * phi), 0.0, 0.0
    if index <= 2 * HARMONICS:
        k = index - HARMONICS
        return 0.0, -k * math.sin(k * phi), 0.0, 0.0
    if index == 2 * HARMONICS + 1:
        return math.cos(theta), 0.0, 0.0, 0.0
    if index == 2 * HARMONICS + 2:
        return -math.sin(theta), 0.0, 0.0, 0.0
    rate = (index - _FIRST_RATE) if index < _FIRST_PRODUCT else (index - _FIRST_PRODUCT) // 2
    v = phi_dot if rate < 4 else theta_dot
    slope = _rate_slope(rate % 4, v)
    d_phi = 0.0
    if index >= _FIRST_PRODUCT:
        value = _rate_term(rate % 4, v)
        if (index - _FIRST_PRODUCT) % 2 == 0:
            slope, d_phi = slope * math.sin(phi), value * math.cos(phi)
        else:
            slope, d_phi = slope * math.cos(phi), -value * math.sin(phi)
    return (0.0, d_phi, 0.0, slope) if rate < 4 else (0.0, d_phi, slope, 0.0)


@njit(cache=True)
def term_value(index, theta, phi, theta_dot, phi_dot):
    """Term ``index`` of :data:`TERMS` at one state (the kernel's copy of the expressions)."""
    if index == 0:
        return 1.0
    if index <= HARMONICS:
        return math.sin(index * phi)
    if index <= 2 * HARMONICS:
        return math.cos((index - HARMONICS) * phi)
    if index == 2 * HARMONICS + 1:
        return math.sin(theta)
    if index == 2 * HARMONICS + 2:
        return math.cos(theta)
    rate = (index - _FIRST_RATE) if index < _FIRST_PRODUCT else (index - _FIRST_PRODUCT) // 2
    v = phi_dot if rate < 4 else theta_dot
    value = _rate_term(rate % 4, v)
    if index < _FIRST_PRODUCT:
        return value
    return value * (math.sin(phi) if (index - _FIRST_PRODUCT) % 2 == 0 else math.cos(phi))


CLOSE = 0.8  # R^2 of a torque on an effect's torque shapes above which that effect is named the closest
# The torque shapes of the vocabulary's state-dependent effects on each joint, as library terms (a spring's
# -k (phi - phi_0) spans phi and a constant; phi is sin(phi) on the arm's range).
EFFECT_SHAPES = {
    "arm": {
        "arm_coulomb_friction": ("tanh(phi_dot/0.02)",),
        "arm_viscous_friction": ("phi_dot",),
        "arm_spring": ("sin(1*phi)", "1"),
    },
    "pendulum": {"pendulum_friction": ("tanh(theta_dot/0.02)", "theta_dot")},
}


def closest_effect(joint: str, torque: np.ndarray, values: np.ndarray) -> str | None:
    """The vocabulary effect whose torque shapes (``EFFECT_SHAPES``) fit the torque along the data best, when their
    least squares explains more than ``CLOSE`` of its mean square; else None. ``values``: the library's terms at
    the data's states (:func:`~.torque_library.term_values`)."""
    best, best_share = None, CLOSE
    total = float(np.sum(torque**2))
    for effect, shapes in EFFECT_SHAPES[joint].items():
        basis = np.stack([values[TERMS.index(shape)] for shape in shapes], axis=1)
        fitted = basis @ np.linalg.lstsq(basis, torque, rcond=None)[0]
        share = 1.0 - float(np.sum((torque - fitted) ** 2)) / max(total, 1e-300)
        if share > best_share:
            best, best_share = effect, share
    return best


def copied_effect(joint: int, term: int, values: np.ndarray) -> str | None:
    """The listed effect whose torque shapes (``EFFECT_SHAPES``) a single term of ``joint`` (0 arm, 1 pendulum)
    takes along the data (:func:`closest_effect` of the term alone, ``values`` the terms at the data's states), or
    None: a term such as ``tanh(phi_dot/0.02)*cos(phi)`` is Coulomb friction over a balancing arm's range."""
    return closest_effect(JOINTS[joint], values[term], values)
