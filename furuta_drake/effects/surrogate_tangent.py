"""The tangent-linear model of the surrogate's RK4 (:mod:`~furuta_drake.effects.surrogate_kernel`), compiled.

One pass per window integrates the state exactly as :func:`~.surrogate_kernel.integrate` does (the same compiled
stages, so the same angles to the last bit) and carries K tangent directions beside it: the derivative of the
discrete scheme itself, stage by stage (the RK4 stages, the bristle's exact step at each stage and at each
substep's end, the friction laws, the mass matrix' solve, the spring, the back-EMF damping and the unmodelled
torque's terms), so the result is what a finite difference of the kernel gives, without its truncation error.

A direction is a change of the initial state (theta, phi, theta', phi', and the arm's bristle z), of the
packed parameters (:func:`flat`: the ``rigid`` row, the arm's and the pendulum's friction rows, the unmodelled
terms' coefficients) and of the arm torque at every substep. Every stage's accelerations solve M(q) q'' = r,
so a change moves them by M^-1 (dr - dM q''): each stage's partial derivatives are formed once and every
direction is a few multiply-adds.

Where the scheme is not differentiable the slope is the mean of its two sides' (what a central difference gives):
a bristle step over a displacement of exactly zero (the first stage of every substep moves the bristle by nothing;
a joint at rest moves it by nothing at the second stage too), and the friction laws at a velocity of exactly zero
(where |v| turns and the level of each direction meets the other's).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from furuta_drake.effects.surrogate_kernel import (
    DAHL,
    F_FC_NEG,
    F_FC_POS,
    F_FS_NEG,
    F_FS_POS,
    F_KIND,
    F_SIGMA0,
    F_SIGMA1,
    F_STRIBECK,
    F_VISCOUS,
    F_VREG,
    F_VS,
    LUGRE,
    STATIC,
    _compiled_unchecked,
    _values,
    bends,
    bristle_torque,
    derivative_at,
    divisor_is_zero,
    pack,
    stage_functions,
    stribeck_level,
)
from furuta_drake.effects.torque_library import term_slopes, term_value

RIGID, ROW = 8, 11  # entries of the rigid row and of a friction row
ARM, PENDULUM, TERMS = RIGID, RIGID + ROW, RIGID + 2 * ROW  # offsets of the rows in the flat parameters
STATE = 5  # theta, phi, theta', phi', the arm's bristle z


def flat(model) -> np.ndarray:
    """The packed parameters of a surrogate :class:`~.surrogate.Model` as one vector (the tangent directions'
    layout): ``rigid`` (8), the arm's friction row (11), the pendulum's (11), each unmodelled term's coefficient."""
    rigid, arm, pendulum, terms = pack(model)
    return np.concatenate([rigid, arm, pendulum, terms[:, 2]])


@njit(cache=True, inline="always")
def _level_slopes(v, f):
    """The Stribeck level g(v) of :func:`~.surrogate_kernel.stribeck_level`, dg/dv and its slopes in the row:
    (g, dg/dv, the Coulomb entry, dg/dFc, the static entry, dg/dFs, dg/dvs)."""
    coulomb = F_FC_POS if v > 0 else F_FC_NEG
    if f[F_STRIBECK] == 0.0:
        return f[coulomb], 0.0, coulomb, 1.0, F_FS_POS, 0.0, 0.0
    static = F_FS_POS if v > 0 else F_FS_NEG
    vs = f[F_VS]
    decay = math.exp(-((v / vs) ** 2))
    rise = (f[static] - f[coulomb]) * decay
    in_v, in_vs = -2.0 * v / (vs * vs) * rise, 2.0 * v * v / vs**3 * rise
    return f[coulomb] + rise, in_v, coulomb, 1.0 - decay, static, decay, in_vs


