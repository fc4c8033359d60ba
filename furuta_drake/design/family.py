"""The excitation family the design searches: band-limited arm motions played as feedforward torque.

An open-loop torque on the arm integrates twice, so a zero-mean torque still walks the arm away. The family is
therefore written as the arm motion it aims at, played through the accepted model's arm:

    phi_d(t) = e(t) sum_k A_k sin(2 pi f_k t + psi_k)                                   [rad]
    u(t)     = a phi_d''(t) + (b_emf + b_v) phi_d'(t)                                    [N m]

with a = J_arm + m r^2 and b_emf + b_v the back-EMF and viscous damping of the model. The frequencies f_k are
the harmonics of 1 / P, P = min(``PERIOD_S``, duration / 2) (the motion repeats, so the train and held-out halves
of the log see the same excitation, and a longer experiment is the same motion repeated more often), between
1 / P and ``MAX_FREQUENCY`` (at most ``NYQUIST_FRACTION`` of the Nyquist frequency), grouped into ``BANDS``
log-spaced bands. A band's components share its amplitude: ``amplitudes[b]``
is the band's peak arm angle if its sines were in phase, spread as A_k = amplitudes[b] / n_b. Phases are
Schroeder's (low crest factor, no random draw). The envelope e rises and falls as a raised cosine over
``RAMP_S``, so the arm starts and ends at rest (phi_d, phi_d' = 0). The pendulum's reaction on the arm and
friction are left to the simulations that check the bounds: the feedforward only keeps the arm from drifting.

For ``--balancing`` the same multisine is a torque dither (``torque_dither``) added to the LQR's command.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

PERIOD_S = 4.0  # [s]
BANDS = 5
MAX_FREQUENCY = 25.0  # [Hz]
NYQUIST_FRACTION = 0.2
RAMP_S = 0.5  # [s], at most an eighth of the duration


@dataclass(frozen=True)
class Family:
    """The components of the family for one duration and sample period."""

    duration: float  # [s]
    period: float  # sample period [s]
    inertia: float  # a [kg m^2]
    damping: float  # b_emf + b_v [N m s/rad]

    @property
    def samples(self) -> int:
        return int(round(self.duration / self.period))

    @property
    def time(self) -> np.ndarray:
        return np.arange(self.samples) * self.period

    @property
    def fundamental(self) -> float:
        """1 / P [Hz]."""
        return 1.0 / min(PERIOD_S, self.duration / 2.0)

    def base(self) -> Family:
        """The same family over two periods: the experiment the search simulates (a longer one repeats it)."""
        return Family(min(self.duration, 2.0 / self.fundamental), self.period, self.inertia, self.damping)

    @property
    def ramp(self) -> float:
        return min(RAMP_S, self.duration / 8.0)

    @property
    def band_edges(self) -> np.ndarray:
        """BANDS + 1 log-spaced edges [Hz] from the fundamental to the highest frequency."""
        top = min(MAX_FREQUENCY, NYQUIST_FRACTION * 0.5 / self.period)
        return np.geomspace(self.fundamental, max(top, 2.0 * self.fundamental), BANDS + 1)

    def components(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(frequencies [Hz], band index, Schroeder phases [rad]) of every harmonic in a band."""
        edges = self.band_edges
        harmonics = np.arange(1, int(np.floor(edges[-1] / self.fundamental * (1 + 1e-9))) + 1)
        frequencies = harmonics * self.fundamental
        band = np.clip(np.searchsorted(edges, frequencies * (1 - 1e-9), side="right") - 1, 0, BANDS - 1)
        k = np.arange(1, frequencies.size + 1)
        return frequencies, band, -np.pi * k * (k - 1) / frequencies.size

    def _envelope(self, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """e, e', e'' of the raised-cosine ramps in and out."""
        ramp = self.ramp
        w = np.pi / ramp
        e, de, dde = np.ones_like(t), np.zeros_like(t), np.zeros_like(t)
        for edge, sign in ((t < ramp, 1.0), (t > self.duration - ramp, -1.0)):
            s = t[edge] if sign > 0 else self.duration - t[edge]
            e[edge] = 0.5 * (1.0 - np.cos(w * s))
            de[edge] = sign * 0.5 * w * np.sin(w * s)
            dde[edge] = 0.5 * w**2 * np.cos(w * s)
        return e, de, dde

    def _multisine(self, amplitudes: np.ndarray, t: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(D, N) values, first and second derivatives of the band multisines of ``amplitudes`` (D, BANDS)."""
        frequencies, band, phases = self.components()
        counts = np.bincount(band, minlength=BANDS)
        per_component = np.asarray(amplitudes, dtype=float)[:, band] / np.maximum(counts[band], 1)  # (D, K)
        angle = 2 * np.pi * np.outer(frequencies, t) + phases[:, None]  # (K, N)
        omega = 2 * np.pi * frequencies[:, None]
        sine, cosine = np.sin(angle), np.cos(angle)
        return (per_component @ sine, per_component @ (omega * cosine), -(per_component @ (omega**2 * sine)))

    def arm_motion(self, amplitudes: np.ndarray) -> np.ndarray:
        """(D, N) the arm angle phi_d [rad] the feedforward aims at, at the sample times."""
        p, _, _ = self._multisine(np.atleast_2d(amplitudes), self.time)
        return self._envelope(self.time)[0] * p

    def feedforward(self, amplitudes: np.ndarray) -> np.ndarray:
        """(D, N) the torque command [N m] of the module docstring, held over each sample (evaluated at its
        middle)."""
        t = self.time + 0.5 * self.period
        p, dp, ddp = self._multisine(np.atleast_2d(amplitudes), t)
        e, de, dde = self._envelope(t)
        velocity = de * p + e * dp
        acceleration = dde * p + 2.0 * de * dp + e * ddp
        return self.inertia * acceleration + self.damping * velocity

    def torque_dither(self, amplitudes: np.ndarray) -> np.ndarray:
        """(D, N) the band multisines as a torque [N m] (``amplitudes`` in N m), with the ramps."""
        p, _, _ = self._multisine(np.atleast_2d(amplitudes), self.time)
        return self._envelope(self.time)[0] * p

    def describe(self, amplitudes: np.ndarray, unit: str) -> dict:
        """The design's parameters for design.json: the bands with their amplitude (in ``unit``) and components."""
        frequencies, band, _ = self.components()
        edges = self.band_edges
        return {
            "fundamental_hz": self.fundamental,
            "periods": self.duration * self.fundamental,
            "ramp_s": self.ramp,
            "phases": "Schroeder",
            "bands": [
                {
                    "low_hz": float(edges[b]),
                    "high_hz": float(edges[b + 1]),
                    "components": int(np.sum(band == b)),
                    f"amplitude_{unit}": float(amplitudes[b]),
                }
                for b in range(BANDS)
            ],
        }
