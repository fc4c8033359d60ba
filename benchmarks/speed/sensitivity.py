"""Speed of the diagnosis' Jacobians from the exact forward sensitivities against finite differences.

QUBE-Servo 2 windows of the diagnosis' horizon from a log of the surrogate itself (hanging under a multisine at
500 Hz, two RK4 substeps per sample), the arm with Dahl friction, the model holding a spring, a fixed input delay
and the lumped constants' scales besides (nine fitted parameters). Timed in this process, on the same windows:

1. the state Jacobian of the Levenberg-Marquardt refinement (``gap._state_jacobian``): the tangent kernel's one
   pass against the forward differences it replaced (one surrogate call of the five perturbed copies of every
   window, the steps the diagnosis used), and their largest difference relative to the Jacobian's size;
2. one model evaluation (``gap.projected_residuals``: three Levenberg-Marquardt steps on every window, with the
   state sensitivities at the end), with either state Jacobian;
3. the fit's parameter Jacobian (``fit._columns``): exact columns against every column differenced (one
   surrogate call of all nine shifted models, as before), and their largest difference relative to each column;
4. a geared rig's windows (the shipped geared rig, a play of 20 mrad, the same hanging multisine): the state
   Jacobian in the six states (the twist and its rate with the rest) from the drive's tangent model against the
   central differences it replaced (one call of the thirteen copies of every window), and one model evaluation
   with either (the screened twists and six Levenberg-Marquardt steps). No difference is printed here: where the
   teeth engage the differences straddle a jump the tangent carries (``tests/test_drive_tangent.py`` checks the
   tangent against the flow's differences on finely stepped windows).

Each time is the best of ``REPEATS`` runs after a first that compiles or loads the kernels. On a shared machine
the times are indicative only. Run from the repository root: ``PYTHONPATH=. python benchmarks/speed/sensitivity.py``.
"""

from __future__ import annotations

import time
from unittest import mock

import numpy as np

from furuta_drake.diagnosis.gap import metric as gap
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.diagnosis.selection import fit
from furuta_drake.effects.surrogate import HISTORY, Model, integrate_windows, predict_windows
from furuta_drake.effects.vocabulary import Effect, apply_effects, rig_model
from furuta_drake.rig import encoder_resolution, geared_rig, qube_servo2_rig

PERIOD, DURATION, WINDOWS, REPEATS = 2e-3, 20.0, 300, 3
EFFECTS = {
    "arm_coulomb_friction": Effect("presliding", (2e-3, 3e-3)),
    "input_delay": Effect("fixed", (3.3e-3,)),
    "arm_spring": Effect("linear", (0.01, 0.1)),
    "inertia_mismatch": Effect("", (1.05, 0.95, 1.02, 0.98)),
}
STATE_STEPS = np.array([1e-4, 1e-4, 1e-3, 1e-3])  # the forward differences' steps [rad, rad, rad/s, rad/s]
CENTRAL_STEPS = (1e-6, 1e-6, 1e-4, 1e-4, 1e-6, 1e-4)  # the drive's central differences' steps (twist last)
PLAY = 0.02  # [rad] the geared windows' backlash


def _log(model: Model) -> RunLog:
    rng = np.random.default_rng(0)
    time_ = np.arange(int(DURATION / PERIOD)) * PERIOD
    frequencies, phases = rng.uniform(0.5, 6.0, 6), rng.uniform(0, 2 * np.pi, 6)
    command = 0.25 * model.gravity_torque * np.sin(2 * np.pi * frequencies * time_[:, None] + phases).sum(axis=1)
    padded = np.concatenate([np.zeros(HISTORY), command])
    x0 = np.array([[np.pi - 0.3], [0.0], [0.0], [0.0]])
    angles = predict_windows(model, x0, padded, np.array([HISTORY]), time_.size, PERIOD, 2, np.zeros(1))[:, :, 0]
    count = 2 * np.pi / model.counts_per_rev
    theta, phi = np.round(angles.T / count) * count
    return RunLog("hanging.csv", "", time_, theta, phi, "torque", command, PERIOD)


def differenced_state_jacobian(model, x, torque, inputs, count: float):
    """The state Jacobian by forward differences, as the diagnosis took it before: (angles, (h, 2, k, n))."""
    n, k = x.shape
    delta = STATE_STEPS if n == 4 else np.append(STATE_STEPS, 0.05 * model.arm_friction.bristle_bound)
    bristles = x[4] if n > 4 else None
    angles = integrate_windows([model], x[:4], torque, inputs.period, inputs.substeps, bristles)
    points = np.concatenate([x + delta[i] * np.eye(n)[:, [i]] for i in range(n)], axis=1)
    predicted = integrate_windows(
        [model], points[:4], np.tile(torque, (1, n)), inputs.period, inputs.substeps, points[4] if n > 4 else None
    )
    columns = [(predicted[:, :, i * k : (i + 1) * k] - angles) / delta[i] / count for i in range(n)]
    return angles, np.stack(columns, axis=-1)