# A friction row's slopes, sparse: (its Coulomb entry, its static entry, the slopes in those two, in vs, in v_reg,
# in the viscous coefficient, in sigma0, in sigma1). The slope functions return them as tuples (no array in the
# stages: an array passed to an inline function is a reference count taken and dropped every stage).
NO_SLOPES = (F_FC_POS, F_FS_POS, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0)


@njit(cache=True, inline="always")
def _level_row(weight, level, vreg=0.0, viscous=0.0, sigma0=0.0, sigma1=0.0):
    """The row slopes of ``weight`` times g (``level``: the tail of :func:`_level_slopes`) and of the other
    entries' slopes given."""
    coulomb, g_c, static, g_s, g_vs = level
    return (coulomb, static, weight * g_c, weight * g_s, weight * g_vs, vreg, viscous, sigma0, sigma1)


@njit(cache=True, inline="always")
def _combined(a, weight, b):
    """``weight`` times the row slopes ``a`` plus ``b``, at b's level entries where b has level slopes (a stage's
    bristle step and torque read the same velocity's direction, and a step by nothing has none)."""
    leveled = b[2] != 0.0 or b[3] != 0.0 or b[4] != 0.0
    return (
        b[0] if leveled else a[0],
        b[1] if leveled else a[1],
        weight * a[2] + b[2],
        weight * a[3] + b[3],
        weight * a[4] + b[4],
        weight * a[5] + b[5],
        weight * a[6] + b[6],
        weight * a[7] + b[7],
        weight * a[8] + b[8],
    )


@njit(cache=True, inline="always")
def _row_slope(row, j):
    """The slope of the row slopes ``row`` in a friction row's entry ``j``."""
    value = row[2] if j == row[0] else 0.0
    value += row[3] if j == row[1] else 0.0
    if j == F_VS:
        value += row[4]
    elif j == F_VREG:
        value += row[5]
    elif j == F_VISCOUS:
        value += row[6]
    elif j == F_SIGMA0:
        value += row[7]
    elif j == F_SIGMA1:
        value += row[8]
    return value


@njit(cache=True, inline="always")
def _resting_levels(f):
    """The Stribeck level g at zero velocity approached from above and from below [N m]."""
    if f[F_STRIBECK] == 0.0:
        return f[F_FC_POS], f[F_FC_NEG]
    return f[F_FS_POS], f[F_FS_NEG]


@njit(cache=True, inline="always")
def _static_slopes(v, f, t):
    """(d/dv of :func:`~.surrogate_kernel.static_torque` at v, whose tanh(v / v_reg) is ``t``, at v = 0 the mean of
    its two sides'; its row slopes)."""
    g, g_v, coulomb, g_c, static, g_s, g_vs = _level_slopes(v, f)
    if v == 0.0:
        up, down = _resting_levels(f)
        g = 0.5 * (up + down)
    vreg = f[F_VREG]
    bend = (1.0 - t * t) / vreg
    row = _level_row(-t, (coulomb, g_c, static, g_s, g_vs), g * bend * v / vreg, -v)
    return -(g_v * t + g * bend + f[F_VISCOUS]), row


