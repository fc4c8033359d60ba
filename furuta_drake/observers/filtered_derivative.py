"""A filtered derivative of the encoder angles: the velocity estimate of Quanser's real-time server.

    v(s) = wc s / (s + wc) y(s),

the derivative rolled off by a first-order low-pass at the corner wc [rad/s], discretised by forward Euler at the
control period h (s -> (z - 1) / h):

    v_k = (1 - wc h) v_k-1 + wc (y_k - y_k-1).

This is the velocity a Quanser QUBE's swing-up and balance controller reads (its server differentiates the
encoder counts this way); the real QUBE logs of ``data/qube-servo2-real`` are reproduced by it to a small
fraction of their voltage (``furuta_drake.real_rig.closed_loop_study`` fits wc on the logs). It is causal
and has no computation delay: the estimate of sample k uses y_k. :func:`filtered_derivative` runs it on arrays,
:class:`FilteredDerivative` is the Drake system (``controller.velocity_source: filtered_derivative``); both use
:func:`filter_coefficients`.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import BasicVector, LeafSystem
from scipy.signal import lfilter

from furuta_drake.errors import ConfigError, require_control_period


@dataclass
class FilteredDerivativeParameters:
    """The corner of the filtered derivative; it runs at the control period."""

    corner: float = 50.0  # wc [rad/s]: v = wc s / (s + wc) y
    period: float | None = None  # [s] optional: a stated period must equal the control period

    def validate(self, where: str = "observers.filtered_derivative") -> None:
        if not (isinstance(self.corner, (int, float)) and math.isfinite(self.corner) and self.corner > 0):
            raise ConfigError(f"{where}.corner must be a positive number of rad/s, got {self.corner!r}")
        if self.period is not None and not (math.isfinite(self.period) and self.period > 0):
            raise ConfigError(f"{where}.period must be > 0 (or null: the control period), got {self.period!r}")


def filter_coefficients(
    corner: float, period: float, where: str = "observers.filtered_derivative"
) -> tuple[float, float]:
    """(pole, gain) of v_k = pole v_k-1 + gain (y_k - y_k-1): (1 - wc h, wc) for ``corner`` wc [rad/s] and
    ``period`` h [s]; a ConfigError naming ``where`` when forward Euler is unstable there (wc h >= 2)."""
    if not corner * period < 2.0:
        raise ConfigError(
            f"{where}.corner {corner} rad/s is too high for the period {period} s: forward Euler needs "
            f"corner * period < 2, got {corner * period:.3g}"
        )
    return 1.0 - corner * period, corner


def filtered_derivative(angles: np.ndarray, period: float, corner: float) -> np.ndarray:
    """The filter run over sampled ``angles`` (n, k) [rad] from rest at the first sample: (n, k) velocities
    [rad/s], zero at the first sample."""
    pole, gain = filter_coefficients(corner, period)
    angles = np.asarray(angles, dtype=float)
    steps = np.diff(angles, axis=0, prepend=angles[:1])
    return lfilter([gain], [1.0, -pole], steps, axis=0)


class FilteredDerivative(LeafSystem):
    """:func:`filtered_derivative` as a Drake system at the control period ``period`` [s].

    Input ``measured_angles_rad`` [theta, phi] (the encoder's held samples); output ``state_estimate`` [theta, phi,
    theta_dot, phi_dot] [rad, rad/s]: the current sample and its filtered derivative, with direct feedthrough,
    so that in [t_k, t_k+1) the estimate holds y_k and v_k (no computation delay). Discrete state [y_k-1 (2),
    v_k-1 (2), started]: updated at each t_k from the sample it reads then (the encoder's previous one), started
    at the first update from rest at the first sample (v = 0), which the encoder's initialisation event takes.
    """

    def __init__(self, params: FilteredDerivativeParameters | None = None, *, period: float):
        super().__init__()
        params = params or FilteredDerivativeParameters()
        params.validate()
        require_control_period(params.period, period, "observers.filtered_derivative.period")
        self.params = params
        self._pole, self._gain = filter_coefficients(params.corner, period)
        self._angles = self.DeclareVectorInputPort("measured_angles_rad", 2)
        self._state = self.DeclareDiscreteState(5)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._update)
        self.DeclareVectorOutputPort(
            "state_estimate", 4, self._calc, prerequisites_of_calc={self.xd_ticket(), self._angles.ticket()}
        )

    def _velocity(self, state: np.ndarray, angles: np.ndarray) -> np.ndarray:
        if state[4] == 0.0:
            return np.zeros(2)
        return self._pole * state[2:4] + self._gain * (angles - state[:2])

    def _update(self, context, discrete_state):
        state = context.get_discrete_state(self._state).value()
        angles = self._angles.Eval(context)
        discrete_state.get_mutable_vector(self._state).SetFromVector(
            np.concatenate([angles, self._velocity(state, angles), [1.0]])
        )

    def _calc(self, context, output: BasicVector):
        angles = self._angles.Eval(context)
        output.SetFromVector(
            np.concatenate([angles, self._velocity(context.get_discrete_state(self._state).value(), angles)])
        )


__all__ = ["FilteredDerivativeParameters", "filter_coefficients", "filtered_derivative", "FilteredDerivative"]
