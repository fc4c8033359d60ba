"""Incremental encoders on the two joints: the only measurements of the rig (paper Sec. II, y = [theta, phi]).

The encoder samples the true angles every control period and holds the sample, quantised to whole counts:
the staircase y(t) = q round((angle(t_k) + n_k) / q) for t in [t_k, t_k+1), q = 2 pi / counts_per_rev, with
optional white Gaussian noise n_k (the ``measurement_noise`` effect of the diagnosis vocabulary) added before
the quantisation. Angles are not wrapped: an incremental encoder counts turns.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import LeafSystem

from furuta_drake.errors import ConfigError, require_control_period
from furuta_drake.rig import _require_nonnegative, _require_positive, encoder_resolution


@dataclass
class EncoderParameters:
    """Resolution and noise of the two joint encoders; they sample at the control period."""

    counts_per_rev: int = 4096  # [counts/rev]; one count is 2 pi / counts_per_rev [rad]
    sample_period: float | None = None  # [s] optional: a stated sample period must equal the control period
    noise_std: float = 0.0  # [rad] white Gaussian noise added to each sample before quantisation
    seed: int = 0  # selects the noise sequence

    def validate(self, where: str = "encoder") -> None:
        counts = self.counts_per_rev
        if (
            isinstance(counts, bool)
            or not isinstance(counts, (int, float))
            or not math.isfinite(counts)
            or int(counts) != counts
            or counts < 4
        ):
            raise ConfigError(f"{where}.counts_per_rev must be an integer >= 4, got {counts!r}")
        if self.sample_period is not None:
            _require_positive(self.sample_period, f"{where}.sample_period")
        _require_nonnegative(self.noise_std, f"{where}.noise_std")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or self.seed < 0:
            raise ConfigError(f"{where}.seed must be a non-negative integer, got {self.seed!r}")

    @property
    def encoder_resolution(self) -> float:
        """One count [rad]."""
        return encoder_resolution(self.counts_per_rev)


class Encoder(LeafSystem):
    """Sampled, quantised (and optionally noisy) measurement of theta and phi.

    Input ``true_state``: the paper's x = [theta, phi, theta_dot, phi_dot]. Output ``measured_angles_rad``:
    [theta, phi] sampled by a periodic discrete update at the control period ``period`` [s] and held, rounded to
    the nearest count (error within half a count when noise_std = 0). An initialization event takes a first
    sample, so the output is a measurement of the initial state from the start, before the periodic sample at t = 0. The
    output is the discrete state: the encoder has no direct feedthrough.

    Noise is counter-based: the noise of sample k is a pure function of (seed, k), drawn in blocks of
    ``NOISE_BLOCK`` samples from ``numpy.random.default_rng([seed, k // NOISE_BLOCK])``, and the context holds
    only the sample counter k. So the same seed gives the same measurements in every fresh simulation and in
    every cloned context, independently of ``Diagram.SetRandomContext`` and of the other random blocks of the
    diagram. The alternatives cost more or lose the seed: a numpy ``Generator`` in abstract state is deep-copied
    by every unrestricted update (an order of magnitude slower per sample), and Drake's ``RandomSource`` takes its
    seed from the diagram's random context, not from this encoder's ``seed``.
    """

    NOISE_BLOCK = 4096  # samples of noise drawn at once

    def __init__(self, params: EncoderParameters, *, period: float):
        super().__init__()
        params.validate()
        _require_positive(period, "Encoder period")
        require_control_period(params.sample_period, period, "encoder.sample_period")
        self._resolution = params.encoder_resolution
        self._noise_std = float(params.noise_std)
        self._seed = int(params.seed)
        self._block = (-1, None)  # (block index, noise samples): a memo of the pure function _noise_block
        self._state_port = self.DeclareVectorInputPort("true_state", 4)
        self._measured = self.DeclareDiscreteState(2)
        if self._noise_std > 0:
            self._counter = self.DeclareDiscreteState(1)
            update = self._sample_with_noise
        else:
            update = self._sample
        self.DeclareInitializationDiscreteUpdateEvent(update)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, update)
        self.DeclareStateOutputPort("measured_angles_rad", self._measured)

    def _write(self, discrete_state, theta: float, phi: float) -> None:
        """Quantise into the state: Python's round() rounds half to even like numpy's, on floats, written
        through the state's array view (no array built per sample)."""
        q = self._resolution
        measured = discrete_state.get_mutable_value(self._measured)
        measured[0], measured[1] = q * round(theta / q), q * round(phi / q)

    def _sample(self, context, discrete_state):
        x = self._state_port.Eval(context).tolist()
        self._write(discrete_state, x[0], x[1])

    def _sample_with_noise(self, context, discrete_state):
        x = self._state_port.Eval(context).tolist()
        k = int(context.get_discrete_state(self._counter).GetAtIndex(0))
        block, offset = divmod(k, self.NOISE_BLOCK)
        if self._block[0] != block:
            self._block = (block, self._noise_block(block).tolist())
        noise = self._block[1][offset]
        self._write(discrete_state, x[0] + noise[0], x[1] + noise[1])
        discrete_state.get_mutable_vector(self._counter).SetAtIndex(0, k + 1)

    def _noise_block(self, block: int) -> np.ndarray:
        """Noise of samples block * NOISE_BLOCK ... (block + 1) * NOISE_BLOCK - 1, shape (NOISE_BLOCK, 2)."""
        rng = np.random.default_rng([self._seed, block])
        return self._noise_std * rng.standard_normal((self.NOISE_BLOCK, 2))


__all__ = ["EncoderParameters", "Encoder"]
