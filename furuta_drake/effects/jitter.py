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


def impulse_energy(predict, samples: int, windows: int, size: float, residual_of=None, stride: int = 1) -> np.ndarray:
    """g_nk^2 (samples + 1, 2, samples, W) [the angles' unit^2 per N m^2] of W windows (module docstring) from
    ``predict(part, copies, change)``: the angles (samples + 1, 2, copies w) predicted for the w windows ``part``
    (a slice), ``copies`` times, with the command of each sample changed by ``change`` (samples, copies w) [N m]
    before the lag and the static map. The impulse responses are forward differences of one command impulse of
    ``size`` [N m] (about the deviation's own size), batched over windows, at every ``stride``-th sample; between
    them a sample's response is the one of the impulse before it, shifted in time (the response changes with the
    operating point, which moves little over a few samples). ``residual_of(responses, part)``: what of the
    responses (samples + 1, 2, samples, w) stays in the residual (the gap refits each window's initial state,
    which absorbs their smooth share); None: all of them."""
    out = np.zeros((samples + 1, 2, samples, windows))
    chunk = max(1, MAX_COLUMNS // (samples // stride + 2))
    for first in range(0, windows, chunk):
        part = slice(first, min(first + chunk, windows))
        g = _impulse_change(predict, part, samples, size, stride) / size
        out[..., part] = (g if residual_of is None else residual_of(g, part)) ** 2
    return out


def response_variance(energy: np.ndarray, variance: np.ndarray) -> np.ndarray:
    """sigma_j^2 (samples + 1, 2, W) of each window's predicted angles (module docstring) from their
    :func:`impulse_energy` and the command's variance v_k (samples, W) [N m^2] at each of their samples."""
    return np.einsum("nskw,kw->nsw", energy, variance)


def _impulse_change(predict, part: slice, samples: int, size: float, stride: int) -> np.ndarray:
    """(samples + 1, 2, samples, w): the predicted angles' change when the command of sample k (axis 2) rises by
    ``size`` [N m], simulated for every ``stride``-th k in one call (copy 0 the unperturbed windows) and shifted in
    time for the samples between."""
    w, impulses = part.stop - part.start, np.arange(0, samples, stride)
    copies = impulses.size + 1
    change = np.zeros((samples, copies, w))
    change[impulses, np.arange(1, copies)] = size
    predicted = predict(part, copies, change.reshape(samples, -1)).reshape(samples + 1, 2, copies, w)
    simulated = (predicted[:, :, 1:] - predicted[:, :, :1]).transpose(0, 2, 1, 3)  # (samples + 1, impulses, 2, w)
    k = np.arange(samples)
    rows = np.arange(samples + 1)[:, None] - (k % stride)[None, :]  # the simulated impulse's sample n - shift
    g = np.where((rows >= 0)[..., None, None], simulated[np.maximum(rows, 0), (k // stride)[None, :]], 0.0)
    return g.transpose(0, 2, 1, 3)
