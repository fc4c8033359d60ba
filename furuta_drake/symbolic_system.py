"""Discrete-time Drake systems written as symbolic expressions and evaluated in C++:
x[n+1] = f(t_n, x[n], u[n]) at a period h, outputs y = g(t, x, u) on named ports.

pydrake's ``SymbolicVectorSystem(time_period=h)`` is such a system on its own, but not in a diagram with a
continuous plant: the integrator evaluates every subsystem's time derivatives at every stage, and its
derivatives demand ``time_period == 0`` (a stateless one demands dynamics), so the simulation aborts. Drake's
``DiscreteTimeApproximation`` of a general continuous system is the discrete wrapper that works there: a
LeafSystem whose state is the wrapped system's continuous state, advanced by an integrator inside its periodic
update and nowhere else. The update is therefore written as a rate: an ``Integrator`` holds x and is driven by
(f - x) / dt, dt = (t + h) - t the step the wrapper's explicit Euler integrator takes, so that one step gives
x + dt (f - x) / dt = f to rounding (an unchanged x stays bit-identical). Each output port is computed by its own
expression block, so that its direct feedthrough is exactly the inputs its expressions read (an output of the
state alone has none: two such systems may feed each other without an algebraic loop).

The expressions take abs, exp, tanh, floor, min, max and ``if_then_else`` (:func:`where`); the laws that build
them (:mod:`furuta_drake.friction`, the observers) take floats too, and their float evaluation is the reference
that the tests hold the C++ systems to.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydrake.symbolic import Expression, ExpressionKind, Formula, Variable, if_then_else, logical_and, logical_not
from pydrake.symbolic import max as symbolic_max
from pydrake.systems.analysis import DiscreteTimeApproximation, SimulatorConfig
from pydrake.systems.framework import Diagram, DiagramBuilder, System
from pydrake.systems.primitives import Integrator, MatrixGain, Multiplexer, PassThrough, SymbolicVectorSystem

Ports = Sequence[tuple[str, Sequence]]


def is_symbolic(*values) -> bool:
    """True if any of ``values`` is a symbolic Variable, Expression or Formula."""
    return any(isinstance(value, (Variable, Expression, Formula)) for value in values)


def where(condition, then, otherwise):
    """``then`` if ``condition`` else ``otherwise``: a Python branch on a bool, ``if_then_else`` on a Formula."""
    if isinstance(condition, Formula):
        return if_then_else(condition, then, otherwise)
    return then if condition else otherwise


def both(first, second):
    """``first and second`` for bools, ``logical_and`` for Formulas."""
    if isinstance(first, Formula) or isinstance(second, Formula):
        return logical_and(first, second)
    return first and second


def negation(condition):
    """``not condition`` for a bool, ``logical_not`` for a Formula."""
    return logical_not(condition) if isinstance(condition, Formula) else not condition


def _expression(value) -> Expression:
    """``value`` (a float, Variable or Expression) as an Expression."""
    return value if isinstance(value, Expression) else Expression(value)


def _variables(expressions) -> set:
    """The ids of the Variables that ``expressions`` read."""
    return {variable.get_id() for expression in expressions for variable in _expression(expression).GetVariables()}


def _state_index(expression: Expression, state_ids: list) -> int | None:
    """The index in the state of ``expression`` if it is one of the state's Variables, else None."""
    if expression.get_kind() != ExpressionKind.Var:
        return None
    (variable,) = expression.GetVariables()
    return state_ids.index(variable.get_id()) if variable.get_id() in state_ids else None


def _expression_system(time: Variable, inputs: list, outputs: list) -> SymbolicVectorSystem:
    """A stateless block y = g(t, u). Its dynamics are a placeholder 0 for a state of size zero: the wrapping
    integrator evaluates its (empty) derivatives, which a block without dynamics refuses."""
    return SymbolicVectorSystem(time=time, input=inputs, dynamics=[Expression(0.0)], output=outputs)


