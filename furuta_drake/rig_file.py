"""A rig file for a user's own pendulum: an annotated template to start from, and the constants it implies.

``furuta-drake rig --template NAME`` prints :func:`rig_template` of a shipped rig: every key with its meaning,
unit, whether it is optional and how to measure or derive it. ``furuta-drake rig --check FILE`` prints
:func:`format_rig_check`: the lumped constants of paper Eq. 1, the linearization constants alpha1, alpha2,
beta3-beta5 of Eq. 2 at the upright, its open-loop poles, and the hanging pendulum's natural frequency with the
arm held and with the arm free, which a user compares with a pendulum-swing test on the bench.
"""

from __future__ import annotations

import dataclasses
import math
import re
import textwrap

import numpy as np
import yaml

from furuta_drake.rig import MotorParameters, RigParameters, linearized_hanging, linearized_upright
from furuta_drake.unmodelled import UnmodelledTorqueParameters
from furuta_drake.yamlio import field_description, to_plain

WIDTH = 110  # comment lines wrap here
UNMODELLED_TORQUE_EXAMPLE = UnmodelledTorqueParameters(arm="0.002*sin(7*phi)", pendulum="-1e-4*theta_dot")


def rig_template(rig: RigParameters, title: str) -> str:
    """YAML text of ``rig`` in which every key is preceded by comments giving its meaning and unit, whether it
    is optional, and how to measure it; it loads back to ``rig`` exactly. A rig without a motor gets the motor
    block commented out, and an example ``unmodelled_torque`` commented out."""
    lines = [
        f"# furuta-drake rig file: {title}.",
        "# SI units. Every key not marked optional is required. Check the constants it implies with",
        "# `furuta-drake rig --check THIS_FILE` against a pendulum-swing test on the bench.",
        "",
    ]
    for field in dataclasses.fields(RigParameters):
        if field.name == "motor":
            lines += _motor_lines(field, rig.motor)
        elif field.name == "unmodelled_torque" and rig.unmodelled_torque is None:
            lines += _key_lines(field, UNMODELLED_TORQUE_EXAMPLE, indent="", comment_out=True)
        else:
            lines += _key_lines(field, getattr(rig, field.name), indent="")
    return "\n".join(lines).rstrip() + "\n"


def _key_lines(field: dataclasses.Field, value, indent: str, comment_out: bool = False) -> list[str]:
    status = "required" if field.metadata.get("required") else f"optional (default {field.default})"
    lines = _comment(f"{field_description(field)}; {status}.", indent)
    lines += _comment(f"  How: {field.metadata['measure']}", indent)
    plain = to_plain(value)
    if isinstance(plain, dict):  # a section on one line, which stays one line when commented out
        entry = f"{field.name}: {yaml.safe_dump(plain, default_flow_style=True, sort_keys=False, width=WIDTH).strip()}"
    else:
        entry = yaml.safe_dump({field.name: plain}, default_flow_style=False).strip()
    lines.append(f"{indent}{'# ' if comment_out else ''}{entry}")
    return lines + [""]


def _motor_lines(field: dataclasses.Field, motor: MotorParameters | None) -> list[str]:
    lines = _comment(
        f"motor: {field_description(field)}; optional otherwise."
        + ("" if motor is not None else " This rig's logs are torques; for voltage logs uncomment and fill in:"),
        "",
    )
    lines.append("motor:" if motor is not None else "# motor:")
    example = motor if motor is not None else MotorParameters()
    for sub in dataclasses.fields(MotorParameters):
        lines += _key_lines(sub, getattr(example, sub.name), indent="  ", comment_out=motor is None)
    return lines


def _comment(text: str, indent: str) -> list[str]:
    """``text`` as wrapped comment lines (a unit in brackets stays on one line)."""
    lead = " " * (len(text) - len(text.lstrip()))
    unbroken = re.sub(r"\[[^\]]*\]", lambda unit: unit.group().replace(" ", "\xa0"), text.lstrip())
    return [
        line.replace("\xa0", " ")
        for line in textwrap.wrap(
            unbroken, WIDTH, initial_indent=f"{indent}# {lead}", subsequent_indent=f"{indent}#   {lead}"
        )
    ]


