"""A design over the parameters' 95 % intervals: the corners where its loop is checked, and what it must meet.

- **Linear corners**: every combination of the ends of the intervals of the parameters that enter the design
  model's linearization (inertia scales, torque gain, spring, viscous friction, delay, lag; ``LINEAR``), or, when
  there are more than ``MAX_CORNERS`` of them, each parameter at either end alone and all at their lower and at
  their upper ends. At each, the gain's loop on that corner's design model must be stable with a gain margin of
  at least ``MIN_GAIN_DB`` and a delay margin of at least ``MIN_DELAY_PERIODS`` sample periods (the controller's own
  computation time, which the design model leaves out).
- **Effect extremes**: each accepted effect with all its parameters at the lower ends of their intervals, then at
  the upper ends (the others at their fits): the Drake runs there (friction levels, dead zones and sensors enter
  only there) must balance.
"""

from __future__ import annotations

import itertools

from furuta_drake.errors import ConfigError
from furuta_drake.tune.inputs import TuneInputs
from furuta_drake.tune.margins import Margins

LINEAR = {  # the parameters of each effect that enter the design model (all of them: None)
    "inertia_mismatch": None,
    "torque_gain_error": None,
    "arm_spring": None,
    "arm_viscous_friction": None,
    "pendulum_friction": ("viscous",),
    "input_delay": ("delay",),
    "actuator_lag": None,
}
MAX_CORNERS = 256
MIN_GAIN_DB = 3.0  # [dB]
MIN_DELAY_PERIODS = 1.0  # [sample periods]


class NotRobust(ConfigError):
    """No design meets the requirements over the parameters' intervals; the message says where each failed."""


def linear_parameters(inputs: TuneInputs) -> list[tuple[str, str]]:
    """The (effect, parameter) of the accepted effects that enter the design model."""
    return [
        (name, param)
        for (name, param) in inputs.intervals
        if name in LINEAR and (LINEAR[name] is None or param in LINEAR[name])
    ]


def linear_corners(inputs: TuneInputs) -> list[tuple[str, dict]]:
    """(label, corner) of the linear corners (module docstring); corner: (effect, parameter) -> value."""
    params = linear_parameters(inputs)
    if not params:
        return []
    ends = [inputs.intervals[key] for key in params]
    if 2 ** len(params) <= MAX_CORNERS:
        choices = itertools.product((0, 1), repeat=len(params))
    else:
        choices = [(0,) * len(params), (1,) * len(params)] + [
            tuple(side if k == j else None for k in range(len(params))) for j in range(len(params)) for side in (0, 1)
        ]
    out = []
    for choice in choices:
        corner = {key: ends[k][side] for k, (key, side) in enumerate(zip(params, choice)) if side is not None}
        label = ", ".join(
            f"{name}.{param} {'low' if side == 0 else 'high'}"
            for (name, param), side in zip(params, choice)
            if side is not None
        )
        out.append((label, corner))
    return out


def effect_extremes(inputs: TuneInputs) -> list[tuple[str, dict]]:
    """(label, corner) of each accepted effect at the lower and at the upper ends of its intervals."""
    out = []
    for name in inputs.accepted:
        keys = [key for key in inputs.intervals if key[0] == name]
        for side, word in ((0, "low"), (1, "high")):
            out.append((f"{name} {word}", {key: inputs.intervals[key][side] for key in keys}))
    return out


def margin_failure(margins: Margins, period: float) -> str:
    """Why ``margins`` fall short of the requirements ('' when they meet them)."""
    if not margins.stable:
        return "the loop is unstable"
    if margins.gain_db < MIN_GAIN_DB:
        return f"gain margin {margins.gain_db:.2f} dB < {MIN_GAIN_DB:g} dB"
    if margins.delay_s < MIN_DELAY_PERIODS * period:
        return (
            f"delay margin {margins.delay_s * 1e3:.2f} ms < {MIN_DELAY_PERIODS:g} sample period ({period * 1e3:g} ms)"
        )
    return ""
