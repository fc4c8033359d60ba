"""The rig's disturbance (``report.json``'s ``disturbance``): what the corrected model still misses on the held-out
logs, read as an equivalent torque on the arm.

A torque d on the arm enters the equations of motion (paper Eq. 3, in the lumped constants a, b, c, d of
:mod:`~furuta_drake.effects.surrogate`) as M(q) q'' = f(q, q', tau) + [0, d]: so along a held-out log,

    d_hat = [M(q) (q''_measured - q''_model)]_arm,

where q'' is each logged angle's lag-L second difference over ``SMOOTHING_S`` (for a command held over each
sample, exactly the accelerations' tent-weighted mean over the 2 L samples about it:
:func:`~furuta_drake.diagnosis.selection.equation_error.tent`), and q''_model the corrected model's acceleration
over each sample, at the smoothed state there, under its applied torque (the logged command through the model's
delay, lag and static map, and a Dahl arm's bristle torque along the smoothed arm path), averaged with the same
tent, so that both sides see the same band. The estimate holds up to the tent's half-amplitude frequency, and its
spectrum is divided by the tent's power response there. The encoder's rounding and the fitted noise enter the
differenced angles. The rounding of a moving angle is not white (a slow angle's rounding error is a slow sawtooth,
much of its power in the band), so its share is read the same way from the smoothed angles rounded again to the
model's encoder at several offsets (``ROUNDING_OFFSETS``), less themselves; the fitted noise's share is its
spectrum through the difference's response, weighted by M's entries along the log. Both come off the mean spectrum.
A drive's twist is not observed in the logs: the drive is read as rigid here.

The level is the RMS of the spectrum that remains (Welch's method over ``SEGMENT_S`` segments of every held-out
log, Hann window, half-overlapping); its 95 % interval comes from resampling the segments. The bandwidth is the
frequency below which 90 % of its power lies.
"""

from __future__ import annotations

import numpy as np
from scipy.signal import savgol_filter, spectrogram

from furuta_drake.diagnosis.selection.equation_error import second_difference, tent, tent_averaged
from furuta_drake.effects import surrogate_kernel as kernel
from furuta_drake.effects.surrogate import Model, applied_torque, bristle_path, expected_command
from furuta_drake.encoder import encoder_resolution
from furuta_drake.torque_disturbance import TorqueDisturbance, bandwidth

SMOOTHING_S = 0.07  # [s] span of the lag second difference and its tent (band edge about 12 Hz)
SEGMENT_S = 2.0  # [s] Welch segments, shorter when the longest log holds fewer than MIN_SEGMENTS of them
ROUNDING_OFFSETS = (0.0, 0.25, 0.5, 0.75)  # [steps] the encoder offsets the rounding's own reading averages
MIN_SEGMENTS = 4  # half-overlapping segments the longest log holds at the least (the interval resamples them)
SHORTEST_S = 0.5  # [s] the shortest segment: logs too short for MIN_SEGMENTS of it give no disturbance
RESAMPLES = 400  # bootstrap resamples of the segments
FLOOR_SHARE = 0.5  # the band ends where the tent's amplitude response falls below this


