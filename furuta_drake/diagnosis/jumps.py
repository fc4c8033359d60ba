"""A line search over a parameter at which the fit's cost jumps (a threshold dead zone's width).

A threshold drops every command below it and passes larger ones whole, so with the command held over each sample
the cost is constant between two logged command magnitudes and jumps at each: its gradient is zero or undefined,
and a least-squares step from any start stalls where it began. The search instead compares costs: on the logged
command levels and the fitted value, then ``ZOOM_ROUNDS`` times on ``ZOOM_POINTS`` values between the neighbours of
the best ones (a plateau of the best cost is bracketed whole: the truth may lie at either end), keeping the best
value found.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np

ZOOM_POINTS = 9  # values per round between the best one's neighbours
ZOOM_ROUNDS = 4  # rounds: the bracket shrinks by (2 / (ZOOM_POINTS - 1)) per round


def line_search(
    cost: Callable[[np.ndarray], float],
    x: np.ndarray,
    index: int,
    low: float,
    high: float,
    levels: Sequence[float],
) -> tuple[np.ndarray, float]:
    """The parameter vector ``x`` with its entry ``index`` (within [``low``, ``high``]) moved to the best value of
    the search (module docstring), and its cost; ``levels``: the logged command magnitudes that seed it."""

    def at(value: float) -> np.ndarray:
        out = np.array(x, dtype=float)
        out[index] = value
        return out

    tried = {float(x[index]): cost(x)}

    def evaluate(values) -> None:
        for value in values:
            value = float(np.clip(value, low, high))
            if value not in tried:
                tried[value] = cost(at(value))

    evaluate([low, high, *levels])
    for _ in range(ZOOM_ROUNDS):
        grid = sorted(tried)
        lowest = min(tried.values())
        ties = [i for i, value in enumerate(grid) if tried[value] == lowest]  # a plateau of the best cost
        evaluate(np.linspace(grid[max(ties[0] - 1, 0)], grid[min(ties[-1] + 1, len(grid) - 1)], ZOOM_POINTS))
    best = min(tried, key=tried.get)
    return at(best), tried[best]
