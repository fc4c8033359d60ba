"""The diagnosis' unmodelled torque (``report.json`` ``unmodelled_torque``) as an effect of a design's hypotheses.

Among a hypothesis' effects the torque is the entry ``TORQUE``: an :class:`~furuta_drake.effects.vocabulary.Effect`
whose form names its library terms (``"joint:term index"`` joined by ``;``) and whose values are their
coefficients [N m]. Applied, its terms are added to the model's own
(:func:`~furuta_drake.diagnosis.selection.missing_torque.with_terms`); refit, its coefficients move within ``SPAN``
times their size either way. ``--target unmodelled_torque=SIZE`` scales the torque found to a size: SIZE is its RMS
[N m] along the diagnosis' train logs (both joints' torques, the rates by central differences of the logged
angles).
"""

from __future__ import annotations

import numpy as np

from furuta_drake.diagnosis.selection.missing_torque import with_terms
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.torque_library import JOINTS, TERMS, expression, term_values
from furuta_drake.effects.vocabulary import Effect, apply_effects, describe
from furuta_drake.errors import ConfigError

TORQUE = "unmodelled_torque"  # the torque's key among a hypothesis' effects and in --target
SPAN = 4.0  # a refit coefficient c stays within c +- SPAN |c|


def report_torque(report: dict) -> Effect | None:
    """The torque of ``report`` as an effect, None when it has none. ConfigError naming an entry that is not a
    library term with a numeric coefficient."""
    keys, values = [], []
    for joint, name in enumerate(JOINTS):
        for i, entry in enumerate(report.get(TORQUE, {}).get(name, {}).get("terms", [])):
            term, coefficient = entry.get("term"), entry.get("coefficient")
            if term not in TERMS or isinstance(coefficient, bool) or not isinstance(coefficient, (int, float)):
                raise ConfigError(
                    f"report.json {TORQUE}.{name}.terms[{i}]: expected a term of the torque library and a numeric "
                    f"coefficient, got {term!r} and {coefficient!r}"
                )
            keys.append(f"{joint}:{TERMS.index(term)}")
            values.append(float(coefficient))
    return Effect(";".join(keys), tuple(values)) if keys else None


def torque_terms(effect: Effect) -> list[tuple[int, int, float]]:
    """(joint, term index, coefficient [N m]) of a torque effect."""
    pairs = [tuple(int(part) for part in key.split(":")) for key in effect.form.split(";")]
    return [(joint, term, float(c)) for (joint, term), c in zip(pairs, effect.values)]


def apply_hypothesis(nominal: Model, effects: dict[str, Effect]) -> Model:
    """``nominal`` with a hypothesis' effects: the listed ones applied in order, the torque's terms added."""
    model = apply_effects(nominal, {name: effect for name, effect in effects.items() if name != TORQUE})
    return with_terms(model, torque_terms(effects[TORQUE])) if TORQUE in effects else model


def torque_bounds(effect: Effect) -> tuple[list[float], list[float]]:
    """The refit's bounds of the torque's coefficients."""
    values = np.asarray(effect.values)
    return list(values - SPAN * np.abs(values)), list(values + SPAN * np.abs(values))


def torque_rms(effect: Effect, logs) -> float:
    """The torque's RMS [N m] along ``logs`` (:class:`~furuta_drake.diagnosis.logs.load.RunLog`): the root of the mean
    over their samples of the arm's and the pendulum's torque squared, summed."""
    total, samples = 0.0, 0
    for log in logs:
        values = term_values(log.theta, log.phi, *(np.gradient(angle, log.time) for angle in (log.theta, log.phi)))
        torque = np.zeros((len(JOINTS), log.time.size))
        for joint, term, c in torque_terms(effect):
            torque[joint] += c * values[term]
        total, samples = total + float(np.sum(torque**2)), samples + log.time.size
    return float(np.sqrt(total / samples))


def scaled_torque(effect: Effect, size: float, logs) -> Effect:
    """The torque scaled so that its RMS along ``logs`` is ``size`` [N m]."""
    return Effect(effect.form, tuple(c * size / torque_rms(effect, logs) for c in effect.values))


def describe_effect(name: str, effect: Effect, nominal: Model) -> dict:
    """The parameters of a hypothesis' effect for design.json: a listed effect's, or the torque's expression per
    joint."""
    if name != TORQUE:
        return describe(name, effect, nominal)
    terms = torque_terms(effect)
    return {
        joint: expression([(t, c) for j, t, c in terms if j == index])
        for index, joint in enumerate(JOINTS)
        if any(j == index for j, _, _ in terms)
    }
