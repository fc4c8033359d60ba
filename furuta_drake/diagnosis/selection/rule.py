"""The held-out rule that accepts an effect (stage 4 of the diagnosis): every threshold it uses (:data:`THRESHOLDS`,
each with its unit and meaning) and :func:`decide`, the one judgement of an effect that the selection, the detection
limits and the experiment design share.

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
  difference of their reductions holds 0, or when one removes no more excess squared residual than the other
  beyond ``FLOOR_COUNTS``^2 at its 5 % bound (at the floor, and beside a small remaining gap, where relative
  reductions magnify differences the floor does not resolve): the data explain them equally well, and the report
  says so;
- beside a sensor effect that passes its signature test (noise, a coarse encoder), every comparison above reads each
  window's excess beyond the variance that sensor adds (:meth:`Bootstrap.beyond`): it is the same in every model, so
  on the whole gap a dynamic effect under it would remove too small a share to be judged; the reductions reported
  over the nominal model read the whole gap (:meth:`Bootstrap.whole`);
- the verdict is ``unexplained`` when the nominal model is not within the noise and the accepted effects together
  reduce its held-out gap by less than ``CLOSES`` (no effect or combination closes it), unless that gap is
  *negligible* (:func:`negligible`): below ``NEGLIGIBLE_COUNTS``, a small fraction of a count after the sensor's
  own variance; then the verdict is ``none`` and the report names the nearest candidate and its fit.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from furuta_drake.effects.vocabulary import CANDIDATES, NULL_TOLERANCE, law_of

FLOOR_COUNTS = 0.03
ENTRY = 0.05
MARGIN = 0.2
PARSIMONY = 0.03
CLOSES = 0.5
CONFUSABLE_LEVEL = 0.9
LOWER_BOUND_QUANTILE = 0.05
NOISE_STANDARD_ERRORS = 2.0
LEVEL_EXCESS = 0.1
NEAR = 0.05
NEGLIGIBLE_COUNTS = 0.15
IMPLAUSIBLE_SCALE = 2.0
INTERVAL_INFLATION = 1.5


@dataclass(frozen=True)
class Threshold:
    """A number of the rule, with its unit ("" for a fraction, "factor" for a ratio) and what it decides."""

    name: str
    value: float
    unit: str
    meaning: str


THRESHOLDS = (
    Threshold("FLOOR_COUNTS", FLOOR_COUNTS, "counts", "a held-out gap below it leaves nothing to explain"),
    Threshold("ENTRY", ENTRY, "", "the 5 % lower bound of a reduction must exceed it for an effect to enter"),
    Threshold("MARGIN", MARGIN, "", "the reduction an effect brings beside the others it must reach to be kept"),
    Threshold("PARSIMONY", PARSIMONY, "", "a simpler candidate within this of the best reduction is preferred"),
    Threshold("CLOSES", CLOSES, "", "accepted effects reducing the nominal gap by less leave it unexplained"),
    Threshold("CONFUSABLE_LEVEL", CONFUSABLE_LEVEL, "", "two-sided level of the interval of a difference"),
    Threshold("LOWER_BOUND_QUANTILE", LOWER_BOUND_QUANTILE, "", "the bootstrap quantile of a lower bound"),
    Threshold(
        "NOISE_STANDARD_ERRORS", NOISE_STANDARD_ERRORS, "", "a gap below this many standard errors is within the noise"
    ),
    Threshold("LEVEL_EXCESS", LEVEL_EXCESS, "", "two friction levels within this fraction are one (no Stribeck part)"),
    Threshold("NEAR", NEAR, "", "a rival within this of the accepted reduction is a close rival (the design)"),
    Threshold(
        "NEGLIGIBLE_COUNTS",
        NEGLIGIBLE_COUNTS,
        "counts",
        "a gap left unexplained below it is no finding: its excess squared residual (0.0225 counts^2) is about a "
        "quarter of a rounding encoder's own variance (1/12 counts^2), so the verdict is none",
    ),
    Threshold(
        "IMPLAUSIBLE_SCALE",
        IMPLAUSIBLE_SCALE,
        "factor",
        "an inertia scale beyond this factor either way is a stand-in (rig files state masses and lengths to a few "
        "per cent): the torque beyond the vocabulary is tried in its place",
    ),
    Threshold(
        "NULL_TOLERANCE",
        NULL_TOLERANCE,
        "",
        "an effect whose size parameters all lie within this fraction of their search range from the values at which "
        "it vanishes is at zero size: it removes nothing and is never entered, exchanged in or paired",
    ),
    Threshold(
        "INTERVAL_INFLATION",
        INTERVAL_INFLATION,
        "factor",
        "the accepted model's bootstrap intervals are inflated about the fitted value by this factor (then widened "
        "by the rival's shift): calibrated so that 95 % intervals cover known parameters 90-99 % of the time with "
        "and without a small second effect below its detection limit",
    ),
)


def gap_of(per_window_excess) -> np.ndarray:
    """The gap [counts] from a mean excess squared residual [counts^2] (clipped at 0)."""
    return np.sqrt(np.maximum(per_window_excess, 0.0))


@dataclass(frozen=True)
class Comparison:
    """One model's held-out figures against a reference model: point reduction and its 5 % lower bound."""

    heldout_gap: float  # [counts]
    reduction: float  # 1 - gap / gap(reference)
    lower_bound: float  # 5 % bootstrap lower bound of the reduction
    excess: float  # mean excess squared residual [counts^2], ties below the floor
    excess_drop: float  # 5 % bootstrap lower bound of the excess squared residual removed [counts^2]


