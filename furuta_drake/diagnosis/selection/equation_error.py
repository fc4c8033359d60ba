"""Starts for the fits from the equations of motion: the train logs' smoothed accelerations regressed on the
effects' regressors (an equation-error fit), so that a fit can start where a large error lies (a drive gain well
below 1, damping several times the back-EMF's, a strong restoring torque) rather than only from starts spread
over each parameter's range.

In the four lumped constants a, b, c, d of the rig file (:mod:`~furuta_drake.effects.surrogate`), with s = sin
theta and co = cos theta,

    b theta'' + c co phi'' - b s co phi'^2 - d s                              = tau_theta
    c co theta'' + (a + b s^2) phi'' - c s theta'^2 + 2 b s co theta' phi'   = tau_phi

and tau_phi = g u(t - D) - (k_emf + F_v) phi' - F_c tanh(phi' / v_s) - k (phi - phi_0) beside the rig file's own
friction, tau_theta = -F_cp tanh(theta' / v_s) - F_vp theta'. Both sides are linear in (g, F_v, F_c, k, k phi_0)
and (F_cp, F_vp): they are regressed jointly, with bounds, at every whole-sample delay D up to ``DELAY_SCAN``
samples, the delay of least residual kept. (The scales of a, b, c and d would multiply the noisy accelerations
themselves, which biases their regression towards zero: an inertia error starts from the rig file's values.) The
accelerations are the angles' lag-L second differences, (y_(k+L) - 2 y_k + y_(k-L)) / (L T)^2:
where the command is held over each sample, that is exactly a tent-weighted mean of the accelerations over the 2 L
samples around k (a bang-bang command that switches every few samples leaves no smooth stretch to differentiate),
so every regressor is averaged with the same tent; L spans about ``SMOOTHING_S`` / 2, which keeps the encoder's
rounding (and, in a closed loop, the command's share of it) small beside the motion. The angles and rates in the
regressors come from a Savitzky-Golay smoother.
"""

from __future__ import annotations

import numpy as np
from scipy.optimize import lsq_linear
from scipy.signal import savgol_filter

from furuta_drake.effects.surrogate import REGULARIZATION_VELOCITY, Model
from furuta_drake.effects.vocabulary import CANDIDATES

SMOOTHING_S = 0.03  # Savitzky-Golay window [s]
DELAY_SCAN = 6  # whole-sample delays tried
STRIDE_SAMPLES = 4  # with a lag of at least this many samples, every STRIDE_SAMPLES-th sample is regressed


def tent(lag: int) -> np.ndarray:
    """The weights (2 lag,) of the accelerations held over the samples k - lag .. k + lag - 1 in the lag-``lag``
    second difference at k, over (lag T)^2: they sum to 1 (module docstring)."""
    ramp = lambda m: np.maximum(m - 0.5, 0.0) * (m > 0)  # noqa: E731  the response to a unit held acceleration
    i = np.arange(-lag, lag)
    return (ramp(lag - i) - 2.0 * ramp(-i) + ramp(-lag - i)) / lag**2


def second_difference(angles: np.ndarray, lag: int, period: float) -> np.ndarray:
    """The lag-``lag`` second difference of each row of ``angles`` over (lag T)^2 (zero at the ends)."""
    out = np.zeros_like(angles)
    out[:, lag:-lag] = (angles[:, 2 * lag :] - 2.0 * angles[:, lag:-lag] + angles[:, : -2 * lag]) / (lag * period) ** 2
    return out


def tent_averaged(values: np.ndarray, weights: np.ndarray) -> np.ndarray:
    """``values`` held over each sample, tent-averaged about every sample (the ends padded with the end values)."""
    lag = weights.size // 2
    padded = np.concatenate([np.full(lag, values[0]), values, np.full(lag, values[-1])])
    return np.convolve(padded, weights[::-1], mode="valid")[: values.size]