@njit(cache=True, inline="always")
def _step_slopes(z, displacement, velocity, f):
    """:func:`~.surrogate_kernel.bristle_step` (the same arithmetic) and its slopes: (the bristle, in z, in the
    displacement, in the velocity, its row slopes). Over a displacement of zero the step leaves z as it is
    whatever the parameters, and its slope in the displacement is the mean of the two sides'."""
    sigma0 = f[F_SIGMA0]
    if displacement == 0.0:
        if f[F_KIND] == DAHL:
            up, down = max(f[F_FC_POS], 1e-12), max(f[F_FC_NEG], 1e-12)
        else:
            up = down = max(stribeck_level(velocity, f), 1e-12)
        return z, 1.0, 1.0 - 0.5 * z * sigma0 * (1.0 / up - 1.0 / down), 0.0, NO_SLOPES
    sign = 1.0 if displacement > 0 else -1.0
    if f[F_KIND] == DAHL:
        coulomb = F_FC_POS if sign > 0 else F_FC_NEG
        g, g_v, g_c, static, g_s, g_vs = f[coulomb], 0.0, 1.0, F_FS_POS, 0.0, 0.0
    else:
        g, g_v, coulomb, g_c, static, g_s, g_vs = _level_slopes(velocity, f)
    level = max(g, 1e-12)
    distance = abs(displacement)
    steady = math.copysign(level / sigma0, displacement)
    decay = math.exp(-sigma0 * distance / level)
    gap = z - steady
    in_level = 0.0 if g < 1e-12 else sign / sigma0 * (1.0 - decay) + gap * decay * sigma0 * distance / (level * level)
    in_sigma0 = -steady / sigma0 * (1.0 - decay) - gap * decay * distance / level
    row = _level_row(in_level, (coulomb, g_c, static, g_s, g_vs), sigma0=in_sigma0)
    return steady + gap * decay, decay, decay * (1.0 - sign * z * sigma0 / level), in_level * g_v, row


@njit(cache=True, inline="always")
def _bristle_torque_slopes(z, v, f):
    """(the slopes in z and in v of :func:`~.surrogate_kernel.bristle_torque`, at v = 0 the mean of its two
    sides'; its row slopes)."""
    sigma0 = f[F_SIGMA0]
    if not (f[F_KIND] == LUGRE and f[F_SIGMA1] != 0.0):
        return -sigma0, -f[F_VISCOUS], _level_row(0.0, (F_FC_POS, 0.0, F_FS_POS, 0.0, 0.0), 0.0, -v, -z)
    sigma1 = f[F_SIGMA1]
    g, g_v, coulomb, g_c, static, g_s, g_vs = _level_slopes(v, f)
    speed = abs(v)
    pull = sigma0 * speed * z / g  # the damping's bristle share
    if v == 0.0:
        up, down = _resting_levels(f)
        turn = 0.5 * (1.0 / up - 1.0 / down)  # d(|v| / g)/dv, the mean of its sides
    else:
        turn = ((1.0 if v > 0 else -1.0) - speed * g_v / g) / g
    level = (coulomb, g_c, static, g_s, g_vs)
    row = _level_row(-sigma1 * pull / g, level, 0.0, -v, -z + sigma1 * speed * z / g, -(v - pull))
    return -sigma0 * (1.0 - sigma1 * speed / g), -(f[F_VISCOUS] + sigma1 * (1.0 - sigma0 * z * turn)), row


@njit(cache=True, inline="always")
def _arm_slopes(x1, x3, phi_start, z, bristles, f, bend):
    """The bristle's torque at a stage (0 without bristles: a static law acts inside the derivative, ``bend`` its
    tanh(phi' / v_reg)), the arm friction torque's slopes (in phi, phi', the substep's start phi, z) and its row
    slopes."""
    if bristles:
        displacement = x1 - phi_start
        zs, s_z, s_d, s_v, step_row = _step_slopes(z, displacement, x3, f)
        t_z, t_v, torque_row = _bristle_torque_slopes(zs, x3, f)
        row = _combined(step_row, t_z, torque_row)
        return bristle_torque(zs, x3, f), t_z * s_d, t_z * s_v + t_v, -t_z * s_d, t_z * s_z, row
    if f[F_KIND] == STATIC:
        rate, row = _static_slopes(x3, f, bend)
        return 0.0, 0.0, rate, 0.0, 0.0, row
    return 0.0, 0.0, 0.0, 0.0, 0.0, NO_SLOPES