class Bootstrap:
    """Paired resamples of the held-out windows, drawn once (seeded) and shared by every comparison.

    ``sensor`` (per window [counts^2], default none): a variance a sensor effect adds to every residual, taken off
    each window's excess before any figure is read, so that the models are judged on the gap beyond that sensor
    (:class:`~furuta_drake.diagnosis.selection.stepwise.Stepwise` judges the dynamic effects so beside a sensor
    effect that passed its signature test; every reported reduction is read without it)."""

    def __init__(self, windows: int, resamples: int, seed: int, sensor: np.ndarray | None = None):
        self.index = np.random.default_rng(seed).integers(0, windows, (resamples, windows))
        self.sensor = np.zeros(windows) if sensor is None else np.asarray(sensor, dtype=float)

    def beyond(self, sensor: np.ndarray) -> Bootstrap:
        """The same resamples judging the gap beyond the variance ``sensor`` (per window [counts^2])."""
        out = Bootstrap.__new__(Bootstrap)
        out.index, out.sensor = self.index, np.asarray(sensor, dtype=float)
        return out

    def whole(self) -> Bootstrap:
        """The same resamples reading the whole gap (the rig file's own sensor alone taken off): what every reported
        reduction over the nominal model reads."""
        return self.beyond(np.zeros_like(self.sensor))

    def judged(self, per_window: np.ndarray) -> np.ndarray:
        """Each window's excess squared residual beyond the sensor's variance [counts^2]."""
        return per_window - self.sensor

    def means(self, per_window: np.ndarray) -> np.ndarray:
        """Bootstrap values of the mean of a per-window figure (an excess squared residual [counts^2], a score)."""
        return per_window[self.index].mean(axis=1)

    def reductions(self, reference: np.ndarray, candidate: np.ndarray) -> np.ndarray:
        """Bootstrap values of 1 - gap(candidate) / gap(reference), beyond the sensor's variance."""
        return _reductions(self.means(self.judged(reference)), self.means(self.judged(candidate)))

    def evidence(self, reference: np.ndarray, candidate: np.ndarray) -> Comparison:
        excess = float(self.judged(candidate).mean())
        point = 1.0 - gap_of(excess) / max(float(gap_of(self.judged(reference).mean())), 1e-12)
        before, after = self.means(self.judged(reference)), self.means(self.judged(candidate))
        return Comparison(
            float(gap_of(excess)),
            float(point),
            float(np.quantile(_reductions(before, after), LOWER_BOUND_QUANTILE)),
            excess,
            _interval(before - after)[0],
        )

    def at_floor(self, per_window: np.ndarray) -> bool:
        """:func:`at_floor` of the excess beyond the sensor's variance."""
        return at_floor(self.judged(per_window))

    def within_noise(self, per_window: np.ndarray) -> bool:
        """The model of ``per_window`` explains the data to within their noise: its gap is below ``FLOOR_COUNTS``
        or twice its bootstrap standard error (module docstring)."""
        judged = self.judged(per_window)
        gap = float(gap_of(judged.mean()))
        return at_floor(judged) or gap < NOISE_STANDARD_ERRORS * float(np.std(gap_of(self.means(judged))))

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


def order(evidence: dict[str, Comparison]) -> list[str]:
    """Candidates best first: the larger reduction, then (two models at the floor both reduce by 1) the smaller
    excess residual before the square root's clip, then fewer parameters, then the name."""
    return sorted(evidence, key=lambda name: (-evidence[name].reduction, evidence[name].excess, n_params(name), name))


