"""The held-out rule that accepts an effect (stage 4 of the diagnosis).

Significance comes from the data: each held-out window contributes its own excess squared residual, so the
reduction of the held-out gap that a model brings over another is bootstrapped over windows (paired: the same
resampled windows for both). Effects enter one at a time (the first against the nominal model, each further
one fitted together with the earlier ones and judged against the model holding them), then each must earn its
place against the model holding all the others:

- a model is *at the floor* when its held-out gap is below ``FLOOR_COUNTS``: nothing more enters; it is
  *within the noise* when its gap is at the floor or below twice its own bootstrap standard error (with few
  windows, or a few large ones, a gap can be large and still not significant): the verdict is ``none`` when the
  nominal model is within the noise and no effect is accepted;
- a candidate *enters* when the 5 % lower bound of its reduction over the model holding the earlier effects
  exceeds ``ENTRY``: the candidate with the largest reduction, replaced by one with fewer parameters when that
  one is within ``PARSIMONY`` of it (at the floor, where reductions are all 1, one of another law: when its
  mean excess squared residual is not larger by more than ``FLOOR_COUNTS``^2 beyond the bootstrap interval), or
  when it is a variant of the same law that the best does not beat significantly (Coulomb before Stribeck or
  asymmetry when the data cannot tell them apart). Entry is lenient because effects mask each other: with three
  strong effects acting, none alone may explain much;
- an effect is *kept* (:func:`is_kept`) when the reduction it brings to the model holding all the other kept effects
  is at least ``MARGIN``, that reduction's 5 % lower bound exceeds ``ENTRY`` and the excess squared residual it
  removes exceeds ``FLOOR_COUNTS``^2 at its 5 % lower bound: large enough to matter, significant, and above the
  floor's resolution; the weakest one that is not is dropped, and the others judged again;
- two supported candidates of different laws are *confusable* when the 90 % bootstrap interval of the
  difference of their reductions holds 0: the data explain them equally well, and the report says so;
- the verdict is ``unexplained`` when the nominal model is not within the noise and the accepted effects together
  reduce its held-out gap by less than ``CLOSES`` (no effect or combination closes it), unless that gap is
  *negligible* (:func:`negligible`): below ``NEGLIGIBLE_COUNTS``, a small fraction of a count after the sensor's
  own variance; then the verdict is ``none`` and the report names the nearest candidate and its fit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from furuta_drake.diagnosis.candidates import CANDIDATES, law_of

FLOOR_COUNTS = 0.03
ENTRY = 0.05
MARGIN = 0.2
PARSIMONY = 0.03
CLOSES = 0.5
CONFUSABLE_LEVEL = 0.9  # two-sided level of the interval of a difference of reductions
NEGLIGIBLE_COUNTS = 0.15  # [counts] a gap left unexplained below this is no finding: its excess squared residual,
# 0.0225 counts^2, is about a quarter of the variance an ideal rounding encoder itself adds (1/12 counts^2)


def threshold_note(bootstrap: int, seed: int) -> str:
    """The acceptance rule in one paragraph, written into every report."""
    return (
        f"Held-out reductions are bootstrapped over held-out windows ({bootstrap} paired resamples, seed "
        f"{seed}). Effects enter one at a time, at most three: nothing more enters once a model's held-out gap "
        f"is below {FLOOR_COUNTS} counts; the candidate with the largest reduction over the model holding the earlier "
        f"effects enters when the 5 % lower bound of that reduction exceeds {ENTRY:.0%} (a simpler one within "
        f"{PARSIMONY:.0%} of it is preferred, or at the floor one whose mean excess squared residual is not larger "
        f"by more than {FLOOR_COUNTS}^2 counts^2 beyond a {CONFUSABLE_LEVEL:.0%} bootstrap interval; when none "
        f"enters first, the best pair of the three best train fits may enter together on the same bound); an "
        f"effect is kept when the reduction it brings to the model "
        f"holding all the other kept effects is at least {MARGIN:.0%} with a 5 % lower bound above {ENTRY:.0%} "
        f"and removes more than {FLOOR_COUNTS}^2 counts^2 of excess squared residual at its 5 % lower bound, "
        f"else the weakest is dropped; a kept effect is exchanged for one of the two best other-law candidates of "
        f"the step it entered at when the model holding that one and the other kept effects reduces the final "
        f"model's held-out gap with a 5 % lower bound above {ENTRY:.0%}; the verdict is none when no effect is "
        f"kept and the nominal gap is below {FLOOR_COUNTS} counts or twice its bootstrap standard error; "
        f"two supported candidates of different laws whose "
        f"difference of reductions has a {CONFUSABLE_LEVEL:.0%} interval holding 0 are reported as confusable; "
        f"accepted effects that together reduce the nominal gap by less than {CLOSES:.0%} leave it "
        f"unexplained, unless it is below {NEGLIGIBLE_COUNTS} counts: then the verdict is none and the nearest "
        f"candidate is named."
    )


def gap_of(per_window_excess) -> np.ndarray:
    """The gap [counts] from a mean excess squared residual [counts^2] (clipped at 0)."""
    return np.sqrt(np.maximum(per_window_excess, 0.0))


@dataclass(frozen=True)
class Evidence:
    """One model's held-out figures against a reference model: point reduction and its 5 % lower bound."""

    heldout_gap: float  # [counts]
    reduction: float  # 1 - gap / gap(reference)
    lower_bound: float  # 5 % bootstrap lower bound of the reduction
    excess: float  # mean excess squared residual [counts^2], ties below the floor
    excess_drop: float  # 5 % bootstrap lower bound of the excess squared residual removed [counts^2]