@njit(cache=True, inline="always")
def _stage_slopes(x0, x1, x2, x3, q1, q2, arm_slopes, rigid, pendulum, terms, functions):
    """The partial derivatives of a stage (:func:`~.surrogate_kernel.derivative` at (theta, phi, theta', phi'),
    whose accelerations are q1, q2, its :func:`~.surrogate_kernel.stage_functions` ``functions``, the arm
    friction's slopes ``arm_slopes`` of :func:`_arm_slopes`) as
    e = dr - dM q'': (e of the pendulum's row in the stage's state (4); e of the arm's row in the stage's state,
    the substep's start phi and z (6), the applied torque's is (0, 1); the mass matrix' (m12, m22, 1 / det), m11 =
    b; the pendulum friction's row slopes)."""
    a, b, c, d = rigid[0], rigid[1], rigid[2], rigid[3]
    s, co, _, pendulum_bend = functions
    sc, double = s * co, co * co - s * s
    m12, m22 = c * co, a + b * s * s
    if pendulum[F_KIND] == STATIC:
        fp_rate, pendulum_row = _static_slopes(x2, pendulum, pendulum_bend)
    else:
        fp_rate, pendulum_row = 0.0, NO_SLOPES
    stretch = x1 - rigid[7]
    spring = -(rigid[5] + 3.0 * rigid[6] * stretch * stretch)
    p0, p1, p2, p3 = d * co + b * double * x3 * x3 + c * s * q2, 0.0, fp_rate, 2.0 * b * sc * x3
    r0 = c * co * x2 * x2 - 2.0 * b * double * x2 * x3 + c * s * q1 - 2.0 * b * sc * q2
    r1 = spring + arm_slopes[1]
    r2, r3 = 2.0 * c * s * x2 - 2.0 * b * sc * x3, -2.0 * b * sc * x2 + arm_slopes[2] - rigid[4]
    for j in range(terms.shape[0]):
        coefficient = terms[j, 2]
        t0, t1, t2, t3 = term_slopes(int(terms[j, 1]), x0, x1, x2, x3)
        if terms[j, 0] != 0.0:
            p0, p1, p2, p3 = p0 + coefficient * t0, p1 + coefficient * t1, p2 + coefficient * t2, p3 + coefficient * t3
        else:
            r0, r1, r2, r3 = r0 + coefficient * t0, r1 + coefficient * t1, r2 + coefficient * t2, r3 + coefficient * t3
    arm_e = (r0, r1, r2, r3, arm_slopes[3], arm_slopes[4])
    return (p0, p1, p2, p3), arm_e, (m12, m22, 1.0 / (b * m22 - m12 * m12)), pendulum_row


@njit(cache=True, inline="always")
def _flat_slopes(e_flat, x0, x1, x2, x3, q1, q2, rigid, terms, arm_row, pendulum_row, s, co):
    """e = dr - dM q'' of a stage per flat parameter (:func:`flat`), written to ``e_flat`` (2, P): the ``rigid``
    row's (a, b, c, d, back-EMF damping, spring k, k3, phi_0), the friction rows' (``arm_row``, ``pendulum_row``
    of the stage's slopes), the unmodelled terms' coefficients'; ``s``, ``co`` the sine and cosine of theta."""
    sc, stretch = s * co, x1 - rigid[7]
    e_flat[0, 0], e_flat[1, 0] = 0.0, -q2
    e_flat[0, 1], e_flat[1, 1] = sc * x3 * x3 - q1, -2.0 * sc * x2 * x3 - s * s * q2
    e_flat[0, 2], e_flat[1, 2] = -co * q2, s * x2 * x2 - co * q1
    e_flat[0, 3], e_flat[1, 3] = s, 0.0
    e_flat[0, 4], e_flat[1, 4] = 0.0, -x3
    e_flat[0, 5], e_flat[1, 5] = 0.0, -stretch
    e_flat[0, 6], e_flat[1, 6] = 0.0, -(stretch**3)
    e_flat[0, 7], e_flat[1, 7] = 0.0, rigid[5] + 3.0 * rigid[6] * stretch * stretch
    for j in range(ROW):
        e_flat[0, ARM + j], e_flat[1, ARM + j] = 0.0, _row_slope(arm_row, j)
        e_flat[0, PENDULUM + j], e_flat[1, PENDULUM + j] = _row_slope(pendulum_row, j), 0.0
    for j in range(terms.shape[0]):
        value = term_value(int(terms[j, 1]), x0, x1, x2, x3)
        e_flat[0, TERMS + j], e_flat[1, TERMS + j] = (value, 0.0) if terms[j, 0] != 0.0 else (0.0, value)