def _derivatives(log):
    """(kept samples, angles (2, n), rates (2, n), accelerations (2, n), the tent) of a log: the angles and rates
    smoothed, the accelerations the raw angles' lag-L second differences (module docstring); the ends left out."""
    period = log.sample_period
    window = max(7, int(round(SMOOTHING_S / period)) | 1)
    lag = max(1, int(round(SMOOTHING_S / (2.0 * period))))
    angles = np.vstack([log.theta, log.phi])
    if angles.shape[1] <= max(window, 2 * lag + 1):
        return None
    smooth = [savgol_filter(angles, window, 3, deriv=k, delta=period, axis=1) for k in range(2)]
    acceleration = second_difference(angles, lag, period)
    keep = np.zeros(angles.shape[1], dtype=bool)
    edge = max(lag, window // 2)
    keep[edge : -edge : STRIDE_SAMPLES if lag >= STRIDE_SAMPLES else 1] = True  # the tent smooths over 2 lag samples
    return keep, *smooth, acceleration, tent(lag)


def _sides(model: Model, log, parts):
    """Per kept sample: the left sides of both equations with the rig file's constants, their parts per constant
    (for the scales), and the state."""
    keep, q, v, acc, _ = parts
    th, ph = q
    thd, phd = v
    thdd, phdd = acc
    s, co = np.sin(th), np.cos(th)
    a, b, c, d = model.arm_inertia_total, model.pendulum_inertia_total, model.coupling, model.gravity_torque
    per_constant = {  # (pendulum, arm) left-side parts of a, b, c, d (each times its constant)
        "a": (np.zeros_like(th), a * phdd),
        "b": (b * (thdd - s * co * phd**2), b * (s * s * phdd + 2 * s * co * thd * phd)),
        "c": (c * co * phdd, c * (co * thdd - s * thd**2)),
        "d": (-d * s, np.zeros_like(th)),
    }
    return keep, per_constant, (th, ph, thd, phd)


def _rig_torques(model: Model, thd, phd):
    """The rig file's own joint torques beside the command: its friction laws and the back-EMF."""
    from furuta_drake.friction import static_friction_torque

    arm = static_friction_torque(phd, model.arm_friction) - model.back_emf_damping * phd
    pendulum = static_friction_torque(thd, model.pendulum_friction)
    return pendulum, arm


def equation_error_starts(logs, model: Model) -> dict[str, dict[str, float]]:
    """The regressed starts, per vocabulary effect its parameters by name (module docstring):
    ``torque_gain_error`` (gain), ``arm_viscous_friction`` (viscous), ``arm_coulomb_friction`` (coulomb),
    ``arm_spring`` (stiffness, equilibrium), ``pendulum_friction`` (coulomb, viscous) and ``input_delay`` (delay).
    Empty when the logs hold too few usable samples."""
    rows = [(log, _derivatives(log)) for log in logs]
    rows = [(log, parts) for log, parts in rows if parts is not None and parts[0].sum() > 20]
    if not rows:
        return {}
    best = None
    for delay in range(DELAY_SCAN + 1):
        fit = _linear_fit(model, rows, delay)
        if fit is not None and (best is None or fit[0] < best[1]):
            best = (delay, *fit)
    if best is None:
        return {}
    delay, cost, (gain, viscous, coulomb, stiffness, offset, pend_coulomb, pend_viscous) = best
    period = float(np.median([log.sample_period for log, _ in rows]))
    out = {
        "torque_gain_error": (gain,),
        "arm_viscous_friction": (viscous + model.arm_friction.viscous,),
        "arm_coulomb_friction": (coulomb,),
        "pendulum_friction": (pend_coulomb, pend_viscous),
        "input_delay": (delay * period,),
    }
    if stiffness > 0:
        out["arm_spring"] = (stiffness, float(np.clip(offset / stiffness, -1.0, 1.0)))
    return {name: dict(zip(CANDIDATES[name].params, values)) for name, values in out.items()}


def _stacked(model: Model, rows, delay: int):
    """Per log the kept samples' equation parts: (per-constant left sides, rig torques, delayed command, state)."""
    out = []
    for log, parts in rows:
        keep, per_constant, (th, ph, thd, phd) = _sides(model, log, parts)
        weights = parts[-1]
        command = log.torque_command
        delayed = tent_averaged(np.concatenate([np.full(delay, command[0]), command[: command.size - delay]]), weights)
        pendulum, arm = (tent_averaged(torque, weights) for torque in _rig_torques(model, thd, phd))
        state = tuple(tent_averaged(x, weights) for x in (th, ph, thd, phd))
        out.append((keep, per_constant, (pendulum, arm), delayed, state))
    return out


def _linear_fit(model: Model, rows, delay: int):
    """(cost, parameters) of the joint regression at one delay (module docstring), or None."""
    A, y = [], []
    for keep, per_constant, (pend_rig, arm_rig), u, (_, ph, thd, phd) in _stacked(model, rows, delay):
        lhs_p = sum(part[0] for part in per_constant.values()) - pend_rig
        lhs_a = sum(part[1] for part in per_constant.values()) - arm_rig
        k, zeros = keep, np.zeros(keep.sum())
        sign_a, sign_p = np.tanh(phd[k] / REGULARIZATION_VELOCITY), np.tanh(thd[k] / REGULARIZATION_VELOCITY)
        # columns: gain, viscous, coulomb, stiffness, stiffness x equilibrium, pendulum coulomb, pendulum viscous
        A.append(np.column_stack([u[k], -phd[k], -sign_a, -ph[k], np.ones(k.sum()), zeros, zeros]))
        y.append(lhs_a[k])
        A.append(np.column_stack([zeros, zeros, zeros, zeros, zeros, -sign_p, -thd[k]]))
        y.append(lhs_p[k])
    A, y = np.vstack(A), np.concatenate(y)
    scale = np.maximum(np.sqrt(np.mean(A**2, axis=0)), 1e-300)
    low = np.array([0.2, 0.0, 0.0, 0.0, -np.inf, 0.0, 0.0]) * scale
    high = np.array([5.0, np.inf, np.inf, np.inf, np.inf, np.inf, np.inf]) * scale
    result = lsq_linear(A / scale, y, bounds=(low, high))
    if not result.success:
        return None
    return float(np.sum(result.fun**2)), tuple(float(v) for v in result.x / scale)
