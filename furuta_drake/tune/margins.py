"""Gain and delay margins of a sampled state-feedback loop, broken at the plant input.

With the design model s_k+1 = Phi s_k + Gamma u_k (:class:`~furuta_drake.tune.design.DesignModel`) and
u = -g K x, the loop gain is L(z) = K S (z I - Phi)^-1 Gamma (S selects x from s); the loop is stable at g = 1.

- **gain margin**: the loop stays stable for g in (g_low, g_high); it changes stability only where
  1 + g L(e^(j w h)) = 0, i.e. at the phase crossovers (L real and negative, including w = pi / h), where
  g = -1 / L. ``gain_db`` = min(20 log10 g_high, -20 log10 g_low): how far, up or down, the loop gain may move
  (an upright pendulum is open-loop unstable, so a gain too low destabilises it as well as one too high);
- **delay margin**: an extra input delay tau multiplies L(e^(j w h)) by e^(-j w tau); at a gain crossover w_c
  (|L| = 1) stability is lost when w_c tau reaches the phase margin pi + arg L(e^(j w_c h)) (taken in [0, 2 pi)),
  so ``delay_s`` = min over crossovers of that phase over w_c (inf without a crossover).

The frequency response is evaluated on a grid of ``POINTS`` frequencies up to the Nyquist frequency and every
crossing is refined by bisection on the exact response.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from furuta_drake.tune.design import UNSTABLE, DesignModel, spectral_radius

POINTS = 4000  # frequencies of the grid, log-spaced up to the Nyquist frequency
REFINE = 60  # bisection steps of a crossing


@dataclass(frozen=True)
class Margins:
    """The loop's margins: ``gain_db`` [dB] (the smaller of ``gain_high`` up and ``gain_low`` down), ``gain_low``
    and ``gain_high`` [-] (the loop is stable for gains between them), ``delay_s`` [s], and whether the loop is
    stable at g = 1 (``stable``; every margin is 0 when it is not)."""

    gain_db: float
    gain_low: float
    gain_high: float
    delay_s: float
    stable: bool

    def as_dict(self) -> dict:
        return {"gain_db": self.gain_db, "delay_s": self.delay_s, "gain_range": [self.gain_low, self.gain_high]}


def loop_response(model: DesignModel, K, z: np.ndarray) -> np.ndarray:
    """L(z) = K S (z I - Phi)^-1 Gamma at the points ``z`` (complex, on the unit circle)."""
    row = model.select(K)
    n = model.size
    resolvent = z[:, None, None] * np.eye(n) - model.Phi
    return (row @ np.linalg.solve(resolvent, np.broadcast_to(model.Gamma, (z.size, n, 1))))[:, 0, 0]


def margins(model: DesignModel, K) -> Margins:
    """The gain and delay margins of u = -K x on ``model`` (module docstring)."""
    if spectral_radius(model.feedback(K)) >= UNSTABLE:
        return Margins(0.0, 1.0, 1.0, 0.0, False)
    h = model.period
    nyquist = math.pi / h
    w = np.geomspace(1e-4, nyquist, POINTS)  # w = 0 left out: a free arm is a pole at z = 1

    def L(frequencies):
        return loop_response(model, K, np.exp(1j * np.asarray(frequencies, dtype=float) * h))

    def refine(f, a: float, b: float) -> float:
        fa = f(a)
        for _ in range(REFINE):
            middle = 0.5 * (a + b)
            if np.sign(f(middle)) == np.sign(fa):
                a, fa = middle, f(middle)
            else:
                b = middle
        return 0.5 * (a + b)

    response = L(w)
    gains = []
    imaginary = response.imag
    for i in np.nonzero(np.sign(imaginary[:-1]) != np.sign(imaginary[1:]))[0]:
        crossing = refine(lambda f: L([f])[0].imag, w[i], w[i + 1])
        gains.append(L([crossing])[0])
    gains += [value for value in response[[-1]] if abs(value.imag) < 1e-12 * max(abs(value), 1.0)]
    critical = [-1.0 / value.real for value in gains if value.real < 0]
    high = min([g for g in critical if g > 1.0], default=math.inf)
    low = max([g for g in critical if g < 1.0], default=0.0)
    gain_db = min(
        20.0 * math.log10(high) if math.isfinite(high) else math.inf, -20.0 * math.log10(low) if low > 0 else math.inf
    )
    magnitude = np.abs(response) - 1.0
    delays = []
    for i in np.nonzero(np.sign(magnitude[:-1]) != np.sign(magnitude[1:]))[0]:
        crossover = refine(lambda f: abs(L([f])[0]) - 1.0, w[i], w[i + 1])
        phase = np.mod(np.angle(L([crossover])[0]) + math.pi, 2.0 * math.pi)
        delays.append(phase / crossover if crossover > 0 else math.inf)
    return Margins(float(gain_db), float(low), float(high), float(min(delays, default=math.inf)), True)
