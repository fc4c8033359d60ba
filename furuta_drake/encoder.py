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
from pydrake import symbolic
from pydrake.symbolic import MakeVectorVariable
from pydrake.systems.framework import Diagram, DiagramBuilder, LeafSystem

from furuta_drake.errors import ConfigError, require_control_period
from furuta_drake.rig import _require_nonnegative, _require_positive, encoder_resolution
from furuta_drake.symbolic_system import discrete_symbolic_system, export_ports, is_symbolic, where


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


class Encoder(Diagram):
    """Sampled, quantised (and optionally noisy) measurement of theta and phi.

    Input ``true_state``: the paper's x = [theta, phi, theta_dot, phi_dot]. Output ``measured_angles_rad``:
    [theta, phi] sampled at the control period ``period`` [s] and held, rounded to the nearest count, half to even
    (error within half a count when noise_std = 0). A first sample is taken when the simulation initializes, so the
    output is a measurement of the initial state from the start, before the periodic sample at t = 0. The output
    depends on the samples alone: the encoder has no direct feedthrough.

    Without noise the periodic sample is a C++ system (:func:`~furuta_drake.symbolic_system.discrete_symbolic_system`
    with state [theta, phi, sampled]: the output is the initialization sample until the first periodic one); the
    initialization sample is a Python system called once per run (Drake's C++ blocks have no initialization event).
    With noise the sampler is :class:`NoisyEncoderSampler`, a Python system: its numpy noise sequence is not a
    symbolic expression.
    """

    def __init__(self, params: EncoderParameters, *, period: float):
        Diagram.__init__(self)
        params.validate()
        _require_positive(period, "Encoder period")
        require_control_period(params.sample_period, period, "encoder.sample_period")
        builder = DiagramBuilder()
        if params.noise_std > 0:
            sampler = builder.AddNamedSystem("noisy_sampler", NoisyEncoderSampler(params, period=period))
            export_ports(builder, sampler)
        else:
            first = builder.AddNamedSystem("first_sample", InitialSample(params.encoder_resolution))
            periodic = builder.AddNamedSystem("sampler", periodic_sampler(params.encoder_resolution, period))
            builder.ExportInput(first.GetInputPort("true_state"), "true_state")
            builder.ConnectInput("true_state", periodic.GetInputPort("true_state"))
            builder.Connect(first.GetOutputPort("first_sample_rad"), periodic.GetInputPort("first_sample_rad"))
            builder.ExportOutput(periodic.GetOutputPort("measured_angles_rad"), "measured_angles_rad")
        builder.BuildInto(self)


def quantise(angle, resolution: float):
    """``angle`` [rad] rounded to whole counts of ``resolution`` [rad], half to even (Python's round): a float, or
    the symbolic expression of it (floor and comparisons, exact for |angle / resolution| < 2^52)."""
    if not is_symbolic(angle):
        return resolution * round(angle / resolution)
    counts = angle / resolution
    below = symbolic.floor(counts)
    fraction = counts - below
    to_even = 2.0 * below - 2.0 * symbolic.floor(below / 2.0)  # below, or below + 1 if below is odd
    return resolution * where(fraction > 0.5, below + 1.0, where(fraction < 0.5, below, to_even))


def periodic_sampler(resolution: float, period: float):
    """The noiseless periodic sample as a C++ system: state [theta, phi, sampled], inputs ``true_state`` and
    ``first_sample_rad``, output ``measured_angles_rad`` (the first sample until ``sampled``)."""
    x = list(MakeVectorVariable(4, "true_state"))
    first = list(MakeVectorVariable(2, "first_sample"))
    held = list(MakeVectorVariable(3, "sample"))
    sampled = held[2] > 0.5
    return discrete_symbolic_system(
        name="encoder_law",
        period=period,
        state=held,
        initial=[0.0, 0.0, 0.0],
        update=[quantise(x[0], resolution), quantise(x[1], resolution), 1.0],
        inputs=[("true_state", x), ("first_sample_rad", first)],
        # The held sample is re-quantised: the wrapper's update leaves it within an ulp of the count.
        outputs=[("measured_angles_rad", [where(sampled, quantise(held[i], resolution), first[i]) for i in range(2)])],
    )


class InitialSample(LeafSystem):
    """The encoder's sample at initialization: input ``true_state``, output ``first_sample_rad`` ([theta, phi]
    rounded to whole counts of ``resolution`` [rad], taken by an initialization event)."""

    def __init__(self, resolution: float):
        super().__init__()
        self._resolution = resolution
        self._state_port = self.DeclareVectorInputPort("true_state", 4)
        sample = self.DeclareDiscreteState(2)
        self.DeclareInitializationDiscreteUpdateEvent(self._sample)
        self.DeclareStateOutputPort("first_sample_rad", sample)

    def _sample(self, context, discrete_state):
        theta, phi = self._state_port.Eval(context)[:2]
        discrete_state.get_mutable_vector(0).SetFromVector(
            [quantise(float(theta), self._resolution), quantise(float(phi), self._resolution)]
        )


class NoisyEncoderSampler(LeafSystem):
    """The encoder with white Gaussian noise added before the quantisation: input ``true_state``, output
    ``measured_angles_rad``, sampled by an initialization event and a periodic discrete update at ``period`` [s].

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
        self._resolution = params.encoder_resolution
        self._noise_std = float(params.noise_std)
        self._seed = int(params.seed)
        self._block = (-1, None)  # (block index, noise samples): a memo of the pure function _noise_block
        self._state_port = self.DeclareVectorInputPort("true_state", 4)
        self._measured = self.DeclareDiscreteState(2)
        self._counter = self.DeclareDiscreteState(1)
        self.DeclareInitializationDiscreteUpdateEvent(self._sample)
        self.DeclarePeriodicDiscreteUpdateEvent(period, 0.0, self._sample)
        self.DeclareStateOutputPort("measured_angles_rad", self._measured)

    def _sample(self, context, discrete_state):
        x = self._state_port.Eval(context).tolist()
        k = int(context.get_discrete_state(self._counter).GetAtIndex(0))
        block, offset = divmod(k, self.NOISE_BLOCK)
        if self._block[0] != block:
            self._block = (block, self._noise_block(block).tolist())
        noise = self._block[1][offset]
        measured = discrete_state.get_mutable_value(self._measured)
        measured[0] = quantise(x[0] + noise[0], self._resolution)
        measured[1] = quantise(x[1] + noise[1], self._resolution)
        discrete_state.get_mutable_vector(self._counter).SetAtIndex(0, k + 1)

    def _noise_block(self, block: int) -> np.ndarray:
        """Noise of samples block * NOISE_BLOCK ... (block + 1) * NOISE_BLOCK - 1, shape (NOISE_BLOCK, 2)."""
        rng = np.random.default_rng([self._seed, block])
        return self._noise_std * rng.standard_normal((self.NOISE_BLOCK, 2))


__all__ = ["EncoderParameters", "Encoder", "InitialSample", "NoisyEncoderSampler", "periodic_sampler", "quantise"]
