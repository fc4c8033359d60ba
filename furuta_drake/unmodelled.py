"""A torque beyond the effect vocabulary, written as an expression of the state, and the Drake system that applies it.

A diagnosis that finds a torque no listed effect explains writes it as a numpy expression in the logged state
(``docs/diagnose.md``: theta 0 upright, the paper's signs; rad and rad/s), e.g. ``0.002*sin(7*phi)`` on the arm.
:func:`compile_torque` turns such text into a vectorised function after checking every token of its syntax
tree against a short list (the variables, a few functions, arithmetic), so a config file can never run code.
:class:`UnmodelledTorque` adds the torques to the plant's generalised forces: paper Eq. 3's tau = [F_theta,
u + F_phi] gains one more term per joint.
"""

from __future__ import annotations

import ast
import math
import operator
import sys
import warnings
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from furuta_drake.errors import ConfigError

TORQUE_VARIABLES = ("theta", "phi", "theta_dot", "phi_dot")
FUNCTIONS = {
    "sin": np.sin,
    "cos": np.cos,
    "tan": np.tan,
    "tanh": np.tanh,
    "exp": np.exp,
    "log": np.log,
    "abs": np.abs,
    "sign": np.sign,
    "sqrt": np.sqrt,
}
BINARY = {
    ast.Add: operator.add,
    ast.Sub: operator.sub,
    ast.Mult: operator.mul,
    ast.Div: operator.truediv,
    ast.Pow: operator.pow,
}


def _on_floats(fast: Callable, numpy_function: Callable) -> Callable:
    """``fast`` (Python's ``math``, an order of magnitude quicker than numpy on one float) where it is defined; numpy's
    value (nan or inf) where it raises, so the per-state path gives what the vectorised one gives."""

    def function(*args: float) -> float:
        try:
            return fast(*args)
        except (ValueError, OverflowError, ZeroDivisionError):
            with np.errstate(all="ignore"):
                return float(numpy_function(*args))

    return function


SCALAR_FUNCTIONS = {
    name: _on_floats(getattr(math, name), FUNCTIONS[name])
    for name in ("sin", "cos", "tan", "tanh", "exp", "log", "sqrt")
}
SCALAR_FUNCTIONS["abs"] = abs
SCALAR_FUNCTIONS["sign"] = lambda v: float((v > 0) - (v < 0)) if v == v else v  # numpy's sign: nan stays nan
SCALAR_BINARY = {
    **BINARY,
    ast.Div: _on_floats(operator.truediv, np.true_divide),
    ast.Pow: _on_floats(math.pow, np.power),  # math.pow: a negative base to a fractional power is nan, not complex
}
UNARY = {ast.USub: operator.neg, ast.UAdd: operator.pos}
MAX_DEPTH = 200  # syntax-tree levels (a sum of n terms is some n deep); compiling and evaluating recurse per level
ALLOWED = (
    f"the variables {', '.join(TORQUE_VARIABLES)}, the functions {' '.join(FUNCTIONS)}, pi, numbers, "
    "+ - * / ** and parentheses"
)


class Torque:
    """A checked torque expression: ``torque(theta, phi, theta_dot, phi_dot)`` [N m] on floats or numpy arrays
    (broadcast together; a float array out, numpy's functions), ``torque.at(x)`` at one paper-order state (a
    float from Python's ``math``: the Drake system's per-stage call). Values outside a function's domain give nan
    or inf, never an exception."""

    def __init__(self, evaluate: Callable[[dict], object], evaluate_scalar: Callable[[dict], float]):
        self._evaluate, self._evaluate_scalar = evaluate, evaluate_scalar

    def __call__(self, theta, phi, theta_dot, phi_dot) -> np.ndarray:
        values = np.broadcast_arrays(*(np.asarray(v, dtype=float) for v in (theta, phi, theta_dot, phi_dot)))
        with np.errstate(all="ignore"):
            result = self._evaluate(dict(zip(TORQUE_VARIABLES, values)))
        return np.broadcast_to(np.asarray(result, dtype=float), values[0].shape).copy()

    def at(self, x) -> float:
        """The torque at x = [theta, phi, theta_dot, phi_dot]."""
        return float(self._evaluate_scalar(dict(zip(TORQUE_VARIABLES, map(float, x)))))


def compile_torque(expression: str, where: str) -> Torque:
    """The torque [N m] that ``expression`` gives, as a :class:`Torque` f(theta, phi, theta_dot, phi_dot). Raises
    :class:`ConfigError` naming ``where`` and the offending token for anything but :data:`TORQUE_VARIABLES`,
    :data:`FUNCTIONS` called with one argument, ``pi``, numbers and + - * / ** (unary minus, parentheses). A result
    outside a function's domain (log of a negative number, a division by zero) is nan or inf, for the caller to
    detect where it uses the torque."""
    if not isinstance(expression, str) or not expression.strip():
        raise ConfigError(f"{where}: expected a torque expression in {', '.join(TORQUE_VARIABLES)}, got {expression!r}")
    try:
        with warnings.catch_warnings():  # text Python parses with a warning ("1if") is refused as a SyntaxError
            warnings.simplefilter("error", SyntaxWarning)
            tree = ast.parse(expression.strip(), mode="eval")
    except SyntaxError as err:
        raise ConfigError(
            f"{where}: not a valid expression ({err.msg}, column {err.offset}): {_shown(expression)}"
        ) from None
    except (RecursionError, MemoryError, ValueError):
        raise ConfigError(f"{where}: expression too deeply nested or malformed: {_shown(expression)}") from None
    if _depth(tree.body) > MAX_DEPTH:
        raise ConfigError(f"{where}: expression nested deeper than {MAX_DEPTH} operations: {_shown(expression)}")
    text = expression.strip()
    return Torque(
        _compile_node(tree.body, text, where, scalar=False), _compile_node(tree.body, text, where, scalar=True)
    )


