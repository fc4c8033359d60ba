"""Figures of merit of the paper's experiments (Tables I-II, Figs. 5-7), computed from a run's tape."""

from __future__ import annotations

import numpy as np
from scipy.signal import butter, filtfilt


def butterworth_velocity_reference(
    measured: np.ndarray, sample_period: float, cutoff_hz: float = 5.0, order: int = 2
) -> np.ndarray:
    """Table II's reference velocity: the encoder angles' finite-difference derivative filtered forward and
    backward (zero phase, paper ref. [13]) by a Butterworth low-pass of ``cutoff_hz``.

    ``measured`` is (n, k) angles [rad]; returns (n, k) velocities [rad/s]. The paper does not state the
    order; 2 (4 after the forward-backward pass) is the usual choice.
    """
    derivative = np.gradient(measured, sample_period, axis=0)
    b, a = butter(order, cutoff_hz, btype="low", fs=1.0 / sample_period)
    return filtfilt(b, a, derivative, axis=0, padtype="odd", padlen=min(3 * max(len(a), len(b)), measured.shape[0] - 1))


def squared_error_statistics(error: np.ndarray) -> dict[str, float]:
    """Mean and standard deviation of the squared error, as the paper's Tables I-II report them."""
    squared = np.asarray(error) ** 2
    return {"mean": float(np.mean(squared)), "std": float(np.std(squared))}


def steady_phases(velocity: np.ndarray, threshold: float, min_samples: int) -> dict[int, np.ndarray]:
    """Boolean masks of the samples in steady sliding phases: |v| above ``threshold`` with the same sign for
    at least ``min_samples`` consecutive samples, split by the sign of v (+1, -1); the first half of each phase
    is dropped so that the friction and its estimates have settled (Figs. 5 and 7 read steady values)."""
    sign = np.where(velocity > threshold, 1, np.where(velocity < -threshold, -1, 0))
    masks = {1: np.zeros(velocity.shape, bool), -1: np.zeros(velocity.shape, bool)}
    start = 0
    for i in range(1, sign.size + 1):
        if i == sign.size or sign[i] != sign[start]:
            if sign[start] != 0 and i - start >= min_samples:
                masks[int(sign[start])][start + (i - start) // 2 : i] = True
            start = i
    return masks


def observer_figures(result, start_time: float) -> dict[str, float]:
    """The VFE run's figures of merit after ``start_time`` [s]: mean squared velocity errors of the VFE estimate
    [(rad/s)^2], control errors (mean theta^2, phi^2 [rad^2]) and the RMS errors of the arm friction estimate
    F_hat and of F_hat + eps_hat_F against the true arm friction [N m]."""
    keep = result.time >= start_time
    error = result.estimates["vfe"][keep, 2:] - result.state[keep, 2:]
    true_arm = result.true_friction[keep, 1]
    f_hat = result.signals["friction_estimate"][keep, 0]
    eps = result.signals["friction_error_estimate"][keep, 1]
    return {
        "theta_dot_mse": float(np.mean(error[:, 0] ** 2)),
        "phi_dot_mse": float(np.mean(error[:, 1] ** 2)),
        "theta_sq": float(np.mean(result.state[keep, 0] ** 2)),
        "phi_sq": float(np.mean(result.state[keep, 1] ** 2)),
        "F_hat_rms_error": float(np.sqrt(np.mean((f_hat - true_arm) ** 2))),
        "F_hat_plus_eps_rms_error": float(np.sqrt(np.mean((f_hat + eps - true_arm) ** 2))),
    }
