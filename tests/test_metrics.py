"""Figures of merit: the Table II Butterworth reference and the steady-phase masks of Figs. 5 and 7."""

import numpy as np
import pytest

from furuta_drake.paper.metrics import butterworth_velocity_reference, squared_error_statistics, steady_phases


def test_butterworth_reference_recovers_a_slow_velocity_without_phase_lag():
    """A 1 Hz motion is far below the 5 Hz cut-off: zero-phase filtering passes it with gain
    1/(1 + (1/5)^4) (a 2nd-order Butterworth applied twice) and no delay."""
    T = 1e-3
    t = np.arange(0, 10, T)
    angle = 0.2 * np.sin(2 * np.pi * t)
    quantised = np.round(angle / (2 * np.pi / 4096)) * (2 * np.pi / 4096)
    reference = butterworth_velocity_reference(quantised[:, None], T)[:, 0]
    true_velocity = 0.2 * 2 * np.pi * np.cos(2 * np.pi * t)
    inner = slice(1000, -1000)
    gain = np.dot(reference[inner], true_velocity[inner]) / np.dot(true_velocity[inner], true_velocity[inner])
    assert gain == pytest.approx(1 / (1 + (1 / 5) ** 4), abs=3e-3)
    lag = np.argmax(np.correlate(reference[inner], true_velocity[inner], "full")) - (t[inner].size - 1)
    assert lag == 0


def test_butterworth_reference_rejects_quantisation_noise():
    """Differentiating 4096-count angles at 1 kHz gives +-1.5 rad/s spikes; the 5 Hz reference is smooth."""
    T = 1e-3
    t = np.arange(0, 5, T)
    res = 2 * np.pi / 4096
    quantised = np.round(0.3 * t / res) * res  # constant 0.3 rad/s
    raw = np.gradient(quantised, T)
    reference = butterworth_velocity_reference(quantised[:, None], T)[:, 0]
    assert np.std(raw) > 0.3
    assert np.std(reference[500:-500]) < 0.01
    assert np.mean(reference[500:-500]) == pytest.approx(0.3, rel=0.01)


def test_squared_error_statistics_of_a_constant_error():
    stats = squared_error_statistics(np.full(100, 0.1))
    assert stats["mean"] == pytest.approx(0.01)
    assert stats["std"] == pytest.approx(0.0, abs=1e-15)


def test_steady_phases_keep_the_settled_half_of_long_same_sign_phases():
    v = np.concatenate([np.full(100, 0.5), np.full(10, 0.0), np.full(100, -0.5), np.full(20, 0.5)])
    masks = steady_phases(v, threshold=0.1, min_samples=50)
    assert masks[1].sum() == 50 and masks[1][50:100].all()
    assert masks[-1].sum() == 50 and masks[-1][160:210].all()
    assert not masks[1][210:].any()  # the last phase is too short


def test_butterworth_reference_at_the_real_rigs_rate_passes_a_balancing_oscillation_with_zero_phase():
    """The real QUBE's setting (real_rig.runs): 2048-count angles at 250 Hz, the 25 Hz reference. An 8 Hz
    oscillation (the balancing loop's) is below the cut-off: gain sin(w T) / (w T) (the central difference) times
    1/(1 + (8/25)^4) (the double pass), and no lag."""
    from furuta_drake.real_rig.runs import REFERENCE_CUTOFF_HZ

    T, count = 0.004, 2 * np.pi / 2048
    t = np.arange(0, 10, T)
    omega = 2 * np.pi * 8.0
    quantised = np.round(0.05 * np.sin(omega * t) / count) * count
    reference = butterworth_velocity_reference(quantised[:, None], T, REFERENCE_CUTOFF_HZ)[:, 0]
    true_velocity = 0.05 * omega * np.cos(omega * t)
    inner = slice(250, -250)
    gain = np.dot(reference[inner], true_velocity[inner]) / np.dot(true_velocity[inner], true_velocity[inner])
    assert gain == pytest.approx(np.sin(omega * T) / (omega * T) / (1 + (8 / REFERENCE_CUTOFF_HZ) ** 4), abs=2e-3)
    lag = np.argmax(np.correlate(reference[inner], true_velocity[inner], "full")) - (t[inner].size - 1)
    assert lag == 0
    residual = reference[inner] - gain * true_velocity[inner]
    assert np.sqrt(np.mean(residual**2)) < 0.02 * np.sqrt(np.mean(true_velocity[inner] ** 2))