class Bootstrap:
    """Paired resamples of the held-out windows, drawn once (seeded) and shared by every comparison."""

    def __init__(self, windows: int, resamples: int, seed: int):
        self.index = np.random.default_rng(seed).integers(0, windows, (resamples, windows))

    def means(self, per_window: np.ndarray) -> np.ndarray:
        """Bootstrap values of the mean excess squared residual [counts^2]."""
        return per_window[self.index].mean(axis=1)

    def reductions(self, reference: np.ndarray, candidate: np.ndarray) -> np.ndarray:
        """Bootstrap values of 1 - gap(candidate) / gap(reference)."""
        return _reductions(self.means(reference), self.means(candidate))

    def evidence(self, reference: np.ndarray, candidate: np.ndarray) -> Evidence:
        point = 1.0 - gap_of(candidate.mean()) / max(float(gap_of(reference.mean())), 1e-12)
        before, after = self.means(reference), self.means(candidate)
        return Evidence(
            float(gap_of(candidate.mean())),
            float(point),
            float(np.quantile(_reductions(before, after), 0.05)),
            float(candidate.mean()),
            _interval(before - after)[0],
        )

    def within_noise(self, per_window: np.ndarray) -> bool:
        """The model of ``per_window`` explains the data to within their noise: its gap is below ``FLOOR_COUNTS``
        or twice its bootstrap standard error (module docstring)."""
        gap = float(gap_of(per_window.mean()))
        return at_floor(per_window) or gap < 2.0 * float(np.std(gap_of(self.means(per_window))))

    def excess_difference_interval(self, first: np.ndarray, second: np.ndarray) -> tuple[float, float]:
        """The ``CONFUSABLE_LEVEL`` interval of the mean excess squared residual of ``first`` minus that of
        ``second`` [counts^2]: what tells models apart when both gaps are clipped at the floor."""
        return _interval(self.means(first) - self.means(second))

    def beats_at_floor(self, better: np.ndarray, worse: np.ndarray) -> bool:
        """Whether the model of ``better`` explains the data beyond doubt better than that of ``worse`` where
        reductions cannot tell (both at the floor): :func:`beyond_resolution` of the excess it removes."""
        return beyond_resolution(self.excess_difference_interval(worse, better)[0])

    def difference_interval(self, reference: np.ndarray, first: np.ndarray, second: np.ndarray) -> tuple[float, float]:
        """The ``CONFUSABLE_LEVEL`` interval of reduction(first) - reduction(second), both over ``reference``."""
        return _interval(self.reductions(reference, first) - self.reductions(reference, second))


def _reductions(before: np.ndarray, after: np.ndarray) -> np.ndarray:
    """1 - gap(after) / gap(before) of resampled mean excesses."""
    return 1.0 - gap_of(after) / np.maximum(gap_of(before), 1e-12)


def _interval(values: np.ndarray) -> tuple[float, float]:
    """The two-sided ``CONFUSABLE_LEVEL`` interval of bootstrap ``values``."""
    tail = 0.5 * (1.0 - CONFUSABLE_LEVEL)
    return float(np.quantile(values, tail)), float(np.quantile(values, 1.0 - tail))


def negligible(gap: float) -> bool:
    """Whether a held-out gap [counts] (after the sensor's own variance) is too small to matter:
    below ``NEGLIGIBLE_COUNTS``."""
    return gap < NEGLIGIBLE_COUNTS


def at_floor(per_window: np.ndarray) -> bool:
    """The model of ``per_window`` has a gap below ``FLOOR_COUNTS``: nothing is left to explain."""
    return float(gap_of(per_window.mean())) < FLOOR_COUNTS


def n_params(name: str) -> int:
    """Fitted parameters of a candidate ('a+b' counts both), in its first form."""
    return sum(len(CANDIDATES[part].params) for part in name.split("+"))


