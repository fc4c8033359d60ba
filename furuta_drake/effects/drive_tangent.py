"""The tangent-linear model of the drive's RK4 (:mod:`~furuta_drake.effects.drive_kernel`) in the initial state,
compiled.

One pass per window integrates the state [theta, phi, theta', phi', delta, delta'] and the arm's bristle exactly as
:func:`~.drive_kernel.integrate` does (the same compiled stages, so the same angles to the last bit) and carries K
directions of the initial state beside it, stage by stage: the Furuta rows' partial derivatives of
:mod:`~.surrogate_tangent` (the arm's row taking the coupling torque T as its applied torque), T's slopes in the
twist and its rate, the rotor's row J psi'' = tau - d (phi' + delta') - T, and the bristle's exact step after each
RK4 step. A step that engages the teeth is taken again in ``ENGAGEMENT_SPLIT`` shorter steps, its directions with it.

The coupling law has kinks (the play's edges, the contact's clip to a push): there the slope is the side the step's
state lies on, as a finite difference of the kernel that stays on that side gives. The drive's parameters are not
directions here: a fit's Jacobian differences them (:func:`~furuta_drake.effects.surrogate.same_branches`).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from furuta_drake.effects.drive_kernel import (
    D_BACKLASH,
    D_DAMPING,
    D_INERTIA,
    D_MOTOR_ENCODER,
    D_ROTOR_DAMPING,
    D_STIFFNESS,
    ENGAGEMENT_SPLIT,
    inner_steps,
)
from furuta_drake.effects.surrogate_kernel import (
    DAHL,
    F_KIND,
    LUGRE,
    _values,
    bends,
    derivative_at,
    stage_functions,
)
from furuta_drake.effects.surrogate_tangent import _arm_slopes, _stage_slopes, _step_slopes

TANGENT = 7  # a direction's state: theta, phi, theta', phi', the arm's bristle z, delta, delta'


@njit(cache=True, inline="always")
def coupling_slopes(twist, rate, drive):
    """(T [N m] of :func:`~.drive_kernel.coupling_torque`, dT/d delta, dT/d delta'): k and c where the teeth (or
    the spring) push, 0 inside the play and where the contact's clip holds T at 0."""
    b, k, c = drive[D_BACKLASH], drive[D_STIFFNESS], drive[D_DAMPING]
    if b == 0.0:
        return k * twist + c * rate, k, c
    if twist > b:
        torque = k * (twist - b) + c * rate
        return (torque, k, c) if torque > 0.0 else (0.0, 0.0, 0.0)
    if twist < -b:
        torque = k * (twist + b) + c * rate
        return (torque, k, c) if torque < 0.0 else (0.0, 0.0, 0.0)
    return 0.0, 0.0, 0.0


