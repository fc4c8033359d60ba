"""The decision: which effect (or pair) the held-out data support, ``none``, or ``unexplained``.

Significance comes from the data: each held-out window contributes its own excess squared residual, so the
held-out gap reduction of a candidate is bootstrapped over windows (paired: the same resampled windows for
the nominal and the candidate). The threshold rule, written into every report:

- ``none`` when the nominal held-out gap is at the floor: below ``FLOOR_COUNTS`` or below twice its own
  bootstrap standard error (the nominal model already explains the data to within their noise);
- a candidate is *supported* when the 5 % lower bound of its reduction exceeds ``MARGIN``; the verdict is the
  supported candidate with the largest reduction, replaced by one with fewer parameters when that one is
  within ``PARSIMONY`` of it (Coulomb before Stribeck or asymmetry when the data cannot tell them apart);
- a pair is accepted instead when it removes at least ``PAIR_GAIN`` of the gap its best member leaves, with the
  5 % bound of that extra reduction above ``MARGIN``, and adds at least ``PAIR_MIN_GAIN`` to the reduction
  from nominal (a pair cannot win by shaving a gap already at the floor);
- ``unexplained`` when the nominal gap is above the floor and no candidate or pair is supported with a
  point reduction of at least ``CLOSES``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from furuta_drake.diagnosis.candidates import CANDIDATES

FLOOR_COUNTS = 0.25
MARGIN = 0.2
PARSIMONY = 0.03
PAIR_GAIN = 0.4
PAIR_MIN_GAIN = 0.05
CLOSES = 0.5
BOOTSTRAP = 1000
THRESHOLD_NOTE = (
    f"Held-out reductions are bootstrapped over held-out windows ({BOOTSTRAP} paired resamples, seed 0). "
    f"The nominal model is at the floor (verdict none) when its held-out gap is below {FLOOR_COUNTS} counts or "
    f"twice its bootstrap standard error. A candidate is supported when the 5 % lower bound of its reduction "
    f"exceeds {MARGIN:.0%}; among supported candidates a simpler one within {PARSIMONY:.0%} of the best wins; a "
    f"pair must remove {PAIR_GAIN:.0%} of the gap its best member leaves, with a lower bound above {MARGIN:.0%}, and add {PAIR_MIN_GAIN:.0%} to the reduction; "
    f"a best reduction under {CLOSES:.0%} leaves the "
    f"gap unexplained.")


def _gap(per_window: np.ndarray) -> np.ndarray:
    return np.sqrt(np.maximum(per_window, 0.0))


def bootstrap_reduction(nominal: np.ndarray, candidate: np.ndarray, seed: int = 0) -> tuple[float, float]:
    """Point reduction 1 - gap/gap_nominal and its 5 % bootstrap lower bound (paired over windows)."""
    point = 1.0 - _gap(candidate.mean()) / max(_gap(nominal.mean()), 1e-12)
    rng = np.random.default_rng(seed)
    index = rng.integers(0, nominal.size, (BOOTSTRAP, nominal.size))
    boot = 1.0 - _gap(candidate[index].mean(axis=1)) / np.maximum(_gap(nominal[index].mean(axis=1)), 1e-12)
    return float(point), float(np.quantile(boot, 0.05))


def nominal_at_floor(nominal: np.ndarray, seed: int = 0) -> bool:
    gap = float(_gap(nominal.mean()))
    rng = np.random.default_rng(seed)
    index = rng.integers(0, nominal.size, (BOOTSTRAP, nominal.size))
    spread = float(np.std(_gap(nominal[index].mean(axis=1))))
    return gap < FLOOR_COUNTS or gap < 2.0 * spread


@dataclass
class Decision:
    verdict: str
    effects: list[str]
    accepted: str | None  # the ranking name of the accepted candidate or pair
    ranking: list[dict] = field(default_factory=list)


def n_params(name: str) -> int:
    return sum(len(CANDIDATES[part].params) for part in name.split("+"))


def rank(nominal: np.ndarray, candidates: dict[str, np.ndarray]) -> list[dict]:
    """Every candidate's held-out gap, reduction and evidence (lower bound), best first."""
    rows = []
    for name, per_window in candidates.items():
        point, low = bootstrap_reduction(nominal, per_window)
        rows.append({"name": name, "heldout_gap": float(_gap(per_window.mean())), "heldout_reduction": point,
                     "evidence": low, "excess": float(per_window.mean())})
    # Ties (two models both at the floor: a reduction of 1) go to the smaller excess residual before the square
    # root's clip at zero, then to fewer parameters.
    return sorted(rows, key=lambda row: (-row["heldout_reduction"], row["excess"], n_params(row["name"]),
                                         row["name"]))


def best_single(ranking: list[dict]) -> dict | None:
    supported = [row for row in ranking if "+" not in row["name"] and row["evidence"] > MARGIN]
    if not supported:
        return None
    best = supported[0]
    simpler = [row for row in supported if n_params(row["name"]) < n_params(best["name"])
               and row["heldout_reduction"] >= best["heldout_reduction"] - PARSIMONY]
    return min(simpler, key=lambda row: (n_params(row["name"]), -row["heldout_reduction"])) if simpler else best


def decide(nominal: np.ndarray, candidates: dict[str, np.ndarray]) -> Decision:
    """The verdict from per-window held-out excess residuals of the nominal model and every candidate (single
    names and 'a+b' pairs)."""
    ranking = rank(nominal, candidates)
    if nominal_at_floor(nominal):
        return Decision("none", [], None, ranking)
    single = best_single(ranking)
    chosen = single
    if single is not None:
        for row in ranking:
            if "+" not in row["name"] or single["name"] not in row["name"].split("+"):
                continue
            extra, extra_low = bootstrap_reduction(candidates[single["name"]], candidates[row["name"]])
            gained = row["heldout_reduction"] - single["heldout_reduction"]
            if extra >= PAIR_GAIN and extra_low > MARGIN and gained >= PAIR_MIN_GAIN:
                chosen = row
                break
    if chosen is None or chosen["heldout_reduction"] < CLOSES:
        return Decision("unexplained", [], None, ranking)
    effects = chosen["name"].split("+")
    if len(effects) > 1:  # the verdict names the stronger member
        strength = {row["name"]: row["heldout_reduction"] for row in ranking}
        effects.sort(key=lambda name: -strength.get(name, 0.0))
    return Decision(effects[0], effects, chosen["name"], ranking)
