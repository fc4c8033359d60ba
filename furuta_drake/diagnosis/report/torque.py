"""The unmodelled torque in the report: the ``report.json`` entry, its words for report.md, its plot, and the
expressions ``fitted_model.yaml`` and ``fitted_rig.yaml`` carry (:mod:`~furuta_drake.diagnosis.selection.missing_torque`
finds it)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from furuta_drake.diagnosis.selection.missing_torque import MissingTorque
from furuta_drake.effects.torque_library import JOINTS, TERMS, carrier, closest_effect, term_values
from furuta_drake.unmodelled import TORQUE_VARIABLES


def plot_name(joint: str) -> str:
    return f"unmodelled_torque_{joint}.png"


def torque_record(missing: MissingTorque) -> dict:
    """The ``report.json`` value of ``unmodelled_torque``: per joint with a torque its expression [N m], terms with
    coefficients and 95 % intervals, the held-out reduction of the nominal gap by the final model with the torque,
    the closest vocabulary effect and the plot's file name."""
    out = {}
    for j, joint in enumerate(JOINTS):
        rows = [(term, c, ci) for (k, term, c), ci in zip(missing.terms, missing.intervals) if k == j]
        if not rows:
            continue
        scatter = missing.scatter[joint]
        values = term_values(*scatter["state"])
        out[joint] = {
            "expression": missing.joint_expression(j),
            "terms": [{"term": TERMS[t], "coefficient": c, "ci": list(ci)} for t, c, ci in rows],
            "heldout_reduction": missing.over_nominal.reduction,
            "closest_effect": closest_effect(joint, scatter["fitted"], values),
            "plot": plot_name(joint),
        }
    return out


def beside_record(accepted: list[str], ranking: list, torque: dict) -> dict:
    """The ``report.json`` value of ``beside_torque``: the listed effects kept beside the kept torque (the
    selection's, ``accepted``), their parameters and 95 % intervals from their model's ``ranking`` entry (keys
    prefixed 'effect.' when it holds several), and the held-out reduction of the nominal gap by these effects with
    the torque; empty when no torque (``torque``: the ``unmodelled_torque`` value) or no listed effect is kept."""
    entry = next(
        (r for r in ranking if r.status == "ok" and set(r.effect.split("+")) == set(accepted)),
        None,
    )
    if not torque or not accepted or entry is None:
        return {}
    return {
        "effects": list(accepted),
        "params": dict(entry.params),
        "params_ci": dict(entry.params_ci),
        "heldout_reduction": next(iter(torque.values()))["heldout_reduction"],
    }


def _leading(entry: dict) -> dict:
    return max(entry["terms"], key=lambda t: abs(t["coefficient"]))


def torque_words(joint: str, entry: dict) -> tuple[str, str]:
    """The torque's size and leading term ("an arm torque of about 1.5 mN m varying as sin(12*phi)"), and what
    it looks like ('' when its term has no known kind)."""
    lead = _leading(entry)
    size = max(abs(t["coefficient"]) for t in entry["terms"])
    article = "an" if joint[0] in "aeiou" else "a"
    return f"{article} {joint} torque of about {size * 1e3:.2g} mN m varying as {lead['term']}", _kind(lead["term"])


def torque_sentence(joint: str, entry: dict) -> str:
    """One plain sentence: the torque's size, its leading term and what it looks like."""
    words, kind = torque_words(joint, entry)
    text = words[:1].upper() + words[1:] + (f": {kind}" if kind else "")
    if entry["closest_effect"]:
        text += f"; its shape is closest to {entry['closest_effect']}"
    return text + f" (expression `{entry['expression']}` N m)."


def _kind(term: str) -> str:
    if term == "1":
        return "a constant torque, as a tilted base or an angle zeroed off the upright gives"
    if term.startswith(("sin(", "cos(")) and "phi)" in term and "_dot" not in term:
        return "a position-periodic torque, as cogging, a cable or a tilted base gives"
    if "abs(" in term:
        return "a torque growing with the square of the speed, as air drag gives"
    if "_dot" in term and "(phi)" in term.split("*")[-1]:
        return "a friction that varies with the arm angle"
    if "theta)" in term:
        return "a torque of the pendulum angle, as an angle offset gives"
    return ""


def plot_torque(joint: str, entry: dict, scatter: dict, path: Path) -> None:
    """The torque against the variable that carries its leading term: each train window's own estimate of a
    constant torque (the data's scatter) behind the fitted torque at the same states."""
    variable = carrier(_leading(entry)["term"])
    x = scatter["state"][TORQUE_VARIABLES.index(variable)]
    order = np.argsort(x)
    fig = Figure(figsize=(6, 4))
    ax = fig.subplots()
    ax.scatter(x, scatter["estimate"] * 1e3, s=8, color="0.6", label="per-window estimate")
    ax.plot(x[order], scatter["fitted"][order] * 1e3, ".-", color="tab:red", lw=1, ms=3, label="fitted torque")
    ax.set_xlabel(f"{variable} [{'rad/s' if variable.endswith('_dot') else 'rad'}]")
    ax.set_ylabel(f"{joint} torque [mN m]")
    ax.set_title(f"Unmodelled {joint} torque: {entry['expression']}", fontsize=8)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