def equivalent_disturbance(model: Model, logs, seed: int) -> TorqueDisturbance | None:
    """The arm torque ``model`` misses along ``logs`` (held-out :class:`~furuta_drake.diagnosis.logs.load.RunLog`
    s of one sample period), seeded bootstrap; None when the logs are too short (``SHORTEST_S``)."""
    period = float(np.median([log.sample_period for log in logs]))
    lag = max(1, int(round(SMOOTHING_S / (2.0 * period))))
    residuals = [_arm_residual(model, log, lag, period) for log in logs]
    longest = max(residual.size for residual, _, _ in residuals)
    segment = min(int(round(SEGMENT_S / period)), 2 * longest // (MIN_SEGMENTS + 1))
    if segment * period < SHORTEST_S:
        return None
    rows, noise_rows = [], []
    for residual, rounding, weights in residuals:
        if residual.size >= segment:
            frequencies, psd = _segments(residual, segment, period)
            rows.append(psd)
            noise = np.mean([_segments(draw, segment, period)[1] for draw in rounding], axis=0)
            noise_rows.append(noise + weights.sum() * _noise_psd(model, frequencies, lag, period)[None, :])
    segments, noise = np.vstack(rows), np.vstack(noise_rows)
    band = (frequencies > 0) & (frequencies <= _band_edge(lag, period))
    # the encoder's share comes off the mean spectrum, clipped there, not off each segment (whose clipped
    # fluctuations would add up to a floor)
    excess = (segments - noise)[:, band] / _tent_response(frequencies[band], lag, period) ** 2
    df = frequencies[1] - frequencies[0]
    psd = np.clip(excess.mean(axis=0), 0.0, None)
    rng = np.random.default_rng([seed, 29])
    draws = rng.integers(0, excess.shape[0], size=(RESAMPLES, excess.shape[0]))
    levels = np.sqrt(np.clip(excess[draws].mean(axis=1), 0.0, None).sum(axis=1) * df)
    return TorqueDisturbance(
        arm_torque_rms=float(np.sqrt(psd.sum() * df)),
        spectrum=[[float(f), float(p)] for f, p in zip(frequencies[band], psd)],
        bandwidth_hz=bandwidth(frequencies[band], psd),
        ci=[float(v) for v in np.percentile(levels, [2.5, 97.5])],
    )


def _segments(values: np.ndarray, segment: int, period: float) -> tuple[np.ndarray, np.ndarray]:
    """(frequencies [Hz], one-sided PSD of each half-overlapping Hann segment of ``values`` (S, F))."""
    frequencies, _, psd = spectrogram(
        values, fs=1.0 / period, window="hann", nperseg=segment, noverlap=segment // 2, detrend="constant"
    )
    return frequencies, psd.T


def _arm_residual(model: Model, log, lag: int, period: float):
    """(d_hat along ``log`` less its ends; the same reading of the rounding alone, one row per encoder offset of
    ``ROUNDING_OFFSETS``: the smoothed angles rounded to the model's encoder, less themselves; the mean squared
    weights [(c cos theta)^2, (a + b sin^2 theta)^2] of the two angles' white noise in d_hat)."""
    angles = np.vstack([log.theta, log.phi])
    window = 2 * lag + 1
    if angles.shape[1] <= 3 * window:
        return np.zeros(0), np.zeros((0, 0)), np.zeros(2)
    q, v = (savgol_filter(angles, window, 3, deriv=k, delta=period, axis=1) for k in range(2))
    acceleration = second_difference(angles, lag, period)
    torque = _applied(model, log.torque_command, period)
    if model.arm_friction.has_bristles:
        packed = kernel.pack_friction(model.arm_friction)
        z = bristle_path(q[1], model.arm_friction, period)
        torque = torque + np.array([kernel.bristle_torque(zk, vk, packed) for zk, vk in zip(z, v[1])])
    # each command holds over [t_k, t_k+1): the model's accelerations there, at the interval's middle state
    x = np.vstack([q, v])
    middle = np.ascontiguousarray(0.5 * (x + np.concatenate([x[:, 1:], x[:, -1:]], axis=1)))
    held = kernel.derivatives(middle, np.ascontiguousarray(torque), *kernel.pack(model))[2:]
    weights = tent(lag)
    miss = acceleration - np.vstack([tent_averaged(row, weights) for row in held])
    s, co = np.sin(q[0]), np.cos(q[0])
    coupling = model.coupling * co
    arm = model.arm_inertia_total + model.pendulum_inertia_total * s**2
    residual = coupling * miss[0] + arm * miss[1]
    step = encoder_resolution(model.counts_per_rev)
    rounding = []
    for offset in ROUNDING_OFFSETS:
        error = second_difference(step * np.round(q / step + offset) - q, lag, period)
        rounding.append((coupling * error[0] + arm * error[1])[window:-window])
    edge = window
    weights = np.array([np.mean(coupling[edge:-edge] ** 2), np.mean(arm[edge:-edge] ** 2)])
    return residual[edge:-edge], np.array(rounding), weights


def _applied(model: Model, command: np.ndarray, period: float) -> np.ndarray:
    """The model's arm torque [N m] at every sample of a logged ``command``: its delay, lag and static map."""
    times = (np.arange(command.size) * period)[:, None]
    held = expected_command(command, np.zeros((1, 1), dtype=int), times, period, period, model)
    if model.lag > 0:
        held = kernel.lag_filter(np.ascontiguousarray(held), held[0].copy(), model.lag, period)[0]
    return applied_torque(model, held)[:, 0]


def _tent_response(frequencies: np.ndarray, lag: int, period: float) -> np.ndarray:
    """|T(f)|, the amplitude response of the tent over the held intervals about a sample."""
    taps = np.arange(2 * lag) - lag + 0.5
    return np.abs(np.exp(-2j * np.pi * np.outer(frequencies * period, taps)) @ tent(lag))


def _band_edge(lag: int, period: float) -> float:
    """The frequency [Hz] where the tent's amplitude response first falls below ``FLOOR_SHARE``."""
    grid = np.linspace(0.0, 0.5 / period, 4000)
    below = np.nonzero(_tent_response(grid, lag, period) < FLOOR_SHARE)[0]
    return float(grid[below[0]]) if below.size else float(grid[-1])


def _noise_psd(model: Model, frequencies: np.ndarray, lag: int, period: float) -> np.ndarray:
    """(F,) the one-sided PSD [rad^2/s^4/Hz] of the fitted noise (white, or first-order low-passed over its
    correlation time) in an angle's lag-``lag`` second difference, through its response
    |2 cos(2 pi f L T) - 2| / (L T)^2 (the rounding is read apart, :func:`_arm_residual`)."""
    if model.noise_std <= 0:
        return np.zeros(frequencies.shape)
    shaped = np.full(frequencies.shape, 2.0 * period * model.noise_std**2)
    if model.noise_correlation_time > 0:
        rho = np.exp(-period / model.noise_correlation_time)
        shaped *= (1 - rho**2) / np.abs(1 - rho * np.exp(-2j * np.pi * frequencies * period)) ** 2
    span = lag * period
    return shaped * ((2.0 - 2.0 * np.cos(2 * np.pi * frequencies * span)) / span**2) ** 2