def rig_check(rig: RigParameters) -> dict[str, float | list[float]]:
    """The constants a rig file implies, in SI units.

    Returns
    -------
    dict
        ``arm_inertia_total`` J_arm + m r^2, ``pendulum_inertia_total`` J_p + m l^2, ``coupling`` m l r [kg m^2],
        ``gravity_torque`` m g l [N m] (Eq. 1); ``alpha1``, ``alpha2`` [1/s^2] and ``beta3``, ``beta4``,
        ``beta5`` [1/(kg m^2)] of Eq. 2 at the upright; ``upright_poles`` [rad/s], the open-loop eigenvalues
        there (real parts; 0, 0, +-p); ``hanging_arm_held`` sqrt(m g l / (J_p + m l^2)) and ``hanging_arm_free``
        (from the hanging linearization) [rad/s], the small-swing natural frequencies of the hanging pendulum.
    """
    A, B_F = linearized_upright(rig)
    A_hanging, _ = linearized_hanging(rig)
    return {
        "arm_inertia_total": rig.arm_inertia_total,
        "pendulum_inertia_total": rig.pendulum_inertia_total,
        "coupling": rig.coupling,
        "gravity_torque": rig.gravity_torque,
        "alpha1": float(A[2, 0]),
        "alpha2": float(A[3, 0]),
        "beta3": float(B_F[2, 0]),
        "beta4": float(B_F[2, 1]),
        "beta5": float(B_F[3, 1]),
        "upright_poles": sorted(float(p) for p in np.linalg.eigvals(A).real.round(12)),
        "hanging_arm_held": math.sqrt(rig.gravity_torque / rig.pendulum_inertia_total),
        "hanging_arm_free": float(np.abs(np.linalg.eigvals(A_hanging).imag).max()),
    }


def format_rig_check(rig: RigParameters, source: str) -> str:
    """:func:`rig_check` of ``rig`` (read from ``source``) as the text ``furuta-drake rig --check`` prints."""
    c = rig_check(rig)
    unstable = max(c["upright_poles"])
    lines = [
        f"{source}: the constants this rig file implies (SI units; theta 0 upright, x = [theta, phi, theta_dot, "
        f"phi_dot])",
        "lumped constants (Eq. 1):",
        f"  J_arm + m r^2 = {c['arm_inertia_total']:.6g} kg m^2  (arm with the pendulum mass at its tip)",
        f"  J_p + m l^2   = {c['pendulum_inertia_total']:.6g} kg m^2  (pendulum about its joint)",
        f"  m l r         = {c['coupling']:.6g} kg m^2  (coupling)",
        f"  m g l         = {c['gravity_torque']:.6g} N m  (gravity torque)",
        "linearization at the upright (Eq. 2):",
        f"  alpha1 = {c['alpha1']:.5g} 1/s^2, alpha2 = {c['alpha2']:.5g} 1/s^2",
        f"  beta3 = {c['beta3']:.5g}, beta4 = {c['beta4']:.5g}, beta5 = {c['beta5']:.5g} 1/(kg m^2)",
        f"  open-loop poles: {', '.join(f'{p:+.4g}' if p else '0' for p in c['upright_poles'])} rad/s "
        f"(an upright error grows "
        f"e-fold every {1 / unstable:.3g} s without control)",
        "hanging pendulum, small free swings (compare with a swing test on the bench):",
    ]
    for key, label in (("hanging_arm_held", "arm held"), ("hanging_arm_free", "arm free")):
        w = c[key]
        lines.append(f"  {label}: {w:.4g} rad/s = {w / (2 * math.pi):.4g} Hz, period {2 * math.pi / w:.4g} s")
    return "\n".join(lines) + "\n"


__all__ = ["rig_template", "rig_check", "format_rig_check"]
