"""A rig file for a user's own pendulum: an annotated template to start from, and the constants it implies.

``furuta-drake rig --template NAME`` prints :func:`rig_template` of a shipped rig: every key with its meaning,
unit, whether it is optional and how to measure or derive it. ``furuta-drake rig --check FILE`` prints
:func:`format_rig_check`: the lumped constants of paper Eq. 1, the linearization constants alpha1, alpha2,
beta3-beta5 of Eq. 2 at the upright, its open-loop poles, and the hanging pendulum's natural frequency with the
arm held and with the arm free, which a user compares with a pendulum-swing test on the bench; and a drive's
constants: its rotor's reflected inertia, its backlash in encoder counts and an elastic drive's resonance.
:func:`load_rig` reads a rig file strictly, its ``effects`` section checked against the effect vocabulary.
"""

from __future__ import annotations

import dataclasses
import math
import re
import textwrap
from pathlib import Path

import numpy as np
import yaml

from furuta_drake.drive import resonance
from furuta_drake.effects.vocabulary import rig_effects
from furuta_drake.errors import ConfigError, read_input_text
from furuta_drake.rig import DriveParameters, MotorParameters, RigParameters, linearized_hanging, linearized_upright
from furuta_drake.unmodelled import UnmodelledTorqueParameters
from furuta_drake.yamlio import field_description, key_lines, loads_yaml_dataclass, locate, to_plain

WIDTH = 110  # comment lines wrap here
UNMODELLED_TORQUE_EXAMPLE = UnmodelledTorqueParameters(arm="0.002*sin(7*phi)", pendulum="-1e-4*theta_dot")


def load_rig(path: str | Path) -> RigParameters:
    """The rig file, strictly (every required key present): unknown keys, non-physical values and effects the
    vocabulary does not hold raise ConfigError naming file:line:key."""
    text = read_input_text(path, "a YAML file", ConfigError)
    rig = loads_yaml_dataclass(text, RigParameters, source=str(path))
    try:
        rig_effects(rig)
    except ConfigError as err:
        raise ConfigError(locate(str(err), str(path), key_lines(yaml.compose(text, Loader=yaml.SafeLoader)))) from None
    return rig


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
        if field.name in SECTIONS:
            lines += _section_lines(field, getattr(rig, field.name))
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


# The rig file's sections: (their dataclass, how optional they are, what a rig without one is told).
SECTIONS = {
    "motor": (
        MotorParameters,
        "optional otherwise.",
        "This rig's logs are torques; for voltage logs uncomment and fill in:",
    ),
    "drive": (
        DriveParameters,
        "optional.",
        "This rig's motor turns the arm directly; for a gear or a belt uncomment and fill in:",
    ),
}


def _section_lines(field: dataclasses.Field, section) -> list[str]:
    """The lines of the section ``field`` (its keys indented), commented out with an example when ``section`` is
    None."""
    schema, optional, absent = SECTIONS[field.name]
    lines = _comment(
        f"{field.name}: {field_description(field)}; {optional}" + ("" if section is not None else f" {absent}"), ""
    )
    lines.append(f"{field.name}:" if section is not None else f"# {field.name}:")
    example = section if section is not None else schema()
    for sub in dataclasses.fields(schema):
        lines += _key_lines(sub, getattr(example, sub.name), indent="  ", comment_out=section is None)
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
        With a drive: ``rotor_inertia_reflected`` J_m N^2 [kg m^2] (part of J_arm + m r^2); with its stiffness k
        stated, ``drive_resonance`` sqrt(k (1 / J_m N^2 + 1 / J_a)) [rad/s], the rotor ringing against the arm (the
        pendulum locked, J_a = J_arm + m r^2 without the rotor), and ``drive_damping_ratio`` c / (2 sqrt(k mu)),
        mu = J_m N^2 J_a / (J_m N^2 + J_a).
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
    } | _drive_constants(rig)


def _drive_constants(rig: RigParameters) -> dict[str, float]:
    """:func:`rig_check`'s drive entries (none without a drive)."""
    if rig.drive is None:
        return {}
    rotor = rig.rotor_inertia_reflected
    out = {"rotor_inertia_reflected": rotor}
    if rig.drive.stiffness is not None:
        arm = rig.arm_inertia_total - rotor
        reduced = rotor * arm / (rotor + arm)
        out["drive_resonance"] = resonance(rig.drive, arm)
        out["drive_damping_ratio"] = rig.drive.damping / (2.0 * math.sqrt(rig.drive.stiffness * reduced))
    return out


def _drive_lines(rig: RigParameters, c: dict) -> list[str]:
    """The drive's block of ``rig --check`` (none without a drive)."""
    drive = rig.drive
    if drive is None:
        return []
    share = c["rotor_inertia_reflected"] / c["arm_inertia_total"]
    lines = [
        f"drive, arm side (the motor turns {drive.gear_ratio:g} times per arm turn):",
        f"  J_m N^2 = {c['rotor_inertia_reflected']:.6g} kg m^2  (the rotor as the arm feels it: {share:.0%} of "
        f"J_arm + m r^2)",
        f"  arm encoder on the {drive.encoder}"
        + (f" (phi is the motor's angle / {drive.gear_ratio:g})" if drive.encoder == "motor" else ""),
    ]
    if drive.backlash > 0:
        counts = 2 * drive.backlash / rig.encoder_resolution
        lines.append(
            f"  backlash +-{drive.backlash:.4g} rad = +-{math.degrees(drive.backlash):.3g} deg: the motor turns "
            f"2 b = {counts:.3g} counts of the arm before the arm follows a reversal"
        )
    if drive.stiffness is not None:
        w, nyquist = c["drive_resonance"], 0.5 / rig.sample_period
        f = w / (2 * math.pi)
        lines.append(
            f"  elastic coupling: the rotor rings against the arm (pendulum locked) at {w:.4g} rad/s = {f:.4g} Hz, "
            f"damping ratio {c['drive_damping_ratio']:.3g}"
        )
        if f >= nyquist:
            lines.append(
                f"  that is above these logs' Nyquist frequency ({nyquist:.4g} Hz): they see the coupling as a lag, "
                f"not a ringing; logging above {2 * f:.4g} Hz samples the ringing"
            )
    return lines


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
    return "\n".join(lines + _drive_lines(rig, c)) + "\n"


__all__ = ["rig_template", "rig_check", "format_rig_check"]