def central_state_jacobian(model, x, torque, inputs, count: float):
    """The state Jacobian of a drive model by central differences, as the diagnosis took it before: (angles,
    (h, 2, k, 6)), every state's two steps in one surrogate call."""
    n, k = x.shape
    shifted = [x + sign * step * np.eye(n)[:, [i]] for i, step in enumerate(CENTRAL_STEPS) for sign in (1.0, -1.0)]
    every = np.hstack([x] + shifted)
    angles = integrate_windows(
        [model] * (2 * n + 1), every[:4], np.tile(torque, (1, 2 * n + 1)), inputs.period, inputs.substeps, None,
        every[4:],
    )  # fmt: skip
    blocks = angles.reshape(angles.shape[0], 2, 2 * n + 1, k)
    columns = [(blocks[:, :, 1 + 2 * i] - blocks[:, :, 2 + 2 * i]) / (2 * step) for i, step in enumerate(CENTRAL_STEPS)]
    return blocks[:, :, 0], np.stack(columns, axis=-1) / count


def drive_rows() -> None:
    """Part 4 of the module docstring."""
    rig = geared_rig().replace(sample_period=PERIOD)
    model = rig_model(rig).replace(drive_backlash=PLAY)
    counts = rig.counts_per_rev
    windows = gap.make_windows([_log(model)], rig).subset(WINDOWS)
    inputs, count = windows.batches()[0].inputs, encoder_resolution(counts)
    torque = inputs.torque(model)
    states = gap.projected_residuals(model, windows, counts)[1][0]
    exact_s, _ = _best(lambda: gap._state_jacobian(model, states, torque, inputs, count))
    central_s, _ = _best(lambda: central_state_jacobian(model, states, torque, inputs, count))
    _row("geared, play: state (6 directions)", exact_s, central_s)
    with mock.patch.object(gap, "_state_jacobian", central_state_jacobian):
        old_s, _ = _best(lambda: gap.projected_residuals(model, windows, counts))
    new_s, _ = _best(lambda: gap.projected_residuals(model, windows, counts))
    _row("geared, play: model evaluation (6 LM steps)", new_s, old_s)


def _best(function) -> tuple[float, object]:
    """(best wall time [s] of ``REPEATS`` runs after a first, the last result)."""
    result = function()
    seconds = []
    for _ in range(REPEATS):
        start = time.perf_counter()
        result = function()
        seconds.append(time.perf_counter() - start)
    return min(seconds), result


def _relative(a: np.ndarray, b: np.ndarray, axis) -> float:
    """The largest difference of ``a`` from ``b`` relative to each column's largest entry of ``b``."""
    return float(np.max(np.max(np.abs(a - b), axis=axis) / np.maximum(np.max(np.abs(b), axis=axis), 1e-300)))


def _row(label: str, exact: float, differenced: float, difference: float | None = None) -> None:
    shown = "" if difference is None else f"{difference:.1e}"
    print(f"| {label} | {exact * 1e3:.1f} | {differenced * 1e3:.1f} | {differenced / exact:.1f}x | {shown} |")


def main() -> None:
    rig = qube_servo2_rig()
    counts = rig.counts_per_rev
    sizes = [len(effect.values) for effect in EFFECTS.values()]
    x = np.concatenate([effect.values for effect in EFFECTS.values()])

    def model_at(values):
        parts = np.split(np.asarray(values), np.cumsum(sizes)[:-1])
        named = {name: Effect(effect.form, tuple(part)) for (name, effect), part in zip(EFFECTS.items(), parts)}
        return apply_effects(Model.from_rig(rig), named)

    model = model_at(x)
    windows = gap.make_windows([_log(model)], rig).subset(WINDOWS)
    batch = windows.batches()[0]
    inputs = batch.inputs
    substeps = inputs.substeps
    count = encoder_resolution(counts)
    torque = inputs.torque(model)
    states = gap.projected_residuals(model, windows, counts)[1][0]
    print(
        f"{windows.count} windows of {batch.horizon} samples at {PERIOD * 1e3:g} ms ({substeps} substeps), Dahl arm, "
        f"{x.size} fitted parameters; best of {REPEATS} [ms], indicative (shared machine)\n"
    )
    print("| Jacobian | exact [ms] | finite differences [ms] | ratio | largest difference (relative) |")
    print("|---|---:|---:|---:|---:|")
    exact_s, (_, exact) = _best(lambda: gap._state_jacobian(model, states, torque, inputs, count))
    differenced_s, (_, differenced) = _best(lambda: differenced_state_jacobian(model, states, torque, inputs, count))
    _row("state (5 directions)", exact_s, differenced_s, _relative(differenced, exact, axis=(0, 1)))
    with mock.patch.object(gap, "_state_jacobian", differenced_state_jacobian):
        old_s, _ = _best(lambda: gap.projected_residuals(model, windows, counts))
    new_s, _ = _best(lambda: gap.projected_residuals(model, windows, counts))
    _row("model evaluation (3 LM steps)", new_s, old_s)
    last = dict(zip(("raw", "states", "state_jacobians"), gap.projected_residuals(model, windows, counts)))
    span = np.maximum(np.abs(x), 1e-3)
    high = x + span

    def columns():
        return np.stack(fit._columns(model_at, x, windows, last, counts, span, high))

    exact_s, exact = _best(columns)
    with mock.patch.object(fit, "same_branches", lambda model, other: False):
        differenced_s, differenced = _best(columns)
    _row(f"parameters ({x.size} columns)", exact_s, differenced_s, _relative(differenced, exact, axis=(1, 2, 3, 4)))
    drive_rows()


if __name__ == "__main__":
    main()
