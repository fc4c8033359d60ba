"""The surrogate with a drive of its own state (gear backlash, an elastic coupling), compiled: used only for a model
that holds one (:attr:`~furuta_drake.effects.surrogate.Model.has_drive`).

The drive is :mod:`furuta_drake.drive`'s, on the arm side: a rotor of inertia J (the share ``rotor_share`` of the
model's a = J_arm + m r^2, so an inertia scale scales both) receives the actuator chain's torque tau and the back-EMF
-d psi' of its own speed; the arm side (a - J) receives the coupling torque T(delta, delta') of the twist
delta = psi - phi instead of tau. The state is [theta, phi, theta', phi', delta, delta'] (and the arm's bristle):

    J psi'' = tau - d (phi' + delta') - T,        delta'' = psi'' - phi'',

phi'' from the Furuta model with the arm torque T (:func:`~.surrogate_kernel.derivative` with a - J and no
back-EMF). T is :meth:`furuta_drake.drive.Coupling.torque`: k delta + c delta' without backlash; with a half-width b,
0 inside +-b and beyond it the push-only k (delta -+ b) + c delta', k and c the stated spring's or, where the model
states none, the rigid gear's tooth contact (:func:`~furuta_drake.drive.tooth_contact`). With the arm's encoder on
the motor the angle read is psi = phi + delta.

The RK4 steps each substep of the torque in ``inner`` steps (:func:`inner_steps`), short against the pair's fastest
rate (a tooth contact rings at 200 Hz). The law is not smooth (the backlash's edges, the contact's clip): its
sensitivities in the initial state are :mod:`~.drive_tangent`'s, with the flow's jump where the teeth engage.
``tests/test_drive_kernel.py`` pins the law to :mod:`furuta_drake.drive` and a window to the Drake world.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from furuta_drake.drive import tooth_contact
from furuta_drake.effects.surrogate_kernel import DAHL, F_KIND, LUGRE, _stage, _values, bristle_step, pack_rows

D_INERTIA, D_BACKLASH, D_STIFFNESS, D_DAMPING, D_ROTOR_DAMPING, D_MOTOR_ENCODER = range(6)  # a drive row
STABLE_STEP = 0.5  # an RK4 step times the pair's fastest rate [-]: within RK4's stability and accurate to < 1e-3


def pack_drive(model) -> np.ndarray:
    """The drive row of a surrogate :class:`~.surrogate.Model` (the layout of the ``D_*`` indices): rotor inertia J
    [kg m^2], backlash b [rad], stiffness k [N m/rad] and damping c [N m s/rad] of the coupling (the tooth contact's
    without a stated stiffness), the rotor's back-EMF damping d [N m s/rad], 1 with the encoder on the motor."""
    rotor = model.rotor_share * model.arm_inertia_total
    arm = model.arm_inertia_total - rotor
    if model.drive_stiffness > 0:
        stiffness, damping = model.drive_stiffness, model.drive_damping
    else:
        stiffness, damping = tooth_contact(rotor, arm)
    encoder = float(model.drive_encoder == "motor")
    return np.array([rotor, model.drive_backlash, stiffness, damping, model.back_emf_damping, encoder])


def pack_drive_rows(models) -> tuple[np.ndarray, ...]:
    """:func:`~.surrogate_kernel.pack_rows` of ``models`` with each rigid row's arm inertia the arm side's (a - J)
    and no back-EMF on the arm (it brakes the rotor), and their drive rows (M, 6) last."""
    rigid, arm, pendulum, terms = pack_rows(models)
    drive = np.stack([pack_drive(model) for model in models])
    rigid = rigid.copy()
    rigid[:, 0] -= drive[:, D_INERTIA]
    rigid[:, 4] = 0.0
    return rigid, arm, pendulum, terms, drive


def fastest_rate(row: np.ndarray, arm_inertia: float) -> float:
    """The coupled pair's fastest rate [1/s] of a drive ``row`` against an arm side of ``arm_inertia`` [kg m^2]:
    w = sqrt(k (1 / J + 1 / J_arm)) times zeta + sqrt(zeta^2 - 1) when overdamped (zeta = c / (2 sqrt(k mu)),
    mu the pair's reduced inertia), and the rotor's back-EMF rate d / J."""
    rotor, stiffness, damping = row[D_INERTIA], row[D_STIFFNESS], row[D_DAMPING]
    reduced = rotor * arm_inertia / (rotor + arm_inertia)
    w = math.sqrt(stiffness / reduced)
    zeta = damping / (2.0 * math.sqrt(stiffness * reduced)) if stiffness > 0 else 0.0
    return max(w * max(1.0, zeta + math.sqrt(max(zeta * zeta - 1.0, 0.0))), row[D_ROTOR_DAMPING] / rotor)


def inner_steps(rigid: np.ndarray, drive: np.ndarray, dt: float) -> int:
    """RK4 steps per torque substep of ``dt`` [s] so that every step is at most ``STABLE_STEP`` over the fastest rate
    of the models' rows (:func:`pack_drive_rows`)."""
    rate = max(fastest_rate(row, arm) for row, arm in zip(drive, rigid[:, 0]))
    return max(1, int(math.ceil(dt * rate / STABLE_STEP - 1e-9)))


@njit(cache=True, inline="always")
def coupling_torque(twist, rate, drive):
    """T [N m] on the arm at the twist delta [rad] and its rate [rad/s] (:meth:`furuta_drake.drive.Coupling.torque`)."""
    b, k, c = drive[D_BACKLASH], drive[D_STIFFNESS], drive[D_DAMPING]
    if b == 0.0:
        return k * twist + c * rate
    if twist > b:
        return max(k * (twist - b) + c * rate, 0.0)
    if twist < -b:
        return min(k * (twist + b) + c * rate, 0.0)
    return 0.0


