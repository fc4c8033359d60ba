"""The surrogate's right-hand side and RK4, compiled (numba): one loop over windows and substeps in machine code.

The diagnosis fits many short windows with few parameters, so a numpy step over a few hundred windows is spent in
the interpreter's overhead of each array operation; a compiled scalar loop does the same arithmetic without it.
The laws are those of :mod:`furuta_drake.friction` written for one float (the Drake systems there also take
AutoDiffXd, which compiled code cannot); ``tests/test_surrogate_kernel.py`` pins each one to its counterpart
there, and the rigid body to Drake's MultibodyPlant.

Parameters travel as flat float arrays (:func:`pack`): ``rigid`` = [a, b, c, d, back-EMF damping, spring k,
spring k3, spring phi_0]; one friction row per joint, laid out as the ``F_*`` indices below; the unmodelled
torque as rows [joint (0 arm, 1 pendulum), term index of :data:`~.torque_library.TERMS`, coefficient N m].
"""

from __future__ import annotations

import math
import types

import numpy as np
from numba import njit

from furuta_drake.effects.torque_library import term_value
from furuta_drake.friction import JointFrictionParameters

NONE, STATIC, DAHL, LUGRE = 0.0, 1.0, 2.0, 3.0  # friction row kinds
F_KIND, F_FC_POS, F_FC_NEG, F_STRIBECK, F_FS_POS, F_FS_NEG, F_VS, F_VISCOUS, F_SIGMA0, F_SIGMA1, F_VREG = range(11)
_KINDS = {"none": NONE, "static": STATIC, "dahl": DAHL, "lugre": LUGRE}


def pack_friction(p: JointFrictionParameters) -> np.ndarray:
    """One joint's friction as a kernel row (the layout of the ``F_*`` indices)."""
    stribeck = p.static_pos is not None or p.static_neg is not None
    static_pos, static_neg = p.static_levels
    return np.array(
        [
            _KINDS[p.model],
            p.coulomb_pos,
            p.coulomb_neg,
            float(stribeck),
            static_pos,
            static_neg,
            p.stribeck_velocity,
            p.viscous,
            p.sigma0,
            p.sigma1,
            p.regularization_velocity,
        ]
    )


def pack(model) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(rigid, arm friction row, pendulum friction row, unmodelled torque rows) of a surrogate
    :class:`~.surrogate.Model`."""
    rigid = np.array(
        [
            model.arm_inertia_total,
            model.pendulum_inertia_total,
            model.coupling,
            model.gravity_torque,
            model.back_emf_damping,
            model.spring_stiffness,
            model.spring_cubic,
            model.spring_equilibrium,
        ]
    )
    terms = np.array(model.unmodelled_terms, dtype=float).reshape(-1, 3)
    return rigid, pack_friction(model.arm_friction), pack_friction(model.pendulum_friction), terms


def pack_rows(models) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """:func:`pack` of each of ``models`` stacked as rows, for :func:`integrate` (the models hold the same number
    of unmodelled torque terms)."""
    packed = [pack(model) for model in models]
    if len({terms.shape for *_, terms in packed}) > 1:
        raise ValueError("models integrated in one call must hold the same number of unmodelled torque terms")
    return tuple(np.stack(rows) for rows in zip(*packed))


@njit(cache=True, inline="always")
def _by_direction(v, positive, negative):
    return positive if v > 0 else negative


@njit(cache=True, inline="always")
def stribeck_level(v, f):
    """g(v) of :func:`furuta_drake.friction.stribeck_curve` [N m]."""
    coulomb = _by_direction(v, f[F_FC_POS], f[F_FC_NEG])
    if f[F_STRIBECK] == 0.0:
        return coulomb
    static = _by_direction(v, f[F_FS_POS], f[F_FS_NEG])
    return coulomb + (static - coulomb) * math.exp(-((v / f[F_VS]) ** 2))


@njit(cache=True, inline="always")
def static_torque(v, f):
    """:func:`furuta_drake.friction.static_friction_torque` [N m]."""
    return static_torque_at(v, f, math.tanh(v / f[F_VREG]))


@njit(cache=True, inline="always")
def static_torque_at(v, f, bend):
    """:func:`static_torque` with its tanh(v / v_reg) given as ``bend``."""
    return -(stribeck_level(v, f) * bend + f[F_VISCOUS] * v)


@njit(cache=True, inline="always")
def bristle_torque(z, v, f):
    """:func:`furuta_drake.friction.bristle_friction_torque` [N m]."""
    torque = f[F_SIGMA0] * z + f[F_VISCOUS] * v
    if f[F_KIND] == LUGRE and f[F_SIGMA1] != 0.0:
        torque += f[F_SIGMA1] * (v - f[F_SIGMA0] * abs(v) * z / stribeck_level(v, f))
    return -torque


@njit(cache=True, inline="always")
def bristle_step(z, displacement, velocity, f):
    """The bristle after the joint moved by ``displacement`` [rad] at ``velocity`` [rad/s] in one direction: Dahl's
    exact step over the path (:func:`furuta_drake.friction.dahl_exact_step` with v dt = displacement), towards the
    direction's Coulomb level (Dahl) or the Stribeck level g of the velocity held (LuGre) [rad]."""
    if f[F_KIND] == DAHL:
        level = max(_by_direction(displacement, f[F_FC_POS], f[F_FC_NEG]), 1e-12)
    else:
        level = max(stribeck_level(velocity, f), 1e-12)
    sigma0 = f[F_SIGMA0]
    steady = 0.0 if displacement == 0.0 else math.copysign(level / sigma0, displacement)
    return steady + (z - steady) * math.exp(-sigma0 * abs(displacement) / level)


