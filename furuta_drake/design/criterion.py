"""How well an experiment separates two hypotheses, measured the way the diagnosis measures the gap.

The experiment's log under the true hypothesis T is cut into a train half and a held-out half, and each half into
the diagnosis' k-step windows (:func:`~furuta_drake.diagnosis.gap.metric.make_windows`). The rival model R is judged as
the diagnosis would judge it: its parameters are fitted again on the train half (Gauss-Newton steps of the
k-step residuals, the initial states of every window re-projected for every parameter vector, Kaufman's
projected Jacobian as in :mod:`furuta_drake.diagnosis.selection.fit`), and its residuals on the held-out half come from
states refined per window (:func:`~furuta_drake.diagnosis.gap.metric.projected_residuals`). What a refit or the initial
states can absorb is no evidence and counts for nothing.

The criterion is the expected log-likelihood ratio of the held-out half under the truth's own sensor noise (its
encoder's rounding, count^2 / 12, and white noise), the noncentrality

    lambda(T, R) = sum over held-out windows, samples k >= 1 and both angles of r_R^2 / sigma_T^2

with r_R the rival's noise-free residual [counts of the rig file's encoder]. It is 0 for identical models and
grows with the square of an effect's size. The optimiser's cheap form takes one linearised refit step and
predicts the held-out residual linearly (:func:`linearised_noncentrality`); the final design is checked with
iterated steps and exact held-out residuals (:func:`refit_residuals`).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from furuta_drake.design.torque_hypothesis import TORQUE, apply_hypothesis, torque_bounds
from furuta_drake.diagnosis.gap.metric import (
    Windows,
    fixed_state_residuals,
    make_windows,
    project_out_states,
    projected_residuals,
)
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.effects.surrogate import Model, sensor_variance
from furuta_drake.effects.vocabulary import CANDIDATES, Effect, Scales
from furuta_drake.rig import RigParameters

JACOBIAN_STEP = 1e-3  # relative finite-difference step of the parameter sensitivities
RIDGE = 1e-8  # relative Tikhonov damping of the refit's normal equations (directions the data do not see)


@dataclass(frozen=True)
class Parametrised:
    """A hypothesis as a function of its fitted parameters (every parameter of its fitted effects, in order; the
    unmodelled torque's coefficients among them)."""

    nominal: Model
    effects: dict[str, Effect]
    scales: Scales

    @property
    def fitted(self) -> list[str]:
        return [name for name in self.effects if name == TORQUE or CANDIDATES[name].fit]

    @property
    def x0(self) -> np.ndarray:
        return np.array([v for name in self.fitted for v in self.effects[name].values])

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        low, high = [], []
        for name in self.fitted:
            effect = self.effects[name]
            lo, hi = torque_bounds(effect) if name == TORQUE else CANDIDATES[name].form(effect.form).bounds(self.scales)
            low, high = low + lo, high + hi
        return np.array(low), np.array(high)

    def model(self, x: np.ndarray) -> Model:
        effects, i = dict(self.effects), 0
        for name in self.fitted:
            size = len(self.effects[name].values)
            effects[name] = Effect(self.effects[name].form, tuple(x[i : i + size]))
            i += size
        return apply_hypothesis(self.nominal, effects)


def experiment_windows(
    angles: np.ndarray, commands: np.ndarray, period: float, rig: RigParameters
) -> tuple[Windows, Windows]:
    """(train, held-out) windows of D experiment logs: ``angles`` (N, 2, D) [rad], ``commands`` (D, N) [N m];
    each log is cut in two halves, the first trains."""
    samples = commands.shape[1]
    half = samples // 2
    time = np.arange(samples) * period
    parts = ([], [])
    for d in range(commands.shape[0]):
        for logs, cut in zip(parts, (slice(0, half), slice(half, samples))):
            logs.append(
                RunLog(
                    name=f"experiment {d}",
                    path="",
                    time=time[cut],
                    theta=angles[cut, 0, d],
                    phi=angles[cut, 1, d],
                    input_kind="torque",
                    input=commands[d, cut],
                    sample_period=period,
                )
            )
    return make_windows(parts[0], rig), make_windows(parts[1], rig)


def _columns(
    param: Parametrised, x: np.ndarray, windows: Windows, raw, states, jacobians, counts: int
) -> list[np.ndarray]:
    """Per log (h, 2, W, P): the residuals' change per unit of each parameter at fixed initial states, with what
    the states can absorb projected out."""
    low, high = param.bounds()
    columns = []
    for i in range(x.size):
        step = JACOBIAN_STEP * max(abs(x[i]), (high[i] - low[i]) * 1e-3)
        step = -step if x[i] + step > high[i] else step
        shifted = x.copy()
        shifted[i] += step
        moved = fixed_state_residuals(param.model(shifted), windows, states, counts)
        columns.append(
            [project_out_states(np.nan_to_num(new - old), J) / step for new, old, J in zip(moved, raw, jacobians)]
        )
    return [np.stack([column[log] for column in columns], axis=-1) for log in range(len(raw))]


def _step(r: np.ndarray, C: np.ndarray) -> np.ndarray:
    """The Gauss-Newton step (P,) minimising |r + C step|^2 over rows k >= 1 of one log's windows."""
    A = C[1:].reshape(-1, C.shape[-1])
    b = np.nan_to_num(r[1:].ravel(), nan=1e6)
    scale = np.maximum(np.linalg.norm(A, axis=0), 1e-300)
    normal = (A / scale).T @ (A / scale)
    normal += RIDGE * np.trace(normal) * np.eye(normal.shape[0])
    return -np.linalg.solve(normal, (A / scale).T @ b) / scale


def linearised_noncentrality(
    param: Parametrised, train: Windows, heldout: Windows, counts: int, truth_variance: float
) -> np.ndarray:
    """(D,) lambda of the module docstring for the D logs of ``train`` and ``heldout``: one Gauss-Newton step of
    the rival ``param`` per log from its hypothesis' parameters, the held-out residual predicted linearly."""
    x0 = param.x0
    model = param.model(x0)
    r_train, s_train, j_train = projected_residuals(model, train, counts)
    r_held, s_held, j_held = projected_residuals(model, heldout, counts)
    if x0.size:
        low, high = param.bounds()
        c_train = _columns(param, x0, train, r_train, s_train, j_train, counts)
        c_held = _columns(param, x0, heldout, r_held, s_held, j_held, counts)
        steps = [np.clip(x0 + _step(r, C), low, high) - x0 for r, C in zip(r_train, c_train)]
        r_held = [r + C @ step for r, C, step in zip(r_held, c_held, steps)]
    return np.array([float(np.sum(np.nan_to_num(r[1:], nan=1e6) ** 2)) for r in r_held]) / truth_variance


@dataclass
class Refit:
    """A model refit on one experiment's train half and its residuals on the held-out half."""

    x: np.ndarray  # fitted parameters
    residuals: np.ndarray  # (h, 2, W) noise-free held-out residuals [counts]
    state_jacobians: np.ndarray  # (h, 2, W, n) their sensitivities to the windows' initial states
    variance: float  # the model's own sensor variance [counts^2]


def refit_residuals(param: Parametrised, train: Windows, heldout: Windows, counts: int, iterations: int) -> Refit:
    """``param`` refit on the single log of ``train`` (``iterations`` projected Gauss-Newton steps, each kept
    only when the train cost falls) and its exact residuals on ``heldout``."""
    x = param.x0
    if x.size:
        low, high = param.bounds()
        raw, states, jacobians = projected_residuals(param.model(x), train, counts)
        cost = float(np.sum(np.nan_to_num(raw[0][1:], nan=1e6) ** 2))
        for _ in range(iterations):
            columns = _columns(param, x, train, raw, states, jacobians, counts)
            trial = np.clip(x + _step(raw[0], columns[0]), low, high)
            trial_raw, trial_states, trial_jacobians = projected_residuals(param.model(trial), train, counts)
            trial_cost = float(np.sum(np.nan_to_num(trial_raw[0][1:], nan=1e6) ** 2))
            if trial_cost >= cost:
                break
            x, raw, states, jacobians, cost = trial, trial_raw, trial_states, trial_jacobians, trial_cost
    model = param.model(x)
    r, _, J = projected_residuals(model, heldout, counts)
    return Refit(x, np.nan_to_num(r[0], nan=1e6), J[0], sensor_variance(model, counts))
