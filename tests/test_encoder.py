"""The encoder: quantisation to whole counts, sample-and-hold at the sample period, seeded white noise."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from furuta_drake.encoder import Encoder, EncoderParameters
from furuta_drake.errors import ConfigError
from furuta_drake.rig import encoder_resolution


def measured_after_first_sample(encoder, x):
    context = encoder.CreateDefaultContext()
    encoder.GetInputPort("true_state").FixValue(context, x)
    context.SetDiscreteState(encoder.EvalUniquePeriodicDiscreteUpdate(context))
    return encoder.GetOutputPort("measured_angles_rad").Eval(context)


@settings(max_examples=25, deadline=None)
@given(theta=st.floats(-50.0, 50.0), phi=st.floats(-50.0, 50.0), counts=st.sampled_from([4, 500, 2048, 4096, 10000]))
def test_measurement_is_a_whole_count_within_half_a_count_of_the_angle(theta, phi, counts):
    encoder = Encoder(EncoderParameters(counts_per_rev=counts), period=1e-3)
    y = measured_after_first_sample(encoder, [theta, phi, 3.0, -2.0])
    count = encoder_resolution(counts)
    np.testing.assert_allclose(y / count, np.round(y / count), atol=1e-9)
    assert np.all(np.abs(y - [theta, phi]) <= count / 2 * (1 + 1e-9))


def ramp_run(params, period, duration, log_period, slope=(10.0, -7.0), seed_context=None):
    """Encoder sampling at ``period`` on a ramp x(t) = [0.3 + slope_theta t, -1 + slope_phi t]; returns the log's
    times and values."""
    builder = DiagramBuilder()
    start, end = np.array([0.3, -1.0, 0, 0]), np.array([0.3, -1.0, 0, 0])
    end[:2] += duration * np.asarray(slope)
    source = builder.AddSystem(
        TrajectorySource(PiecewisePolynomial.FirstOrderHold([0.0, duration], np.column_stack([start, end])))
    )
    encoder = builder.AddSystem(Encoder(params, period=period))
    builder.Connect(source.get_output_port(), encoder.GetInputPort("true_state"))
    logger = LogVectorOutput(encoder.GetOutputPort("measured_angles_rad"), builder, publish_period=log_period)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    if seed_context is not None:
        diagram.SetRandomContext(simulator.get_mutable_context(), RandomGenerator(seed_context))
    simulator.AdvanceTo(duration)
    log = logger.FindLog(simulator.get_context())
    return log.sample_times(), log.data().T, start[:2], np.asarray(slope)


def test_output_is_the_sample_held_for_exactly_one_period():
    period = 4e-3
    params = EncoderParameters(counts_per_rev=4096)
    count = params.encoder_resolution
    times, y, start, slope = ramp_run(params, period, duration=0.1, log_period=period / 8)
    counts = np.round(y / count)
    # Between samples (t_k, t_k+1) the output is the count of the angle at t_k; at t_k itself Drake shows the
    # value before that instant's update, i.e. still the previous sample.
    sample_index = np.ceil(times / period - 1e-9) - 1
    sample_index[0] = 0
    expected = np.round((start + np.outer(sample_index * period, slope)) / count)
    np.testing.assert_array_equal(counts, expected)
    # The ramp moves 26 or 27 counts per period on theta: the output steps exactly once per period.
    steps = np.flatnonzero(np.any(np.diff(counts, axis=0) != 0, axis=1))
    step_times = times[steps + 1]
    np.testing.assert_allclose(step_times - period / 8, period * np.arange(1, len(step_times) + 1), atol=1e-12)


def test_noise_has_the_requested_std_is_white_and_is_reproducible_by_seed():
    sigma, period, duration = 0.01, 1e-3, 5.0
    params = EncoderParameters(counts_per_rev=4096, noise_std=sigma, seed=3)
    times, y, start, slope = ramp_run(params, period, duration, period)
    # Row j (j >= 1) holds the sample taken at t_{j-1}; 5000 samples cross a noise block of 4096.
    error = y[1:] - (start + np.outer(times[:-1], slope))
    # Noise plus uniform quantisation of a moving angle: variance sigma^2 + q^2 / 12.
    expected_std = math.sqrt(sigma**2 + params.encoder_resolution**2 / 12)
    n = len(error)
    for column in error.T:
        assert abs(np.mean(column)) < 4 * sigma / math.sqrt(n)
        assert np.std(column) == pytest.approx(expected_std, rel=4 / math.sqrt(2 * n))
        assert abs(np.corrcoef(column[:-1], column[1:])[0, 1]) < 4 / math.sqrt(n)
    assert abs(np.corrcoef(error[:, 0], error[:, 1])[0, 1]) < 4 / math.sqrt(n)

    _, again, _, _ = ramp_run(params, period, duration, period, seed_context=12345)
    np.testing.assert_array_equal(again, y)
    _, other_seed, _, _ = ramp_run(EncoderParameters(noise_std=sigma, seed=4), period, duration, period)
    assert np.mean(other_seed == y) < 0.5


@pytest.mark.parametrize(
    "field, value",
    [
        ("counts_per_rev", 3),
        ("counts_per_rev", 100.5),
        ("counts_per_rev", math.inf),
        ("sample_period", 0.0),
        ("sample_period", math.nan),
        ("noise_std", -0.1),
        ("noise_std", math.inf),
        ("seed", -1),
        ("seed", 1.5),
    ],
)
def test_non_physical_parameters_are_rejected_with_the_field_named(field, value):
    with pytest.raises(ConfigError, match=f"encoder.{field}"):
        Encoder(EncoderParameters(**{field: value}), period=1e-3)


def test_a_stated_sample_period_must_be_the_control_period():
    with pytest.raises(ConfigError, match=r"encoder.sample_period = 0.001 differs from the control period = 0.002"):
        Encoder(EncoderParameters(sample_period=1e-3), period=2e-3)