@njit(cache=True, inline="always")
def spring_torque(phi, stiffness, cubic, equilibrium):
    """The arm spring's torque -(k x + k3 x^3), x = phi - phi_0 [N m]."""
    stretch = phi - equilibrium
    return -(stiffness + cubic * stretch * stretch) * stretch


@njit(cache=True, inline="always")
def bends(f):
    """Whether a stage takes the tanh(v / v_reg) of the friction row ``f``: a static law's with a Coulomb or static
    level (without one the law is its viscous term alone, and the tanh scales nothing)."""
    levels = f[F_FC_POS] != 0.0 or f[F_FC_NEG] != 0.0 or f[F_FS_POS] != 0.0 or f[F_FS_NEG] != 0.0
    return f[F_KIND] == STATIC and levels


@njit(cache=True, inline="always")
def stage_functions(theta, theta_dot, phi_dot, arm, pendulum, arm_bends, pendulum_bends):
    """The transcendental values a stage's laws read: (sin theta, cos theta, the tanh(v / v_reg) of the arm's and of
    the pendulum's static friction law where ``arm_bends``, ``pendulum_bends``, else 0). The tangent model reads
    them too."""
    arm_bend = math.tanh(phi_dot / arm[F_VREG]) if arm_bends else 0.0
    pendulum_bend = math.tanh(theta_dot / pendulum[F_VREG]) if pendulum_bends else 0.0
    return math.sin(theta), math.cos(theta), arm_bend, pendulum_bend


@njit(cache=True, inline="always")
def derivative(theta, phi, theta_dot, phi_dot, tau, rigid, arm, pendulum, terms):
    """x' of the Furuta model (:mod:`~furuta_drake.effects.surrogate`) under the arm torque ``tau`` [N m]; a
    joint's static friction law acts where its row is static (a bristle's torque comes in ``tau``); the unmodelled
    torque's ``terms`` add to each joint's generalised force."""
    functions = stage_functions(theta, theta_dot, phi_dot, arm, pendulum, bends(arm), bends(pendulum))
    return derivative_at(theta, phi, theta_dot, phi_dot, tau, rigid, arm, pendulum, terms, functions)


@njit(cache=True, inline="always")
def derivative_at(theta, phi, theta_dot, phi_dot, tau, rigid, arm, pendulum, terms, functions):
    """:func:`derivative` with the stage's :func:`stage_functions` given."""
    a, b, c, d = rigid[0], rigid[1], rigid[2], rigid[3]
    s, co, arm_bend, pendulum_bend = functions
    sc = s * co
    tau_phi = tau
    if arm[F_KIND] == STATIC:
        tau_phi += static_torque_at(phi_dot, arm, arm_bend)
    tau_phi -= rigid[4] * phi_dot
    tau_phi += spring_torque(phi, rigid[5], rigid[6], rigid[7])
    m12, m22 = c * co, a + b * s * s
    r1 = d * s + b * sc * phi_dot * phi_dot
    if pendulum[F_KIND] == STATIC:
        r1 += static_torque_at(theta_dot, pendulum, pendulum_bend)
    for j in range(terms.shape[0]):
        value = terms[j, 2] * term_value(int(terms[j, 1]), theta, phi, theta_dot, phi_dot)
        if terms[j, 0] == 0.0:
            tau_phi += value
        else:
            r1 += value
    r2 = c * s * theta_dot * theta_dot - 2.0 * b * sc * theta_dot * phi_dot + tau_phi
    det = b * m22 - m12 * m12
    return theta_dot, phi_dot, (m22 * r1 - m12 * r2) / det, (b * r2 - m12 * r1) / det