@njit(cache=True, inline="always")
def _advance(tangent, stages, sixth, bristles, z, moved, dt, arm, active, directions):
    """Every direction's state tangent (K, 5) over the substep from its stages' slopes (4, K, 4): RK4's sum, and
    the bristle's exact step over the arm's move ``moved`` [rad] from ``z`` (a Dahl or LuGre arm); returns the
    bristle after the step (:func:`~.surrogate_kernel.bristle_step`)."""
    s_z, s_move, row = 0.0, 0.0, NO_SLOPES
    if bristles:
        z, s_z, s_d, s_v, row = _step_slopes(z, moved, moved / dt, arm)
        s_move = s_d + s_v / dt
    for k in range(tangent.shape[0]):
        for i in range(4):
            increment = sixth * (stages[0, k, i] + 2.0 * stages[1, k, i] + 2.0 * stages[2, k, i] + stages[3, k, i])
            tangent[k, i] += increment
        if bristles:
            dz = s_z * tangent[k, 4] + s_move * sixth * (
                stages[0, k, 1] + 2.0 * stages[1, k, 1] + 2.0 * stages[2, k, 1] + stages[3, k, 1]
            )
            for j in range(active.size):
                if ARM <= active[j] < PENDULUM:
                    dz += _row_slope(row, active[j] - ARM) * directions[k, j]
            tangent[k, 4] = dz
    return z