def _shown(expression: str) -> str:
    """The expression quoted for a message, cut after 80 characters."""
    return repr(expression) if len(expression) <= 80 else f"{expression[:80]!r}..."


def _depth(tree: ast.AST) -> int:
    """The depth of a syntax tree, walked without recursion."""
    deepest, stack = 0, [(tree, 1)]
    while stack:
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        stack.extend((child, depth + 1) for child in ast.iter_child_nodes(node))
    return deepest


def _compile_node(node: ast.AST, text: str, where: str, scalar: bool) -> Callable[[dict], object]:
    """A function of the variables' values that evaluates ``node``, which must be one of the allowed forms: on
    numpy values with numpy's functions, or (``scalar``) on Python floats with ``math``'s."""
    if isinstance(node, ast.Constant) and type(node.value) in (int, float):
        number = float(node.value) if abs(node.value) <= sys.float_info.max else math.inf  # an int may not fit
        if not math.isfinite(number):
            raise ConfigError(f"{where}: the number {_segment(node, text)[:20]!r} is not a finite float")
        value = number if scalar else np.float64(number)
        return lambda _: value
    if isinstance(node, ast.Name) and node.id in TORQUE_VARIABLES:
        name = node.id
        return lambda values: values[name]
    if isinstance(node, ast.Name) and node.id == "pi":
        value = math.pi if scalar else np.float64(math.pi)
        return lambda _: value
    if isinstance(node, ast.BinOp) and type(node.op) in BINARY:
        op, left, right = (
            (SCALAR_BINARY if scalar else BINARY)[type(node.op)],
            _compile_node(node.left, text, where, scalar),
            _compile_node(node.right, text, where, scalar),
        )
        return lambda values: op(left(values), right(values))
    if isinstance(node, ast.UnaryOp) and type(node.op) in UNARY:
        op, operand = UNARY[type(node.op)], _compile_node(node.operand, text, where, scalar)
        return lambda values: op(operand(values))
    if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) and node.func.id in FUNCTIONS:
        if len(node.args) != 1 or node.keywords or isinstance(node.args[0], ast.Starred):
            raise ConfigError(f"{where}: {node.func.id} takes one argument, in {_segment(node, text)!r}")
        function = (SCALAR_FUNCTIONS if scalar else FUNCTIONS)[node.func.id]
        argument = _compile_node(node.args[0], text, where, scalar)
        return lambda values: function(argument(values))
    if isinstance(node, (ast.BinOp, ast.UnaryOp)):
        raise ConfigError(
            f"{where}: operator {type(node.op).__name__} in {_segment(node, text)!r} is not allowed "
            f"in a torque expression (allowed: {ALLOWED})"
        )
    offending = node.func if isinstance(node, ast.Call) else node
    raise ConfigError(
        f"{where}: {_segment(offending, text)!r} is not allowed in a torque expression (allowed: {ALLOWED})"
    )


def _segment(node: ast.AST, text: str) -> str:
    return ast.get_source_segment(text, node) or type(node).__name__


@dataclass
class UnmodelledTorqueParameters:
    """Generalised torques [N m] beyond the vocabulary: ``arm`` on the arm joint (phi), ``pendulum`` on the
    pendulum joint (theta), each an expression for :func:`compile_torque`; "" is none."""

    arm: str = ""
    pendulum: str = ""

    def validate(self, where: str = "unmodelled_torque") -> None:
        """Raise :class:`ConfigError` naming ``where.arm`` or ``where.pendulum`` for an expression that does not
        compile."""
        self.torques(where)

    def torques(self, where: str = "unmodelled_torque") -> dict[str, Torque]:
        """The compiled torque of each joint that has one: {"pendulum": f, "arm": f} (paper order)."""
        out = {}
        for joint in ("pendulum", "arm"):
            expression = getattr(self, joint)
            if not isinstance(expression, str):
                raise ConfigError(f"{where}.{joint} must be an expression (a string), got {expression!r}")
            if expression.strip():
                out[joint] = compile_torque(expression, f"{where}.{joint}")
        return out

    @property
    def is_empty(self) -> bool:
        """True when neither joint has a torque (a value that is not a string is one, for validate to refuse)."""
        return all(isinstance(e, str) and not e.strip() for e in (self.arm, self.pendulum))


__all__ = [
    "TORQUE_VARIABLES",
    "FUNCTIONS",
    "Torque",
    "compile_torque",
    "UnmodelledTorqueParameters",
]