@njit(cache=True)
def derivatives(x, tau, rigid, arm, pendulum, terms):
    """:func:`derivative` of every column of ``x`` (4, W) under ``tau`` (W,)."""
    out = np.empty_like(x)
    for w in range(x.shape[1]):
        out[0, w], out[1, w], out[2, w], out[3, w] = derivative(
            x[0, w], x[1, w], x[2, w], x[3, w], tau[w], rigid, arm, pendulum, terms
        )
    return out


@njit(cache=True, inline="always")
def _stage(x0, x1, x2, x3, phi_start, z, tau, bristles, rigid, arm, pendulum, terms):
    if bristles:
        tau = tau + bristle_torque(bristle_step(z, x1 - phi_start, x3, arm), x3, arm)
    return derivative(x0, x1, x2, x3, tau, rigid, arm, pendulum, terms)


@njit(cache=True, inline="always")
def _values(row, n):
    """The first ``n`` entries of a parameter row as a tuple (passed by value in the loops)."""
    if n == 8:
        return (row[0], row[1], row[2], row[3], row[4], row[5], row[6], row[7])
    return (row[0], row[1], row[2], row[3], row[4], row[5], row[6], row[7], row[8], row[9], row[10])


@njit(cache=True, inline="always")
def _rk4_window(t, p, td, pd, z, column, dt, substeps, out, w, bristles, rigid, arm, pendulum, terms):
    """One window's RK4 from (t, p, td, pd) and the bristle ``z`` under the torque ``column`` (steps,), its angles
    written to ``out[:, :, w]`` every ``substeps`` substeps; returns the final (t, p, td, pd, z)."""
    h = 0.5 * dt
    row, substep = 0, 0
    out[0, 0, w], out[0, 1, w] = t, p
    for i in range(column.size):
        tau = column[i]
        a0, a1, a2, a3 = _stage(t, p, td, pd, p, z, tau, bristles, rigid, arm, pendulum, terms)
        b0, b1, b2, b3 = _stage(
            t + h * a0, p + h * a1, td + h * a2, pd + h * a3, p, z, tau, bristles, rigid, arm, pendulum, terms
        )
        c0, c1, c2, c3 = _stage(
            t + h * b0, p + h * b1, td + h * b2, pd + h * b3, p, z, tau, bristles, rigid, arm, pendulum, terms
        )
        d0, d1, d2, d3 = _stage(
            t + dt * c0, p + dt * c1, td + dt * c2, pd + dt * c3, p, z, tau, bristles, rigid, arm, pendulum, terms
        )
        sixth = dt / 6.0
        p_next = p + sixth * (a1 + 2.0 * b1 + 2.0 * c1 + d1)
        t += sixth * (a0 + 2.0 * b0 + 2.0 * c0 + d0)
        td += sixth * (a2 + 2.0 * b2 + 2.0 * c2 + d2)
        pd += sixth * (a3 + 2.0 * b3 + 2.0 * c3 + d3)
        if bristles:
            moved = p_next - p
            z = bristle_step(z, moved, moved / dt, arm)
        p = p_next
        substep += 1
        if substep == substeps:
            row, substep = row + 1, 0
            out[row, 0, w], out[row, 1, w] = t, p
    return t, p, td, pd, z