@njit(cache=True, inline="always")
def _drive_stage(y, out, phi_start, z, tau, bristles, rigid, arm, pendulum, terms, drive):
    """The state's derivative at ``y`` (6,) written to ``out`` (module docstring)."""
    coupling = coupling_torque(y[4], y[5], drive)
    out[0], out[1], out[2], out[3] = _stage(
        y[0], y[1], y[2], y[3], phi_start, z, coupling, bristles, rigid, arm, pendulum, terms
    )
    rotor = (tau - drive[D_ROTOR_DAMPING] * (y[3] + y[5]) - coupling) / drive[D_INERTIA]
    out[4], out[5] = y[5], rotor - out[3]


ENGAGEMENT_SPLIT = 16  # RK4 steps into which a step that engages the teeth is split


@njit(cache=True, inline="always")
def _rk4(s, h, slopes, y, z, tau, bristles, rigid, arm, pendulum, terms, drive):
    """One RK4 step of ``h`` [s] from the state ``s`` (6,) (changed in place); returns the arm's move."""
    weights = (0.0, 0.5, 0.5, 1.0)
    start = s[1]
    for stage in range(4):
        for j in range(6):
            y[j] = s[j] + (weights[stage] * h * slopes[stage - 1, j] if stage > 0 else 0.0)
        _drive_stage(y, slopes[stage], start, z, tau, bristles, rigid, arm, pendulum, terms, drive)
    for j in range(6):
        s[j] += h / 6.0 * (slopes[0, j] + 2.0 * slopes[1, j] + 2.0 * slopes[2, j] + slopes[3, j])
    return s[1] - start


@njit(cache=True)
def _drive_window(s, z, column, dt, inner, substeps, out, w, bristles, rigid, arm, pendulum, terms, drive):
    """One window's RK4 from the state ``s`` (6,) (changed in place) and the bristle ``z`` under the torque ``column``
    (steps,), held over each substep of ``dt`` [s] and stepped ``inner`` times in it; the angles read are written to
    ``out[:, :, w]`` every ``substeps`` substeps. Returns the final bristle.

    With backlash, a step that ends with the teeth touching where it started in the play is taken again as
    ``ENGAGEMENT_SPLIT`` shorter steps: the coupling's damping switches on at the touch, and a fixed step would place
    that impact anywhere within it (an error of the impact speed times the step in the angles that follow)."""
    h = dt / inner
    slopes, y, before = np.empty((4, 6)), np.empty(6), np.empty(6)
    motor = drive[D_MOTOR_ENCODER] != 0.0
    b = drive[D_BACKLASH]
    row, substep = 0, 0
    out[0, 0, w], out[0, 1, w] = s[0], s[1] + (s[4] if motor else 0.0)
    for i in range(column.size):
        for _ in range(inner):
            for j in range(6):
                before[j] = s[j]
            moved = _rk4(s, h, slopes, y, z, column[i], bristles, rigid, arm, pendulum, terms, drive)
            if b > 0.0 and abs(before[4]) <= b and abs(s[4]) > b:
                for j in range(6):
                    s[j] = before[j]
                moved = 0.0
                for _ in range(ENGAGEMENT_SPLIT):
                    part = _rk4(
                        s, h / ENGAGEMENT_SPLIT, slopes, y, z, column[i], bristles, rigid, arm, pendulum, terms, drive
                    )
                    if bristles:
                        z = bristle_step(z, part, part / (h / ENGAGEMENT_SPLIT), arm)
                    moved += part
            elif bristles:
                z = bristle_step(z, moved, moved / h, arm)
        substep += 1
        if substep == substeps:
            row, substep = row + 1, 0
            out[row, 0, w], out[row, 1, w] = s[0], s[1] + (s[4] if motor else 0.0)
    return z


@njit(cache=True)
def _integrate(x0, z0, torque, dt, inner, substeps, rigid, arm, pendulum, terms, drive):
    steps, width = torque.shape
    out = np.empty((steps // substeps + 1, 2, width))
    final, final_z = np.ascontiguousarray(x0).copy(), np.empty(width)
    columns = np.ascontiguousarray(torque.T)
    block = width // rigid.shape[0]
    for m in range(rigid.shape[0]):
        rigid_m, arm_m, pendulum_m = _values(rigid[m], 8), _values(arm[m], 11), _values(pendulum[m], 11)
        bristles = arm_m[F_KIND] == DAHL or arm_m[F_KIND] == LUGRE
        for w in range(m * block, (m + 1) * block):
            s = final[:, w].copy()
            final_z[w] = _drive_window(
                s,
                z0[w],
                columns[w],
                dt,
                inner,
                substeps,
                out,
                w,
                bristles,
                rigid_m,
                arm_m,
                pendulum_m,
                terms[m],
                drive[m],
            )
            final[:, w] = s
    return out, final, final_z


def integrate(x0, z0, torque, dt, substeps, rigid, arm, pendulum, terms, drive):
    """RK4 of every window from ``x0`` (6, W) (the module docstring's state) and the arm's bristle ``z0`` (W,) under
    ``torque`` (steps, W) [N m] held over each substep of ``dt`` [s], the parameters as M rows of
    :func:`pack_drive_rows`, row m for the m-th block of W / M windows. Returns (the angles read after every
    ``substeps`` substeps (steps / substeps + 1, 2, W), row 0 the start; the final states (6, W); the final bristles
    (W,))."""
    inner = inner_steps(rigid, drive, dt)
    x0 = np.ascontiguousarray(x0, dtype=float)
    return _integrate(x0, np.asarray(z0, dtype=float), torque, dt, inner, substeps, rigid, arm, pendulum, terms, drive)
