"""An ongoing torque on the arm that no model term explains: the rig's disturbance (torque ripple, a cable, what the
corrected model still misses), as a level and a one-sided power spectral density.

A diagnosis reads it from its held-out logs (:mod:`furuta_drake.diagnosis.selection.disturbance`) and writes it in the
fitted rig file's ``disturbance:`` section; a simulation adds a seeded draw of it to the arm's generalised force
(paper Eq. 3's tau gains one more term on the arm), so that ``tune`` judges its designs on a rig that is pushed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

from furuta_drake.errors import ConfigError


@dataclass
class TorqueDisturbance:
    """An arm torque of RMS ``arm_torque_rms`` [N m] whose spectrum has the shape of ``spectrum`` ([frequency [Hz],
    PSD [N^2 m^2/Hz]] pairs, frequencies increasing; linear between them, zero outside); ``bandwidth_hz``, the
    frequency below which 90 % of its power lies, and ``ci``, the 95 % interval of the RMS, say how it was read."""

    arm_torque_rms: float = 0.0  # [N m]
    spectrum: list[list[float]] = field(default_factory=list)  # [[Hz, N^2 m^2/Hz], ...]
    bandwidth_hz: float = 0.0  # [Hz]
    ci: list[float] | None = None  # [N m]

    def validate(self, where: str = "disturbance") -> None:
        """Raise :class:`ConfigError` naming the first value that is not a disturbance's."""
        if not (isinstance(self.arm_torque_rms, (int, float)) and math.isfinite(self.arm_torque_rms)):
            raise ConfigError(f"{where}.arm_torque_rms must be a finite number, got {self.arm_torque_rms!r}")
        if self.arm_torque_rms < 0:
            raise ConfigError(f"{where}.arm_torque_rms must be >= 0, got {self.arm_torque_rms!r}")
        if self.arm_torque_rms > 0 and len(self.spectrum) < 2:
            raise ConfigError(f"{where}.spectrum needs at least two [frequency, PSD] pairs when arm_torque_rms > 0")
        table = np.asarray(self.spectrum, dtype=float).reshape(-1, 2) if self.spectrum else np.zeros((0, 2))
        if len(self.spectrum) and table.shape[0] != len(self.spectrum):
            raise ConfigError(f"{where}.spectrum must be a list of [frequency, PSD] pairs")
        if not np.all(np.isfinite(table)) or np.any(table < 0):
            raise ConfigError(f"{where}.spectrum must hold non-negative finite numbers")
        if table.shape[0] and np.any(np.diff(table[:, 0]) <= 0):
            raise ConfigError(f"{where}.spectrum's frequencies must increase")
        if self.arm_torque_rms > 0 and not np.any(table[:, 1] > 0):
            raise ConfigError(f"{where}.spectrum has no power, but arm_torque_rms > 0")
        if not (math.isfinite(self.bandwidth_hz) and self.bandwidth_hz >= 0):
            raise ConfigError(f"{where}.bandwidth_hz must be a non-negative number, got {self.bandwidth_hz!r}")
        if self.ci is not None and (
            len(self.ci) != 2 or not all(math.isfinite(v) for v in self.ci) or not 0 <= self.ci[0] <= self.ci[1]
        ):
            raise ConfigError(f"{where}.ci must be [low, high] with 0 <= low <= high, got {self.ci!r}")

    @property
    def active(self) -> bool:
        return self.arm_torque_rms > 0

    def scaled(self, factor: float) -> TorqueDisturbance:
        """The same spectrum's shape at ``factor`` times the level."""
        ci = None if self.ci is None else [factor * v for v in self.ci]
        return TorqueDisturbance(factor * self.arm_torque_rms, self.spectrum, self.bandwidth_hz, ci)

    def samples(self, count: int, period: float, seed: int) -> np.ndarray:
        """``count`` samples [N m], one per ``period`` [s], of a seeded Gaussian draw with this spectrum's shape at
        exactly ``arm_torque_rms``: white noise shaped in frequency by the square root of the PSD."""
        if not self.active:
            return np.zeros(count)
        rng = np.random.default_rng([seed, 23])
        white = np.fft.rfft(rng.standard_normal(count))
        table = np.asarray(self.spectrum, dtype=float)
        frequencies = np.fft.rfftfreq(count, period)
        psd = np.interp(frequencies, table[:, 0], table[:, 1], left=0.0, right=0.0)
        shaped = np.fft.irfft(white * np.sqrt(psd), count)
        size = float(np.sqrt(np.mean(shaped**2)))
        return shaped * (self.arm_torque_rms / size) if size > 0 else shaped

    def trajectory(self, duration: float, period: float, seed: int) -> PiecewisePolynomial:
        """A seeded draw (:meth:`samples`) over ``duration`` [s] as a zero-order-hold trajectory at ``period``."""
        times = np.arange(0.0, duration + 2 * period, period)
        return PiecewisePolynomial.ZeroOrderHold(times, self.samples(times.size, period, seed).reshape(1, -1))


def bandwidth(frequencies: np.ndarray, psd: np.ndarray, share: float = 0.9) -> float:
    """The frequency [Hz] below which ``share`` of the power of a one-sided ``psd`` lies (0 without power)."""
    cumulative = np.cumsum(psd)
    if cumulative.size == 0 or cumulative[-1] <= 0:
        return 0.0
    return float(frequencies[int(np.searchsorted(cumulative, share * cumulative[-1]))])