def _integrate(x0, z0, torque, dt, substeps, rigid, arm, pendulum, terms):
    """:func:`integrate`: RK4 of every window from ``x0`` (4, W) and the arm's bristle ``z0`` (W,) under
    ``torque`` (steps, W) [N m] held over each substep of ``dt`` [s]; the parameters come as M rows (``rigid``
    (M, 8), ``arm`` and ``pendulum`` (M, 11), ``terms`` (M, T, 3)), row m for the m-th block of W / M windows (the
    models of a finite-difference Jacobian's columns in one call; each window's arithmetic is that of a call of
    its model alone). At every stage the bristle (a Dahl or LuGre arm) is its exact step from the substep's start
    over the stage's arm displacement (:func:`bristle_step`), so the stiff bristle needs no step of its own.
    Returns (the angles after every ``substeps`` substeps (steps / substeps + 1, 2, W), row 0 the start; the final
    states (4, W); the final bristles (W,))."""
    steps, width = torque.shape
    out = np.empty((steps // substeps + 1, 2, width))
    final, final_z = np.empty((4, width)), np.empty(width)
    columns = np.ascontiguousarray(torque.T)
    block = width // rigid.shape[0]
    for m in range(rigid.shape[0]):
        rigid_m, arm_m, pendulum_m = _values(rigid[m], 8), _values(arm[m], 11), _values(pendulum[m], 11)
        bristles = arm_m[F_KIND] == DAHL or arm_m[F_KIND] == LUGRE
        for w in range(m * block, (m + 1) * block):
            final[0, w], final[1, w], final[2, w], final[3, w], final_z[w] = _rk4_window(
                x0[0, w],
                x0[1, w],
                x0[2, w],
                x0[3, w],
                z0[w],
                columns[w],
                dt,
                substeps,
                out,
                w,
                bristles,
                rigid_m,
                arm_m,
                pendulum_m,
                terms[m],
            )
    return out, final, final_z


def _compiled_unchecked(function):
    """``function`` compiled with numpy's error model (a division by zero gives inf or nan instead of raising,
    and no division pays for the check), under a name of its own so that its cached machine code is apart from
    that of the checked compilation."""
    name = function.__name__ + "_unchecked"
    names = {"co_name": name} | ({"co_qualname": name} if hasattr(function.__code__, "co_qualname") else {})
    code = function.__code__.replace(**names)  # co_qualname: Python 3.11 on
    return njit(cache=True, error_model="numpy")(types.FunctionType(code, function.__globals__, name))


_checked = njit(cache=True)(_integrate)
_unchecked = _compiled_unchecked(_integrate)


def divisor_is_zero(dt, substeps, arm, pendulum) -> bool:
    """Whether a divisor among the step and the friction rows ``arm`` and ``pendulum`` (M, 11) is zero: then every
    window runs checked."""
    divisors = np.concatenate([arm[:, [F_VS, F_VREG, F_SIGMA0]].ravel(), pendulum[:, [F_VS, F_VREG]].ravel()])
    return dt == 0.0 or substeps == 0 or bool(np.any(divisors == 0.0))


def integrate(x0, z0, torque, dt, substeps, rigid, arm, pendulum, terms):
    """RK4 of every window (:func:`_integrate`) without the division checks, exactly as checked: a division by a
    zero state (the mass matrix' determinant, a LuGre Stribeck level) makes the window's states inf or nan, and
    those windows, or every window when a divisor among the parameters is zero, run again checked, which raises
    ZeroDivisionError where a division by zero happens and otherwise gives the same numbers."""
    rows = (rigid, arm, pendulum, terms)
    if divisor_is_zero(dt, substeps, arm, pendulum):
        return _checked(x0, z0, torque, dt, substeps, *rows)
    out, final, final_z = _unchecked(x0, z0, torque, dt, substeps, *rows)
    finite = np.isfinite(out).all(axis=(0, 1)) & np.isfinite(final).all(axis=0) & np.isfinite(final_z)
    if not finite.all():
        again = np.flatnonzero(~finite)
        block = x0.shape[1] // rigid.shape[0]
        models = again // block
        for m in np.unique(models):
            w = again[models == m]
            one = tuple(row[m : m + 1] for row in rows)
            sub = _checked(x0[:, w], z0[w], np.ascontiguousarray(torque[:, w]), dt, substeps, *one)
            out[:, :, w], final[:, w], final_z[w] = sub
    return out, final, final_z


@njit(cache=True)
def bristle_path(path, period, f):
    """The arm's bristle [rad] at every sample of an arm angle ``path`` sampled every ``period`` [s], from z = 0 at
    the first sample (:func:`bristle_step` per sample)."""
    out = np.empty(path.size)
    z, previous = 0.0, path[0]
    for i in range(path.size):
        moved = path[i] - previous
        if moved != 0.0:
            z = bristle_step(z, moved, moved / period, f)
        out[i], previous = z, path[i]
    return out


@njit(cache=True)
def lag_filter(held, state, time_constant, dt):
    """A first-order lag of ``time_constant`` [s] applied exactly to the input ``held`` (steps, W) held over each
    substep of ``dt`` [s], from the filter states ``state`` (W,): each substep takes the filter's mean over it.
    Returns (the filtered input, the filter states at the end)."""
    decay = math.exp(-dt / time_constant)
    mean = time_constant / dt * (1.0 - decay)  # the mean of exp(-t / lag) over [0, dt)
    out = np.empty_like(held)
    final = state.copy()
    for w in range(held.shape[1]):
        y = final[w]
        for i in range(held.shape[0]):
            u = held[i, w]
            out[i, w] = u + (y - u) * mean
            y = u + (y - u) * decay
        final[w] = y
    return out, final
