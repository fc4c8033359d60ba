"""The balancing limit cycle of a run: its amplitude and frequency, and the run's balancing figures.

A balancing loop with friction, a dead zone or a coarse encoder does not come to rest: it settles into an
oscillation (a limit cycle) about the upright. Over the run's steady part (``STEADY_SHARE`` of it, at its end):

- **frequency** [Hz]: the dominant peak of the signal's periodogram (mean removed, Hann window, zero-padded to
  ``PADDING`` times its length), refined by a parabola through the peak's log-power and its two neighbours, at
  or above two cycles over the steady part (a slower swing is a drift, not a cycle);
- **amplitude** [rad]: half the peak-to-peak of the signal over each period of that frequency, the median over the
  periods (a spike or a missed cycle moves it little; a drift within one period does not enter).

A sine of amplitude a gives a; a signal at the encoder's rounding gives about one count.
"""

from __future__ import annotations

import math

import numpy as np

STEADY_SHARE = 0.5  # the last half of a run is its steady part
PADDING = 8  # zero-padding of the periodogram


def dominant_frequency(signal: np.ndarray, period: float) -> float:
    """The frequency [Hz] of the periodogram's highest peak of ``signal`` sampled at ``period`` [s] (module
    docstring); NaN for a constant signal or one shorter than four samples."""
    values = np.asarray(signal, dtype=float)
    if values.size < 4 or np.ptp(values) == 0.0:
        return float("nan")
    centred = (values - values.mean()) * np.hanning(values.size)
    power = np.abs(np.fft.rfft(centred, PADDING * values.size)) ** 2
    frequencies = np.fft.rfftfreq(PADDING * values.size, period)
    lowest = 2.0 / (values.size * period)
    allowed = np.nonzero(frequencies >= lowest)[0]
    if allowed.size == 0:
        return float("nan")
    k = allowed[np.argmax(power[allowed])]
    if allowed[0] < k < power.size - 1 and np.all(power[k - 1 : k + 2] > 0):
        a, b, c = np.log(power[k - 1 : k + 2])
        denominator = a - 2.0 * b + c
        offset = 0.5 * (a - c) / denominator if denominator != 0 else 0.0
        return float(frequencies[k] + offset * (frequencies[1] - frequencies[0]))
    return float(frequencies[k])


def cycle_amplitude(signal: np.ndarray, period: float, frequency: float) -> float:
    """Half the peak-to-peak of ``signal`` over each whole period of ``frequency`` [Hz], the median over the
    periods [rad]; half the whole signal's peak-to-peak when it holds less than one period."""
    values = np.asarray(signal, dtype=float)
    if values.size == 0:
        return float("nan")
    samples = int(round(1.0 / (frequency * period))) if math.isfinite(frequency) and frequency > 0 else values.size
    if samples < 2 or samples >= values.size:
        return 0.5 * float(np.ptp(values))
    cycles = values[: (values.size // samples) * samples].reshape(-1, samples)
    return 0.5 * float(np.median(np.ptp(cycles, axis=1)))


def limit_cycle(signal: np.ndarray, period: float) -> tuple[float, float]:
    """(amplitude [rad], frequency [Hz]) of the limit cycle in the steady part of ``signal`` sampled at
    ``period`` [s] (module docstring)."""
    steady = steady_part(signal)
    frequency = dominant_frequency(steady, period)
    return cycle_amplitude(steady, period, frequency), frequency


def steady_part(signal: np.ndarray) -> np.ndarray:
    """The last ``STEADY_SHARE`` of ``signal`` (along its first axis)."""
    values = np.asarray(signal, dtype=float)
    return values[int(round((1.0 - STEADY_SHARE) * len(values))) :]


def rms(values) -> float:
    values = np.asarray(values, dtype=float)
    return float(np.sqrt(np.mean(np.square(values)))) if values.size else float("nan")


def balancing_figures(theta: np.ndarray, phi: np.ndarray, command: np.ndarray, period: float) -> dict:
    """The contract's ``predicted`` figures of a balancing run sampled at ``period`` [s]: over its steady part,
    the RMS of theta and phi about the upright [rad] and of the command [N m], and theta's limit cycle
    (:func:`limit_cycle`)."""
    amplitude, frequency = limit_cycle(theta, period)
    return {
        "theta_rms": rms(steady_part(theta)),
        "phi_rms": rms(steady_part(phi)),
        "limit_cycle_amplitude": amplitude,
        "limit_cycle_frequency": frequency,
        "effort_rms": rms(steady_part(command)),
    }
