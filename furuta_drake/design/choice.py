"""Which experiment brings the targeted detection limits lowest, and the duration a target would need.

When the design targets detection limits and the mode or the duration is left to it, every candidate experiment
(open loop from hanging, a dither on the LQR balancing; each at the durations compared) is played in Drake and
its detection limits predicted (:mod:`furuta_drake.design.limits`). A candidate's **shortfall** on a target is its
predicted limit over the target's size, both measured from the effect's neutral value (1 for a gain or inertia
scale, 0 otherwise; the size over the limit for a saturation, whose larger limits detect more); a limit not
reached counts as infinite. The chosen candidate is the shortest that brings every target to its size (every
shortfall at most 1: a lab's time is the cost, and a limit further below the size buys nothing the verdict
needs), the open loop first; when none does, the one of smallest worst shortfall over the targets, then the
smallest next one, and so on, ties going to the shorter experiment, then to the open loop.

A target that the chosen experiment leaves above its size gets the duration the chosen mode's limits
extrapolate to: the shortfall fitted as a power of the duration, ``shortfall = c T^b``, over the mode's
candidates that reach a limit, solved for a shortfall of 1; none when the shortfall does not fall with the
duration (b >= 0) or fewer than two durations reach a limit.
"""

from __future__ import annotations

import math

import numpy as np

MODES = ("hanging", "balancing")  # the order of the tie-break: the open loop first


def shortfall(name: str, limit: float | None, size: float) -> float:
    """The predicted ``limit`` of effect ``name`` over the target ``size`` (module docstring); inf when not
    reached; at most 1 exactly when the limit detects the effect at that size."""
    if limit is None:
        return math.inf
    if name == "actuator_saturation":
        return size / limit if limit > 0 else math.inf
    neutral = 1.0 if name in ("torque_gain_error", "inertia_mismatch") else 0.0
    distance, wanted = abs(limit - neutral), abs(size - neutral)
    if wanted == 0:
        return 1.0 if distance == 0 else math.inf
    return distance / wanted


def ranking_key(candidate: dict) -> tuple:
    """The order of the choice: the shortfalls, worst first, each counted as 1 where it reaches the size (all
    candidates that reach every size tie there), then the duration, then the open loop first."""
    shortfalls = sorted((shortfall(t["effect"], t["predicted"], t["size"]) for t in candidate["limits"]), reverse=True)
    return tuple(max(s, 1.0) for s in shortfalls), candidate["duration_s"], MODES.index(candidate["mode"])


def chosen(candidates: list[dict]) -> int:
    """The index of the chosen candidate among ``candidates`` (``{mode, duration_s, limits}``, ``limits`` as
    ``design.json``'s ``detection_limits``; a candidate with ``status`` other than ``design`` is never chosen);
    None when none is a design."""
    usable = [i for i, c in enumerate(candidates) if c.get("status", "design") == "design"]
    return min(usable, key=lambda i: ranking_key(candidates[i])) if usable else None


def duration_reaching(durations: list[float], shortfalls: list[float]) -> tuple[float | None, float | None]:
    """``(b, T)``: the exponent of ``shortfall = c T^b`` fitted (least squares in logs) to the finite
    ``shortfalls`` at ``durations``, and the duration [s] at which it reaches 1; (None, None) when fewer than two
    durations reach a limit, (b, None) when it does not fall with the duration."""
    points = [(d, s) for d, s in zip(durations, shortfalls) if math.isfinite(s) and s > 0]
    if len({d for d, _ in points}) < 2:
        return None, None
    logs = np.log(np.asarray(points))
    slope, intercept = np.polyfit(logs[:, 0], logs[:, 1], 1)
    return float(slope), float(np.exp(-intercept / slope)) if slope < 0 else None


def longer_experiments(candidates: list[dict], choice: int) -> list[dict]:
    """Per target the chosen candidate leaves above its size: its size, the chosen mode's durations and predicted
    limits, the fitted exponent and the duration they extrapolate to (None: no duration does)."""
    mode = candidates[choice]["mode"]
    same = sorted(
        (c for c in candidates if c["mode"] == mode and c["status"] == "design"), key=lambda c: c["duration_s"]
    )
    out = []
    for index, target in enumerate(candidates[choice]["limits"]):
        if shortfall(target["effect"], target["predicted"], target["size"]) <= 1:
            continue
        durations = [c["duration_s"] for c in same]
        limits = [c["limits"][index]["predicted"] for c in same]
        exponent, reaching = duration_reaching(
            durations, [shortfall(target["effect"], v, target["size"]) for v in limits]
        )
        out.append(
            {
                "effect": target["effect"],
                "param": target["param"],
                "unit": target["unit"],
                "size": target["size"],
                "mode": mode,
                "durations_s": durations,
                "predicted": limits,
                "exponent": exponent,
                "duration_reaching_size_s": reaching,
            }
        )
    return out


def choice_record(candidates: list[dict], choice: int | None) -> dict:
    """``design.json``'s ``choice``: the criterion, every candidate with its predicted limits and shortfalls,
    why the chosen one was, and what longer experiments of its mode would reach."""
    listed = [
        {
            "mode": c["mode"],
            "duration_s": c["duration_s"],
            "status": c["status"],
            "reason": c["reason"],
            "detection_limits": [
                {
                    "effect": t["effect"],
                    "predicted": t["predicted"],
                    "shortfall": shortfall(t["effect"], t["predicted"], t["size"]),
                }
                for t in c["limits"]
            ],
            "chosen": i == choice,
        }
        for i, c in enumerate(candidates)
    ]
    return {
        "criterion": CRITERION,
        "candidates": listed,
        "why": _why(candidates, choice),
        "longer": [] if choice is None else longer_experiments(candidates, choice),
    }


CRITERION = (
    "the shortest candidate whose shortfalls (predicted detection limit over the target's size, from the "
    "effect's neutral value; not reached: infinite) are all at most 1, the open loop first; when none is, the "
    "smallest worst shortfall over the targets, then the next worst; ties: the shorter, then the open loop"
)


def _why(candidates: list[dict], choice: int | None) -> str:
    if choice is None:
        return "no candidate is a design within the bounds"
    best = candidates[choice]
    rivals = sorted((c for i, c in enumerate(candidates) if i != choice and c["status"] == "design"), key=ranking_key)
    text = f"{_named(best)}: worst shortfall {_worst(best):.3g}"
    if _worst(best) <= 1.0:
        return text + ", the shortest candidate that brings every target to its size"
    if not rivals:
        return text + ", the only candidate within the bounds"
    tie = ranking_key(rivals[0])[0] == ranking_key(best)[0]
    text += f", against {_worst(rivals[0]):.3g} for the next, {_named(rivals[0])}"
    return text + (" (a tie, broken by the duration, then the open loop)" if tie else "")


def _named(candidate: dict) -> str:
    mode = "open loop from hanging" if candidate["mode"] == "hanging" else "a dither on the LQR balancing"
    return f"{mode}, {candidate['duration_s']:g} s"


def _worst(candidate: dict) -> float:
    return max(shortfall(t["effect"], t["predicted"], t["size"]) for t in candidate["limits"])