@njit(cache=True, inline="always")
def _tangent_window(t, p, td, pd, z, column, changes, torque_of, dt, substeps, angles, slopes, w, model, terms, work):
    """:func:`~.surrogate_kernel._rk4_window` of window ``w`` with every direction's tangent carried along from
    ``work``'s ``tangent`` (K, 5) (the seeds); the torque's change ``changes[torque_of[k]]`` (steps,) for the
    directions with one (``torque_of[k]`` >= 0). Angles to ``angles[:, :, w]``, their slopes to
    ``slopes[:, :, w, :]``. The four stages run in a loop (one compiled copy of the stage), their values kept in
    ``values`` (4, 4) and summed as the kernel sums them; each stage's directions are a few multiply-adds on its
    partial derivatives (:func:`_stage_slopes`), the applied torque's change and the flat parameters' (``e_flat``
    at the entries ``active``)."""
    bristles, rigid, arm, pendulum, arm_bends, pendulum_bends = model
    e_flat, active, directions, tangent, stages, torque, values = work
    full, b, h = active.size > 0, rigid[1], 0.5 * dt
    row, substep = 0, 0
    _record(angles, slopes, 0, w, t, p, tangent)
    for i in range(column.size):
        tau = column[i]
        for j in range(torque.size):
            torque[j] = 0.0 if torque_of[j] < 0 else changes[torque_of[j], i]
        x0, x1, x2, x3 = t, p, td, pd
        for n in range(4):
            functions = stage_functions(x0, x2, x3, arm, pendulum, arm_bends, pendulum_bends)
            arm_slopes = _arm_slopes(x1, x3, p, z, bristles, arm, functions[2])
            stage_tau = tau + arm_slopes[0] if bristles else tau
            q = derivative_at(x0, x1, x2, x3, stage_tau, rigid, arm, pendulum, terms, functions)
            e, f, (m12, m22, inverse), pendulum_row = _stage_slopes(
                x0, x1, x2, x3, q[2], q[3], arm_slopes, rigid, pendulum, terms, functions
            )
            if full:
                s, co = functions[0], functions[1]
                _flat_slopes(e_flat, x0, x1, x2, x3, q[2], q[3], rigid, terms, arm_slopes[5], pendulum_row, s, co)
            weight = dt if n == 3 else h  # of the previous stage's slopes in this one's state
            for k in range(tangent.shape[0]):
                dx0, dx1, dx2, dx3 = tangent[k, 0], tangent[k, 1], tangent[k, 2], tangent[k, 3]
                if n > 0:
                    dx0 += weight * stages[n - 1, k, 0]
                    dx1 += weight * stages[n - 1, k, 1]
                    dx2 += weight * stages[n - 1, k, 2]
                    dx3 += weight * stages[n - 1, k, 3]
                e1 = e[0] * dx0 + e[1] * dx1 + e[2] * dx2 + e[3] * dx3
                e2 = f[0] * dx0 + f[1] * dx1 + f[2] * dx2 + f[3] * dx3 + f[4] * tangent[k, 1] + f[5] * tangent[k, 4]
                e2 += torque[k]
                for j in range(active.size):
                    e1 += e_flat[0, active[j]] * directions[k, j]
                    e2 += e_flat[1, active[j]] * directions[k, j]
                stages[n, k, 0], stages[n, k, 1] = dx2, dx3
                stages[n, k, 2], stages[n, k, 3] = (m22 * e1 - m12 * e2) * inverse, (b * e2 - m12 * e1) * inverse
            values[n, 0], values[n, 1], values[n, 2], values[n, 3] = q
            step = dt if n == 2 else h
            x0, x1, x2, x3 = t + step * q[0], p + step * q[1], td + step * q[2], pd + step * q[3]
        sixth = dt / 6.0
        p_next = p + sixth * (values[0, 1] + 2.0 * values[1, 1] + 2.0 * values[2, 1] + values[3, 1])
        t += sixth * (values[0, 0] + 2.0 * values[1, 0] + 2.0 * values[2, 0] + values[3, 0])
        td += sixth * (values[0, 2] + 2.0 * values[1, 2] + 2.0 * values[2, 2] + values[3, 2])
        pd += sixth * (values[0, 3] + 2.0 * values[1, 3] + 2.0 * values[2, 3] + values[3, 3])
        moved = p_next - p
        z = _advance(tangent, stages, sixth, bristles, z, moved, dt, arm, active, directions)
        p = p_next
        substep += 1
        if substep == substeps:
            row, substep = row + 1, 0
            _record(angles, slopes, row, w, t, p, tangent)


@njit(cache=True, inline="always")
def _record(angles, slopes, row, w, t, p, tangent):
    angles[row, 0, w], angles[row, 1, w] = t, p
    for k in range(tangent.shape[0]):
        slopes[row, 0, w, k], slopes[row, 1, w, k] = tangent[k, 0], tangent[k, 1]


@njit(cache=True, inline="always")
def _bends(f, active, first, end):
    """Whether the stages take the tanh(v / v_reg) of the friction row ``f`` (the flat entries first to end): where
    the kernel does (:func:`~.surrogate_kernel.bends`), and for a static law a direction moves (the levels' slopes
    read it)."""
    return bends(f) or (f[F_KIND] == STATIC and np.any((active >= first) & (active < end)))