@njit(cache=True, inline="always")
def _rk4_tangent(s, tangent, h, slopes, stages, y, d, z, tau, model, drive):
    """One RK4 step of ``h`` [s] from ``s`` (6,) and its directions ``tangent`` (K, 7) (both changed in place),
    the stages as :func:`~.drive_kernel._rk4` takes them (``y``, ``d``: a stage's state and a direction's change
    of it); returns the arm's move."""
    bristles, rigid, arm, pendulum, terms, arm_bends, pendulum_bends = model
    weights = (0.0, 0.5, 0.5, 1.0)
    start, pendulum_inertia = s[1], rigid[1]
    inertia, rotor_damping = drive[D_INERTIA], drive[D_ROTOR_DAMPING]
    for stage in range(4):
        for j in range(6):
            y[j] = s[j] + (weights[stage] * h * slopes[stage - 1, j] if stage > 0 else 0.0)
        functions = stage_functions(y[0], y[2], y[3], arm, pendulum, arm_bends, pendulum_bends)
        arm_slopes = _arm_slopes(y[1], y[3], start, z, bristles, arm, functions[2])
        coupling, in_twist, in_rate = coupling_slopes(y[4], y[5], drive)
        stage_tau = coupling + arm_slopes[0] if bristles else coupling
        q = derivative_at(y[0], y[1], y[2], y[3], stage_tau, rigid, arm, pendulum, terms, functions)
        rotor = (tau - rotor_damping * (y[3] + y[5]) - coupling) / inertia
        slopes[stage, 0], slopes[stage, 1], slopes[stage, 2], slopes[stage, 3] = q
        slopes[stage, 4], slopes[stage, 5] = y[5], rotor - q[3]
        e, f, (m12, m22, inverse), _ = _stage_slopes(
            y[0], y[1], y[2], y[3], q[2], q[3], arm_slopes, rigid, pendulum, terms, functions
        )
        weight = weights[stage] * h
        for k in range(tangent.shape[0]):
            for j in range(6):
                d[j] = tangent[k, j if j < 4 else j + 1] + (weight * stages[stage - 1, k, j] if stage > 0 else 0.0)
            passed = in_twist * d[4] + in_rate * d[5]
            e1 = e[0] * d[0] + e[1] * d[1] + e[2] * d[2] + e[3] * d[3]
            e2 = f[0] * d[0] + f[1] * d[1] + f[2] * d[2] + f[3] * d[3] + f[4] * tangent[k, 1] + f[5] * tangent[k, 4]
            e2 += passed
            arm_acceleration = (pendulum_inertia * e2 - m12 * e1) * inverse
            stages[stage, k, 0], stages[stage, k, 1] = d[2], d[3]
            stages[stage, k, 2], stages[stage, k, 3] = (m22 * e1 - m12 * e2) * inverse, arm_acceleration
            stages[stage, k, 4] = d[5]
            stages[stage, k, 5] = (-rotor_damping * (d[3] + d[5]) - passed) / inertia - arm_acceleration
    for j in range(6):
        s[j] += h / 6.0 * (slopes[0, j] + 2.0 * slopes[1, j] + 2.0 * slopes[2, j] + slopes[3, j])
    for k in range(tangent.shape[0]):
        for j in range(6):
            increment = stages[0, k, j] + 2.0 * stages[1, k, j] + 2.0 * stages[2, k, j] + stages[3, k, j]
            tangent[k, j if j < 4 else j + 1] += h / 6.0 * increment
    return s[1] - start


@njit(cache=True, inline="always")
def _bristle_tangent(tangent, z, moved, h, arm, before_phi):
    """The bristle after the arm moved by ``moved`` [rad] over a step of ``h`` [s]
    (:func:`~.surrogate_kernel.bristle_step`), its directions' column of ``tangent`` moved with it
    (``before_phi`` (K,): each direction's phi before the step)."""
    stepped, in_z, in_move, in_velocity, _ = _step_slopes(z, moved, moved / h, arm)
    for k in range(tangent.shape[0]):
        tangent[k, 4] = in_z * tangent[k, 4] + (in_move + in_velocity / h) * (tangent[k, 1] - before_phi[k])
    return stepped


@njit(cache=True, inline="always")
def _saltation(tangent, s, rigid, drive):
    """The directions' jump where the teeth engage at the state ``s`` (6,): the contact's damper switches on
    there, so the accelerations jump by those of T = c delta' on the arm and -T on the rotor, and a direction that
    moves the twist by d delta moves the engagement by -d delta / delta' in time: its accelerations take the jump
    times d delta / delta' (the saltation matrix of the flow at the event)."""
    rate = s[5]
    if rate == 0.0:
        return
    torque = drive[D_DAMPING] * rate
    pendulum_inertia, coupling = rigid[1], rigid[2] * math.cos(s[0])
    arm_inertia = rigid[0] + pendulum_inertia * math.sin(s[0]) ** 2
    det = pendulum_inertia * arm_inertia - coupling * coupling
    jump_theta, jump_phi = -coupling * torque / det, pendulum_inertia * torque / det
    jump_twist = -torque / drive[D_INERTIA] - jump_phi
    for k in range(tangent.shape[0]):
        moved = tangent[k, 5] / rate
        tangent[k, 2] += jump_theta * moved
        tangent[k, 3] += jump_phi * moved
        tangent[k, 6] += jump_twist * moved


