"""The predicted outcome of an experiment: what the diagnosis' held-out rule decides once its log is added.

For one direction of a pair (a hypothesis taken as the truth, the other as the rival), the three models the
rule compares at the pair's step (the truth, the rival and the model holding the earlier effects that both are
judged against) are refit on the experiment's train half and give noise-free residuals on its held-out half
(:func:`~furuta_drake.design.criterion.refit_residuals`). Each Monte Carlo draw adds the truth's sensor
noise (the rounding of its encoder, uniform over a count, and its white noise), with what each model's
re-projected initial states absorb of it projected out, appends the per-window excess of the diagnosis' own
held-out windows (the new log joins them, it does not replace them), and applies the rule of
:mod:`furuta_drake.diagnosis.selection.rule` with its bootstrap:

- a nested pair (the truth is the rival plus one effect): detected when the truth's reduction over the rival
  has a 5 % lower bound above the margin, so the effect is kept (and, for a first effect, closes the gap; the
  unmodelled torque is kept on that rule alone, as the diagnosis keeps it, never having to close the gap);
- otherwise: detected when the rule lets the truth's effect enter rather than the rival's (its parsimony
  included), keeps it (the lower bound of its reduction over the model without it above the margin) and, for
  two different laws, no longer finds the two confusable.

The detection probability is the share of draws detected; the gap difference (rival minus truth [counts]) is
pooled over draws and bootstrap resamples, on the experiment's held-out half and on all held-out windows. The
same prediction for the experiment repeated (its held-out windows repeated with fresh noise) gives the duration
an experiment needs: the old held-out windows, on which the hypotheses agree, dilute the new ones.
"""

from __future__ import annotations

import numpy as np

from furuta_drake.design.criterion import Refit
from furuta_drake.design.torque_hypothesis import TORQUE
from furuta_drake.diagnosis.gap.metric import project_out_states
from furuta_drake.diagnosis.selection.rule import ENTRY, Bootstrap, at_floor, choose, decide, gap_of, is_kept
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import law_of
from furuta_drake.rig import encoder_resolution

TRUTH, RIVAL = "truth", "rival"


def _excess(refit: Refit, noise: np.ndarray) -> np.ndarray:
    """(W,) per-window excess squared residual [counts^2] of ``refit`` with ``noise`` (h, 2, W) added to the
    data and what the initial states absorb of it projected out."""
    r = refit.residuals + project_out_states(noise, refit.state_jacobians)
    return (r[1:] ** 2).mean(axis=(0, 1)) - refit.variance


def _summary(values: np.ndarray) -> dict:
    return {
        "median": float(np.median(values)),
        "interval90": [float(np.quantile(values, 0.05)), float(np.quantile(values, 0.95))],
    }


def predict_direction(
    truth: Refit,
    rival: Refit,
    previous: Refit,
    old: dict[str, np.ndarray],
    new: dict[str, str],
    nested: bool,
    first_effect: bool,
    truth_model: Model,
    counts: int,
    draws: int,
    resamples: int,
    seed: int,
    replicas: int = 1,
) -> dict:
    """The predicted outcome of one direction (module docstring).

    ``old``: per-window excess [counts^2] of ``truth``, ``rival`` and ``"previous"`` on the diagnosis' held-out
    windows; ``new``: the effect the truth and the rival add at the step (the rule's parsimony counts its
    parameters); ``first_effect``: the step is the first (a detection must also close the gap); ``replicas``:
    the experiment repeated that many times (its held-out windows repeat, each with its own noise).
    """
    rng = np.random.default_rng(seed)
    step = counts / truth_model.counts_per_rev  # the truth's encoder step [counts of the rig file]
    white = truth_model.noise_std / encoder_resolution(counts)
    shape = truth.residuals.shape
    models = {TRUTH: truth, RIVAL: rival, "previous": previous}
    detected, experiment, combined, gaps = [], [], [], {TRUTH: [], RIVAL: []}
    for draw in range(draws):
        noises = [
            rng.uniform(-0.5 * step, 0.5 * step, shape) + white * rng.standard_normal(shape) for _ in range(replicas)
        ]
        fresh = {key: np.concatenate([_excess(refit, noise) for noise in noises]) for key, refit in models.items()}
        for key in gaps:
            gaps[key].append(float(gap_of(fresh[key].mean())))
        pooled = {key: np.concatenate([old[key], fresh[key]]) for key in fresh}
        both = Bootstrap(pooled[TRUTH].size, resamples, seed + 1 + draw)
        alone = Bootstrap(fresh[TRUTH].size, resamples, seed + 1 + draw)
        combined.append(gap_of(pooled[RIVAL][both.index].mean(axis=1)) - gap_of(pooled[TRUTH][both.index].mean(axis=1)))
        experiment.append(
            gap_of(fresh[RIVAL][alone.index].mean(axis=1)) - gap_of(fresh[TRUTH][alone.index].mean(axis=1))
        )
        detected.append(_detected(both, pooled, new, nested, first_effect))
    return {
        "heldout_gap": {key: float(np.median(value)) for key, value in gaps.items()},
        "gap_difference": _summary(np.concatenate(experiment)),
        "gap_difference_all_heldout": _summary(np.concatenate(combined)),
        "detection_probability": float(np.mean(detected)),
    }


def _detected(
    bootstrap: Bootstrap, excess: dict[str, np.ndarray], new: dict[str, str], nested: bool, first_effect: bool
) -> bool:
    """Whether the rule, on these per-window excesses, tells the truth from the rival (module docstring)."""
    if at_floor(excess["previous"]):
        return False
    truth = bootstrap.evidence(excess["previous"], excess[TRUTH])
    if nested:
        return is_kept(truth) if new[TRUTH] == TORQUE else decide(truth, first=first_effect)
    # The rule's keys are the effects each model adds (its parsimony counts their parameters); the chosen one
    # enters on a lenient bound (with the floor's and the same law's clauses, as in the selection) and is kept
    # when it reduces the model without it by the margin.
    evidence = {new[TRUTH]: truth, new[RIVAL]: bootstrap.evidence(excess["previous"], excess[RIVAL])}
    per_window = {new[TRUTH]: excess[TRUTH], new[RIVAL]: excess[RIVAL]}
    chosen = choose(evidence, {name: name for name in evidence}, ENTRY, excess["previous"], per_window, bootstrap)
    if chosen != new[TRUTH] or not decide(truth, first=first_effect):
        return False
    if law_of(new[TRUTH]) == law_of(new[RIVAL]):  # variants of one law are never confusable: the choice stands
        return True
    low, high = bootstrap.difference_interval(excess["previous"], excess[TRUTH], excess[RIVAL])
    return not low <= 0.0 <= high