def _tangents(x0, z0, torque, changes, dt, substeps, rigid, arm, pendulum, terms, seeds, directions, active, torque_of):
    """:func:`tangents` of one model's packed rows (``rigid`` (8,), ``arm`` and ``pendulum`` (11,), ``terms``
    (T, 3)); ``directions`` (K, A) the directions' changes of the flat entries ``active``; ``changes`` (C, W, steps)
    the torque changes, direction k's the ``torque_of[k]``-th (-1: none)."""
    steps, width = torque.shape
    count = seeds.shape[0]
    angles = np.empty((steps // substeps + 1, 2, width))
    slopes = np.empty((steps // substeps + 1, 2, width, count))
    columns = np.ascontiguousarray(torque.T)
    rigid_v, arm_v, pendulum_v = _values(rigid, 8), _values(arm, 11), _values(pendulum, 11)
    bristles = arm_v[F_KIND] == DAHL or arm_v[F_KIND] == LUGRE
    bends = _bends(arm_v, active, ARM, PENDULUM), _bends(pendulum_v, active, PENDULUM, TERMS)
    model = (bristles, rigid_v, arm_v, pendulum_v) + bends
    work = (
        np.zeros((2, TERMS + terms.shape[0])),  # the stage's slopes in the flat parameters
        active,
        directions,
        np.empty((count, STATE)),  # the directions' state tangents
        np.empty((4, count, 4)),  # the stages' slopes
        np.empty(count),  # the applied torque's change
        np.empty((4, 4)),  # the stages' values
    )
    for w in range(width):
        work[3][:, :] = seeds
        _tangent_window(
            x0[0, w], x0[1, w], x0[2, w], x0[3, w], z0[w], columns[w], changes[:, w], torque_of, dt, substeps,
            angles, slopes, w, model, terms, work,
        )  # fmt: skip
    return angles, slopes


_checked = njit(cache=True)(_tangents)
_unchecked = _compiled_unchecked(_tangents)


def tangents(x0, z0, torque, dt, substeps, packed, seeds, rows=None, torques=None):
    """RK4 of every window (:func:`~.surrogate_kernel.integrate` of one model, ``packed`` = its
    :func:`~.surrogate_kernel.pack`) from ``x0`` (4, W) and the arm's bristle ``z0`` (W,) under ``torque``
    (steps, W) [N m], with K directions carried along: ``seeds`` (K, 5) each one's change of the initial
    (theta, phi, theta', phi', z), the same for every window; ``rows`` (K, P) its change of the flat parameters
    (:func:`flat`; None: none); ``torques`` K arrays (steps, W) or None: its change of the torque [N m].
    Returns (the angles (steps / substeps + 1, 2, W), row 0 the start; their derivatives along each direction
    (steps / substeps + 1, 2, W, K)). Run without division checks, and checked where a window's numbers are not
    finite, as :func:`~.surrogate_kernel.integrate`."""
    rigid, arm, pendulum, terms = (np.ascontiguousarray(part, dtype=float) for part in packed)
    directions = len(seeds)
    rows = np.zeros((directions, TERMS + len(terms))) if rows is None else np.asarray(rows, dtype=float)
    active = np.flatnonzero(np.any(rows != 0.0, axis=0))
    given = [change is not None for change in ([None] * directions if torques is None else torques)]
    torque_of = np.where(given, np.cumsum(given) - 1, -1).astype(np.int64)
    changes = np.stack([np.transpose(c) for c, g in zip(torques or [], given) if g] or [np.zeros(torque.shape[::-1])])
    windowed = (x0, z0, torque, changes)
    fixed = (dt, substeps, rigid, arm, pendulum, terms, np.ascontiguousarray(seeds, dtype=float))
    fixed += (np.ascontiguousarray(rows[:, active]), active, torque_of)

    def run(compiled, w):
        x, z, u, c = (np.ascontiguousarray(a[..., w] if a.ndim < 3 else a[:, w], dtype=float) for a in windowed)
        return compiled(x, z, u, c, *fixed)

    everything = slice(None)
    if divisor_is_zero(dt, substeps, arm[None], pendulum[None]):
        return run(_checked, everything)
    angles, slopes = run(_unchecked, everything)
    again = np.flatnonzero(~(np.isfinite(angles).all(axis=(0, 1)) & np.isfinite(slopes).all(axis=(0, 1, 3))))
    if again.size:
        angles[:, :, again], slopes[:, :, again] = run(_checked, again)
    return angles, slopes
