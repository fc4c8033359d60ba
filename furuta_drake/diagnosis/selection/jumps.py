"""A line search over a parameter at which the fit's cost jumps (a threshold dead zone's width).

A threshold drops every command below it and passes larger ones whole, so with the command held over each sample
the cost is constant between two logged command magnitudes and jumps at each: its gradient is zero or undefined,
and a least-squares step from any start stalls where it began. The search instead compares costs: on the logged
command levels and the fitted value, then ``ZOOM_ROUNDS`` times on ``ZOOM_POINTS`` values across each edge of the
plateau of the best cost (from its end to the next value tried): a lower cost lies beyond an edge, not inside a
plateau, and the truth's own plateau may be far narrower than the plateau beside it, so the rounds spend their
values on the edges; the best value found is kept.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

ZOOM_POINTS = 5  # values per round across each edge of the best plateau, its two ends included
ZOOM_ROUNDS = 5  # rounds: each edge's bracket shrinks by 1 / (ZOOM_POINTS - 1) per round


def line_search(
    residuals: Callable[[np.ndarray], np.ndarray],
    x: np.ndarray,
    index: int,
    low: float,
    high: float,
    levels: Sequence[float],
) -> tuple[np.ndarray, float, dict[float, np.ndarray]]:
    """The parameter vector ``x`` with its entry ``index`` (within [``low``, ``high``]) moved to the best value of
    the search (module docstring), its cost (the sum of squared ``residuals``), and the residuals at every value
    tried (the profile :func:`bootstrap_argmin` resamples); ``levels``: the logged command magnitudes that seed
    it."""

    def at(value: float) -> np.ndarray:
        out = np.array(x, dtype=float)
        out[index] = value
        return out

    profile = {float(x[index]): residuals(x)}
    tried = {float(x[index]): float(np.sum(profile[float(x[index])] ** 2))}

    def evaluate(values) -> None:
        for value in values:
            value = float(np.clip(value, low, high))
            if value not in tried:
                profile[value] = residuals(at(value))
                tried[value] = float(np.sum(profile[value] ** 2))

    evaluate([low, high, *levels])
    for _ in range(ZOOM_ROUNDS):
        grid = sorted(tried)
        lowest = min(tried.values())
        ties = [i for i, value in enumerate(grid) if tried[value] == lowest]  # a plateau of the best cost
        evaluate(np.linspace(grid[max(ties[0] - 1, 0)], grid[ties[0]], ZOOM_POINTS))
        evaluate(np.linspace(grid[ties[-1]], grid[min(ties[-1] + 1, len(grid) - 1)], ZOOM_POINTS))
    best = min(tried, key=tried.get)
    return at(best), tried[best], profile


def bootstrap_argmin(
    profile: dict[float, np.ndarray], per_window: Callable, weights: np.ndarray, rng: np.random.Generator
) -> np.ndarray:
    """Bootstrap values of the searched parameter: for each row of window ``weights`` (resamples, windows), a value
    drawn uniformly between the neighbours of the values tried whose weighted cost over windows is least (the cost
    is flat between logged commands: the data place the parameter anywhere on that plateau, whose edges lie
    between the values tried). ``per_window`` maps residuals to each window's sum of squares. Where a gradient
    step cannot move the parameter, this block bootstrap of the search itself is its interval."""
    values = np.array(sorted(profile))
    costs = weights @ np.stack([per_window(profile[value]) for value in values]).T  # (resamples, values)
    best = costs <= costs.min(axis=1, keepdims=True) * (1.0 + 1e-12)
    first = np.argmax(best, axis=1)
    last = values.size - 1 - np.argmax(best[:, ::-1], axis=1)
    low, high = values[np.maximum(first - 1, 0)], values[np.minimum(last + 1, values.size - 1)]
    return rng.uniform(low, high)
