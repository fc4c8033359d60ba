"""The variance a jittering input delay adds to the predicted angles, beside the expected command the surrogate applies.

A delay drawn anew every sample, D_k uniform on delay +- sqrt(3) delay_spread, applies over sample k the held
command delayed by D_k. Averaged over the sample, that is the logged command read at the fractional index
k - D_k / T, linear between its samples:

    a_k(D) = (1 - f) u[k - j] + f u[k - j - 1],   j = floor(D / T), f = D / T - j.

The surrogate applies its expectation E[a_k(D)] (:func:`~furuta_drake.effects.surrogate.expected_command`); the
deviation a_k(D_k) - E[a_k(D)] is a command disturbance of variance v_k = Var_D[a_k(D)], independent from sample
to sample, that no deterministic prediction removes. To first order its angles are the window's impulse responses
g_nk = d y_n / d u_k (a unit change of the command over sample k, through the model's lag, static map and
dynamics), so each predicted angle gains the variance

    sigma_j^2(n) = sum_{k < n} g_nk^2 v_k,

a process-noise counterpart of the sensor's variance.
"""

from __future__ import annotations

import numpy as np

from furuta_drake.effects.surrogate import Model, jitter_width

MAX_COLUMNS = 20_000  # impulse-response columns (windows x samples) per surrogate call: bounds the memory


def command_variance(command: np.ndarray, period: float, model: Model) -> np.ndarray:
    """v_k [N m^2] at every sample k of ``command`` (module docstring): the variance, over the delay uniform on
    delay +- width / 2, of the held command averaged over the sample, exact by pieces (a_k is linear in D between
    multiples of the period); the ends are held beyond the log. Zeros without a spread."""
    if model.delay_spread <= 0:
        return np.zeros(command.size)
    width = jitter_width(model)
    low, high = (model.delay - width / 2.0) / period, (model.delay + width / 2.0) / period
    k, last = np.arange(command.size), command.size - 1
    reference = command[np.clip(k - int(round(0.5 * (low + high))), 0, last)]  # the variance is shift invariant

    def at(j: int, x: float) -> np.ndarray:
        here, next_ = command[np.clip(k - j, 0, last)], command[np.clip(k - j - 1, 0, last)]
        return here + (x - j) * (next_ - here) - reference

    first, second = np.zeros(command.size), np.zeros(command.size)
    for j in range(int(np.floor(low)), int(np.ceil(high))):
        a, b = max(j, low), min(j + 1, high)
        fa, fb = at(j, a), at(j, b)
        first += (b - a) * (fa + fb) / 2.0
        second += (b - a) * (fa * fa + fa * fb + fb * fb) / 3.0
    mean = first / (high - low)
    return np.maximum(second / (high - low) - mean * mean, 0.0)


def response_variance(variance: np.ndarray, predict, residual_of=None) -> np.ndarray:
    """sigma_j^2 (horizon, 2, W) [the angles' unit^2] of W windows (module docstring) from ``variance``
    (horizon - 1, W), v_k of each window's samples [N m^2], and ``predict(part, copies, change)``: the angles
    (horizon, 2, copies w) predicted for the w windows ``part`` (a slice), ``copies`` times, with the command of
    each sample changed by ``change`` (horizon - 1, copies w) before the lag and static map (the ``change`` of
    :func:`~.surrogate.predict_windows`). The impulse responses are forward differences of one command impulse
    per sample, of the deviation's own size (the root mean of v_k), batched over windows; ``residual_of(responses,
    part)``: what of the responses (horizon, 2, horizon - 1, w) stays in the residual (the gap refits each
    window's initial state, which absorbs their smooth share); None: all of them. Zeros where every v_k is."""
    samples, W = variance.shape
    out = np.zeros((samples + 1, 2, W))
    size = float(np.sqrt(np.mean(variance))) if variance.size else 0.0
    if size == 0.0:
        return out
    chunk = max(1, MAX_COLUMNS // (samples + 1))
    for first in range(0, W, chunk):
        part = slice(first, min(first + chunk, W))
        g = _impulse_change(predict, part, samples, size) / size
        g = g if residual_of is None else residual_of(g, part)
        out[:, :, part] = np.einsum("nskw,kw->nsw", g**2, variance[:, part])
    return out


def _impulse_change(predict, part: slice, samples: int, size: float) -> np.ndarray:
    """(samples + 1, 2, samples, w): the predicted angles' change when the command of sample k (axis 2) rises by
    ``size`` [N m], one call of width (samples + 1) w (copy 0 the unperturbed windows)."""
    w, copies = part.stop - part.start, samples + 1
    impulse = np.zeros((samples, copies, w))
    impulse[np.arange(samples), np.arange(1, copies)] = size
    predicted = predict(part, copies, impulse.reshape(samples, -1)).reshape(samples + 1, 2, copies, w)
    return predicted[:, :, 1:] - predicted[:, :, :1]
