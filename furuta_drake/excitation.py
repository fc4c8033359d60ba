"""Excitation signals as Drake trajectories: a seeded multisine torque, a recorded torque command, and a
square-wave arm reference."""

from __future__ import annotations

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

from furuta_drake.config import ExcitationConfig


def multisine(
    excitation: ExcitationConfig, duration: float, sample_period: float, rng: np.random.Generator
) -> tuple[np.ndarray, np.ndarray]:
    """Times [s] and values [N m] of a multisine with ``torque_components`` sines, frequencies log-uniform in
    [frequency_min, frequency_max], random phases, total RMS ``torque_rms``."""
    n = excitation.torque_components
    freqs = np.exp(rng.uniform(np.log(excitation.frequency_min), np.log(excitation.frequency_max), n))
    phases = rng.uniform(0.0, 2.0 * np.pi, n)
    times = np.arange(0.0, duration + 2 * sample_period, sample_period)
    amplitude = excitation.torque_rms * np.sqrt(2.0 / n)
    values = amplitude * np.sin(2.0 * np.pi * np.outer(times, freqs) + phases).sum(axis=1)
    return times, values


def torque_excitation_trajectory(
    excitation: ExcitationConfig, duration: float, sample_period: float, seed: int
) -> PiecewisePolynomial | None:
    """The multisine plus the recorded ``command`` (zero after its end) as a zero-order-hold trajectory at the
    control period [N m], or None when there is neither."""
    if excitation.torque_rms == 0 and excitation.command is None:
        return None
    times = np.arange(0.0, duration + 2 * sample_period, sample_period)
    values = np.zeros(times.size)
    if excitation.torque_rms > 0:
        values += multisine(excitation, duration, sample_period, np.random.default_rng([seed, 1]))[1]
    if excitation.command is not None:
        played = np.asarray(excitation.command, dtype=float)[: times.size]
        values[: played.size] += played
    return PiecewisePolynomial.ZeroOrderHold(times, values.reshape(1, -1))


def arm_reference_trajectory(excitation: ExcitationConfig, duration: float) -> PiecewisePolynomial | None:
    """Paper-order state reference [0, phi_ref, 0, 0] with phi_ref a square wave of the configured amplitude
    and period (starting positive), or None when the amplitude is 0."""
    if excitation.arm_reference_amplitude == 0:
        return None
    half = excitation.arm_reference_period / 2.0
    times = np.arange(0.0, duration + half, half)
    levels = excitation.arm_reference_amplitude * np.where(np.arange(times.size) % 2 == 0, 1.0, -1.0)
    values = np.zeros((4, times.size))
    values[1] = levels
    return PiecewisePolynomial.ZeroOrderHold(times, values)