def choose(
    evidence: dict[str, Comparison],
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
        if bootstrap is not None and bootstrap.at_floor(per_window[best]) and not same_law:  # reductions are 1 there
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


def decide(evidence: Comparison, *, first: bool = False) -> bool:
    """The rule's judgement of one effect from ``evidence`` of the model holding it over the model without it:
    kept (:func:`is_kept`) and, when it is the ``first`` effect (nothing else accepted), closing the gap
    (a reduction of at least ``CLOSES``): what a diagnosis would accept. The caller checks first that the model
    without it is not at the floor (nothing would enter there)."""
    return is_kept(evidence) and (not first or evidence.reduction >= CLOSES)


def combined_reduction(predicted: float, sensor: float) -> float:
    """1 - gap / nominal gap when the predictions remove the share ``predicted`` of the nominal held-out mean
    squared excess and the accepted sensor effects (and a credited jitter) account for the share ``sensor``: what
    closing the gap reads, each part having passed its own test."""
    return 1.0 - float(np.sqrt(max(1.0 - predicted - sensor, 0.0)))


def verdict(dynamic: list[str], sensors: list[str], shares: tuple[float, float], quiet: bool) -> str:
    """The verdict of a selection that kept the effects ``dynamic`` (those changing the predictions, in the order
    they entered) and ``sensors`` (the sensor effects, the largest claim first), whose ``shares`` are (the share of
    the nominal held-out mean squared excess the predictions remove, the share the sensor effects account for): when
    together they close the gap (:func:`combined_reduction` of at least ``CLOSES``), the first effect of the part
    that explains more; else ``none`` when the nominal model is within the noise or its gap is :func:`negligible`
    (``quiet``), else ``unexplained``."""
    if (dynamic or sensors) and combined_reduction(*shares) >= CLOSES:
        return sensors[0] if sensors and (shares[1] > shares[0] or not dynamic) else dynamic[0]
    return "none" if quiet else "unexplained"


def is_kept(evidence: Comparison) -> bool:
    """Whether an effect whose removal costs ``evidence`` earns its place: a reduction of at least ``MARGIN`` of
    the gap of the model without it, with a 5 % lower bound above ``ENTRY`` (a second effect beside a strong
    first one shares a small remaining gap, so its bound is wide even when its size is clear), removing more
    excess squared residual than the floor resolves (:func:`beyond_resolution`: a small remaining gap's large
    relative reductions are no evidence below it)."""
    return evidence.reduction >= MARGIN and evidence.lower_bound > ENTRY and beyond_resolution(evidence.excess_drop)


def confusable(
    chosen: str,
    evidence: dict[str, Comparison],
    new: dict[str, str],
    previous: np.ndarray,
    per_window: dict[str, np.ndarray],
    bootstrap: Bootstrap,
) -> list[dict]:
    """The supported candidates of other laws that explain the held-out data as well as ``chosen``, each as
    ``{"effects": [chosen's effect, other's effect], "reductions": [theirs], "by_excess": bool, "difference":
    [low, high]}``: the ``CONFUSABLE_LEVEL`` interval of the difference of their reductions, which holds 0, or else
    of their mean excess squared residuals [counts^2], whose lower bound stays below the floor's resolution
    (:func:`beyond_resolution`). The second alone at the floor, where both reductions are 1; off it too, because
    beside a small remaining gap a difference below that resolution is no evidence, however large the relative
    reductions it makes (as for :func:`is_kept`)."""
    out = []
    for name in order(evidence):
        if name == chosen or not is_kept(evidence[name]) or new[name] in law_of(new[chosen]):
            continue
        reductions = (
            None
            if bootstrap.at_floor(per_window[chosen])  # both reductions are 1 there: the excess residuals tell apart
            else bootstrap.difference_interval(previous, per_window[chosen], per_window[name])
        )
        excess = bootstrap.excess_difference_interval(per_window[name], per_window[chosen])
        if reductions is not None and reductions[0] <= 0.0 <= reductions[1]:
            by_excess, difference = False, reductions
        elif not beyond_resolution(excess[0]):
            by_excess, difference = True, excess
        else:
            continue
        reductions = (evidence[chosen].reduction, evidence[name].reduction)
        out.append(confusable_pair((new[chosen], new[name]), reductions, difference, by_excess))
    return out


def confusable_pair(effects, reductions, difference, by_excess: bool = False) -> dict:
    """The record of two confusable effects (the kept one first), their reductions, and the ``CONFUSABLE_LEVEL``
    interval of the difference of their reductions (of their mean excess squared residuals when ``by_excess``)."""
    return {
        "effects": list(effects),
        "reductions": list(reductions),
        "by_excess": by_excess,
        "difference": list(difference),
    }
