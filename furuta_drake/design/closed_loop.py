"""The sizes of actuator effects that change the rig's closed loop, from the margins of its own LQR, and the
detection limits a design targets when a diagnosis has no rival.

With u = -K x on the upright linearisation (A, B), the loop broken at the plant input is L(s) = K (sI - A)^-1 B.
Its margins against the actuator effects of the vocabulary:

- **delay**: the smallest tau with 1 + L(jw) e^(-jw tau) = 0, i.e. at a crossover |L(jw)| = 1,
  tau = ((arg L(jw) + pi) mod 2 pi) / w;
- **lag**: the smallest time constant T of 1 / (T s + 1) in the loop that leaves an eigenvalue of the augmented
  closed loop [[A, B], [-K / T, -1 / T]] in the right half plane (bisection);
- **gain**: the smallest gain g < 1 on the command with A - g B K still stable (bisection).

An effect a ``CLOSED_LOOP_SHARE`` of the way to its margin changes how the loop behaves (its damping, its
overshoot) without destabilising it: that is the size a diagnosis should be able to see.
"""

from __future__ import annotations

import numpy as np

from furuta_drake.design.choice import shortfall
from furuta_drake.effects.vocabulary import law_of
from furuta_drake.rig import RigParameters, linearized_upright

CLOSED_LOOP_SHARE = 0.1  # of a margin: an effect this far towards instability changes the closed loop
BISECTION_STEPS = 60


def _stable(matrix: np.ndarray) -> bool:
    return bool(np.max(np.linalg.eigvals(matrix).real) < 0.0)


def delay_margin(A: np.ndarray, B: np.ndarray, K: np.ndarray, frequencies: np.ndarray | None = None) -> float:
    """The smallest input delay [s] that destabilises u = -K x (module docstring); inf without a crossover."""
    w = np.geomspace(1e-2, 1e4, 20001) if frequencies is None else frequencies
    resolvent = 1j * w[:, None, None] * np.eye(A.shape[0]) - A
    loop = (K @ np.linalg.solve(resolvent, np.broadcast_to(B, (w.size, *B.shape))))[:, 0, 0]
    gain = np.abs(loop) - 1.0
    crossings = np.nonzero(np.sign(gain[:-1]) != np.sign(gain[1:]))[0]
    margins = []
    for i in crossings:
        t = gain[i] / (gain[i] - gain[i + 1])  # linear interpolation of the crossover
        wc = w[i] + t * (w[i + 1] - w[i])
        phase = np.angle(loop[i]) + t * (np.angle(loop[i + 1] * np.conj(loop[i])))
        margins.append(np.mod(phase + np.pi, 2.0 * np.pi) / wc)
    return float(min(margins)) if margins else float("inf")


def lag_margin(A: np.ndarray, B: np.ndarray, K: np.ndarray, longest: float = 10.0) -> float:
    """The smallest first-order lag time constant [s] in the loop that destabilises it; inf if none up to
    ``longest``."""

    def stable(T: float) -> bool:
        top = np.hstack([A, B])
        bottom = np.hstack([-K / T, [[-1.0 / T]]])
        return _stable(np.vstack([top, bottom]))

    if stable(longest):
        return float("inf")
    low, high = 1e-9, longest
    for _ in range(BISECTION_STEPS):
        middle = np.sqrt(low * high)
        low, high = (middle, high) if stable(middle) else (low, middle)
    return float(low)


def gain_margin(A: np.ndarray, B: np.ndarray, K: np.ndarray) -> float:
    """The smallest command gain g in (0, 1] that keeps A - g B K stable (0 when every positive gain does)."""
    if _stable(A - 1e-9 * B @ K):
        return 0.0
    low, high = 1e-9, 1.0
    for _ in range(BISECTION_STEPS):
        middle = 0.5 * (low + high)
        low, high = (low, middle) if _stable(A - middle * B @ K) else (middle, high)
    return float(high)


def closed_loop_sizes(rig: RigParameters, K: np.ndarray) -> dict[str, float]:
    """Per actuator effect, the size (as ``detection_limits`` states it) that changes the closed loop of ``K`` on
    the rig: ``CLOSED_LOOP_SHARE`` of the way to each margin."""
    A, B_F = linearized_upright(rig)
    B = B_F[:, [1]]  # the arm-torque input
    K = np.asarray(K, dtype=float).reshape(1, 4)
    return {
        "input_delay": CLOSED_LOOP_SHARE * delay_margin(A, B, K),
        "actuator_lag": CLOSED_LOOP_SHARE * lag_margin(A, B, K),
        "torque_gain_error": 1.0 - CLOSED_LOOP_SHARE * (1.0 - gain_margin(A, B, K)),
    }


def limited_targets(report: dict, sizes: dict[str, float]) -> list[tuple[str, float]]:
    """The (effect, size) targets of a diagnosis limited by what its logs can see: every effect of ``sizes`` not
    accepted (nor a variant of an accepted law) whose detection limit is above that size or was not reached."""
    accepted = {step["effect"] for step in report.get("steps") or []}
    limits = {limit["effect"]: limit["value"] for limit in report.get("detection_limits") or []}
    out = []
    for name, size in sizes.items():
        if not np.isfinite(size) or law_of(name) & accepted or name not in limits:
            continue
        if not reaches(name, limits[name], size):
            out.append((name, float(size)))
    return out


def reaches(name: str, limit: float | None, size: float) -> bool:
    """Whether a detection limit of effect ``name`` (None: not reached) detects it at ``size``, both as
    ``detection_limits`` states them: a gain's or an inertia scale's distance from 1 at most the size's, other
    sizes' from 0; a saturation limit at most the largest limit detected (its shortfall at most 1)."""
    return shortfall(name, limit, size) <= 1