def order(evidence: dict[str, Evidence]) -> list[str]:
    """Candidates best first: the larger reduction, then (two models at the floor both reduce by 1) the smaller
    excess residual before the square root's clip, then fewer parameters, then the name."""
    return sorted(evidence, key=lambda name: (-evidence[name].reduction, evidence[name].excess, n_params(name), name))


def choose(
    evidence: dict[str, Evidence],
    new: dict[str, str],
    margin: float = MARGIN,
    previous: np.ndarray | None = None,
    per_window: dict[str, np.ndarray] | None = None,
    bootstrap: Bootstrap | None = None,
) -> str | None:
    """The candidate among ``evidence`` (over the ``previous`` model) whose reduction's lower bound exceeds
    ``margin``: the best, or a simpler one within ``PARSIMONY`` of it or, when it is a variant of the best one's
    law, one the best does not beat beyond the ``CONFUSABLE_LEVEL`` interval of their difference (given the
    per-window excesses and the bootstrap). When the best is at the floor, where every reduction is 1, a simpler
    one of another law must instead not be beaten there (:meth:`Bootstrap.beats_at_floor`; a viscous friction
    standing in for a small Coulomb friction sits at the floor too, but measurably further from the data).
    None when none is. ``new``: each candidate's added effect, whose
    parameters the parsimony rule counts."""
    supported = [name for name in order(evidence) if evidence[name].lower_bound > margin]
    if not supported:
        return None
    best = supported[0]

    def as_good(name):
        same_law = new[name] in law_of(new[best])
        if bootstrap is not None and at_floor(per_window[best]) and not same_law:  # reductions are 1 there
            return not bootstrap.beats_at_floor(per_window[best], per_window[name])
        if evidence[name].reduction >= evidence[best].reduction - PARSIMONY:
            return True
        if bootstrap is None or not same_law:
            return False
        return bootstrap.difference_interval(previous, per_window[best], per_window[name])[0] <= 0.0

    simpler = [name for name in supported if n_params(new[name]) < n_params(new[best]) and as_good(name)]
    return min(simpler, key=lambda name: (n_params(new[name]), -evidence[name].reduction)) if simpler else best


def beyond_resolution(excess_drop: float) -> bool:
    """Whether a removed excess squared residual's lower bound [counts^2] exceeds ``FLOOR_COUNTS``^2, the floor's
    own resolution: each window's initial states are refitted per model (a hidden bristle state too), and the
    surrogate's friction differs slightly from a real or simulated one, so below it a richer model or a tiny extra
    effect fits what no effect explains."""
    return excess_drop > FLOOR_COUNTS**2


def is_kept(evidence: Evidence) -> bool:
    """Whether an effect whose removal costs ``evidence`` earns its place: a reduction of at least ``MARGIN`` of
    the gap of the model without it, with a 5 % lower bound above ``ENTRY`` (a second effect beside a strong
    first one shares a small remaining gap, so its bound is wide even when its size is clear), removing more
    excess squared residual than the floor resolves (:func:`beyond_resolution`: a small remaining gap's large
    relative reductions are no evidence below it)."""
    return evidence.reduction >= MARGIN and evidence.lower_bound > ENTRY and beyond_resolution(evidence.excess_drop)


def confusable(
    chosen: str,
    evidence: dict[str, Evidence],
    new: dict[str, str],
    previous: np.ndarray,
    per_window: dict[str, np.ndarray],
    bootstrap: Bootstrap,
) -> list[dict]:
    """The supported candidates of other laws that explain the held-out data as well as ``chosen``, each as
    ``{"effects": [chosen's effect, other's effect], "why": ...}``."""
    out = []
    for name in order(evidence):
        if name == chosen or not is_kept(evidence[name]) or new[name] in law_of(new[chosen]):
            continue
        if at_floor(per_window[chosen]):  # both reductions are 1 there: the excess residuals tell them apart
            low, high = bootstrap.excess_difference_interval(per_window[name], per_window[chosen])
            alike = not beyond_resolution(low)
            difference = (
                f"mean excess squared residuals, [{low:+.3g}, {high:+.3g}] counts^2, stays below the floor's "
                f"resolution ({FLOOR_COUNTS}^2 counts^2)"
            )
        else:
            low, high = bootstrap.difference_interval(previous, per_window[chosen], per_window[name])
            alike = low <= 0.0 <= high
            difference = f"reductions, [{100 * low:+.1f}, {100 * high:+.1f}] points, holds 0"
        if alike:
            out.append(
                {
                    "effects": [new[chosen], new[name]],
                    "why": (
                        f"held-out reductions {evidence[chosen].reduction:.1%} ({new[chosen]}) and "
                        f"{evidence[name].reduction:.1%} ({new[name]}): the {CONFUSABLE_LEVEL:.0%} bootstrap interval "
                        f"of the difference of their {difference}"
                    ),
                }
            )
    return out