def discrete_symbolic_system(
    *,
    name: str,
    period: float,
    state: Sequence[Variable],
    initial: Sequence[float],
    update: Sequence,
    inputs: Ports,
    outputs: Ports,
    time: Variable | None = None,
) -> System:
    """The C++ system x[n+1] = ``update`` at ``period`` [s] from x[0] = ``initial`` (module docstring).

    ``state``: the Variables of x; ``inputs``: (port name, Variables) in port order; ``outputs``: (port name,
    Expressions of ``time``, ``state`` and the inputs); ``time``: the Variable of t if the expressions read it.
    The system has those input and output ports, in that order; an input that no expression reads is still
    declared. Every connected input is read at each update."""
    time = time if time is not None else Variable("t")
    state = list(state)
    state_ids = [variable.get_id() for variable in state]
    builder = DiagramBuilder()
    held = builder.AddNamedSystem("state", Integrator(len(state)))
    held.set_default_integral_value(np.asarray(initial, dtype=float))
    readers = {port: [] for port, _ in inputs}  # the block inputs each port feeds

    def feed(block_name: str, expressions: list) -> System:
        """A block evaluating ``expressions`` on [x; the inputs they read], fed by the state."""
        used = _variables(expressions)
        ports = [(port, list(variables)) for port, variables in inputs if _variables(variables) & used]
        block = builder.AddNamedSystem(
            block_name, _expression_system(time, state + [v for _, variables in ports for v in variables], expressions)
        )
        mux = builder.AddNamedSystem(f"{block_name}_inputs", Multiplexer([len(state)] + [len(v) for _, v in ports]))
        builder.Connect(held.get_output_port(), mux.get_input_port(0))
        for i, (port, _) in enumerate(ports, start=1):
            readers[port].append(mux.get_input_port(i))
        builder.Connect(mux.get_output_port(), block.get_input_port())
        return block

    # The explicit Euler step's own dt: max() keeps (t + h) - t from being simplified to h.
    step = symbolic_max(time + period, time) - time
    rate = feed("update", [(_expression(f) - x) / step for f, x in zip(update, state)])
    builder.Connect(rate.get_output_port(), held.get_input_port())
    for port, expressions in outputs:
        expressions = [_expression(e) for e in expressions]
        selected = [_state_index(e, state_ids) for e in expressions]
        if None not in selected:  # entries of the state: a selection, no expression to evaluate
            select = builder.AddNamedSystem(f"{port}_selection", MatrixGain(np.eye(len(state))[selected]))
            builder.Connect(held.get_output_port(), select.get_input_port())
            builder.ExportOutput(select.get_output_port(), port)
        else:
            builder.ExportOutput(feed(port, expressions).get_output_port(), port)
    for port, variables in inputs:  # exported in their order; an input nothing reads ends in a PassThrough
        targets = readers[port] or [
            builder.AddNamedSystem(f"{port}_unread", PassThrough(len(variables))).get_input_port()
        ]
        builder.ExportInput(targets[0], port)
        for target in targets[1:]:
            builder.ConnectInput(port, target)
    continuous = builder.Build()
    continuous.set_name(name)
    # One explicit Euler step per period (module docstring); the wrapper keeps ``continuous`` alive.
    euler = SimulatorConfig(integration_scheme="explicit_euler", max_step_size=period, use_error_control=False)
    return DiscreteTimeApproximation(continuous, period, euler)


def build_into(diagram: Diagram, system: System) -> None:
    """Build ``diagram`` (a Diagram subclass under construction) around ``system``: its one subsystem ``law``, every
    port exported under its own name."""
    builder = DiagramBuilder()
    builder.AddNamedSystem("law", system)
    export_ports(builder, system)
    builder.BuildInto(diagram)


def export_ports(builder: DiagramBuilder, system: System) -> None:
    """Export every input and output port of ``system`` (added to ``builder``) under its own name."""
    for i in range(system.num_input_ports()):
        builder.ExportInput(system.get_input_port(i), system.get_input_port(i).get_name())
    for i in range(system.num_output_ports()):
        builder.ExportOutput(system.get_output_port(i), system.get_output_port(i).get_name())


__all__ = ["both", "build_into", "discrete_symbolic_system", "export_ports", "is_symbolic", "negation", "where"]