@njit(cache=True)
def _tangent_window(s, z, column, dt, inner, substeps, angles, out, w, model, drive, seeds):
    """:func:`~.drive_kernel._drive_window` of window ``w`` with the directions ``seeds`` (K, 7) carried along;
    angles to ``angles[:, :, w]``, their slopes to ``out[:, :, w, :]``."""
    bristles, arm = model[0], model[2]
    h = dt / inner
    tangent, saved = seeds.copy(), np.empty_like(seeds)
    slopes, stages = np.empty((4, 6)), np.empty((4, seeds.shape[0], 6))
    y, d, before = np.empty(6), np.empty(6), np.empty(6)
    motor = drive[D_MOTOR_ENCODER] != 0.0
    b = drive[D_BACKLASH]
    row, substep = 0, 0
    _record(angles, out, 0, w, s, tangent, motor)
    for i in range(column.size):
        for _ in range(inner):
            before[:] = s
            saved[:, :] = tangent
            moved = _rk4_tangent(s, tangent, h, slopes, stages, y, d, z, column[i], model, drive)
            if b > 0.0 and abs(before[4]) <= b and abs(s[4]) > b:
                s[:] = before
                tangent[:, :] = saved
                short = h / ENGAGEMENT_SPLIT
                for _ in range(ENGAGEMENT_SPLIT):
                    start_phi, start_twist = tangent[:, 1].copy(), s[4]
                    part = _rk4_tangent(s, tangent, short, slopes, stages, y, d, z, column[i], model, drive)
                    if abs(start_twist) <= b and abs(s[4]) > b:
                        _saltation(tangent, s, model[1], drive)
                    if bristles:
                        z = _bristle_tangent(tangent, z, part, short, arm, start_phi)
            elif bristles:
                z = _bristle_tangent(tangent, z, moved, h, arm, saved[:, 1])
        substep += 1
        if substep == substeps:
            row, substep = row + 1, 0
            _record(angles, out, row, w, s, tangent, motor)


@njit(cache=True, inline="always")
def _record(angles, out, row, w, s, tangent, motor):
    angles[row, 0, w], angles[row, 1, w] = s[0], s[1] + (s[4] if motor else 0.0)
    for k in range(tangent.shape[0]):
        out[row, 0, w, k] = tangent[k, 0]
        out[row, 1, w, k] = tangent[k, 1] + (tangent[k, 5] if motor else 0.0)


@njit(cache=True)
def _tangents(x0, z0, torque, dt, inner, substeps, rigid, arm, pendulum, terms, drive, seeds):
    steps, width = torque.shape
    angles = np.empty((steps // substeps + 1, 2, width))
    out = np.empty((steps // substeps + 1, 2, width, seeds.shape[0]))
    columns = np.ascontiguousarray(torque.T)
    rigid_v, arm_v, pendulum_v = _values(rigid, 8), _values(arm, 11), _values(pendulum, 11)
    bristles = arm_v[F_KIND] == DAHL or arm_v[F_KIND] == LUGRE
    model = (bristles, rigid_v, arm_v, pendulum_v, terms, bends(arm_v), bends(pendulum_v))
    for w in range(width):
        _tangent_window(x0[:, w].copy(), z0[w], columns[w], dt, inner, substeps, angles, out, w, model, drive, seeds)
    return angles, out


def state_tangents(x0, z0, torque, dt, substeps, rows, bristles: bool) -> tuple[np.ndarray, np.ndarray]:
    """The angles of :func:`~.drive_kernel.integrate` of one model (``rows``: its
    :func:`~.drive_kernel.pack_drive_rows`) from ``x0`` (6, W) and the bristles ``z0`` (W,) under ``torque``
    (steps, W) [N m], and their derivatives (steps / substeps + 1, 2, W, n) in each window's initial theta, phi,
    theta', phi', the bristle z where ``bristles``, delta and delta' (n = 6, or 7 with the bristle), in that order."""
    rigid, arm, pendulum, terms, drive = rows
    columns = [0, 1, 2, 3] + ([4] if bristles else []) + [5, 6]
    seeds = np.eye(TANGENT)[columns]
    inner = inner_steps(rigid, drive, dt)
    x0 = np.ascontiguousarray(x0, dtype=float)
    z0 = np.ascontiguousarray(z0, dtype=float)
    return _tangents(x0, z0, torque, dt, inner, substeps, rigid[0], arm[0], pendulum[0], terms[0], drive[0], seeds)
