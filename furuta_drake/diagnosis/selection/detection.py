"""Detection limits: for every effect not accepted, the smallest size of its main parameter that these logs would
have detected under the acceptance rule (stage 6 of the diagnosis).

The effect is injected into the accepted model's own prediction of the very same held-out windows: the
synthetic data are the measured angles plus the change the effect at size s makes to the model's prediction from
the model's refined initial states, with the part the initial states can absorb projected out (the residuals are
re-projected for every model, so a state-like change is no evidence). The model is then judged on the synthetic
data against the model holding the injected effect at its true size, which explains them exactly, with the
acceptance rule's bootstrap (:mod:`furuta_drake.diagnosis.selection.rule`): detected when the model is not at the floor
on them and the lower bound of the reduction exceeds the margin (and, for a first effect, the reduction reaches
the level that closes a gap). The smallest detected size is found by bisection on a log scale. A real fit must
also find the parameters, so a real detection needs somewhat more than this limit.

Sensor effects are injected into the data and judged by their own rule
(:mod:`~furuta_drake.diagnosis.selection.sensor`): white noise added to the residuals, judged by the log score of its
third differences (and never below the size the noise reading names), and a coarser encoder by re-quantising the
measured angles, judged by the grid the held-out increments lie on.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from furuta_drake.diagnosis.gap.metric import (
    Windows,
    fixed_state_residuals,
    project_out_states,
    projected_residuals,
    window_excess,
)
from furuta_drake.diagnosis.result import DetectionLimit
from furuta_drake.diagnosis.selection.rule import Bootstrap, decide
from furuta_drake.diagnosis.selection.sensor import (
    GRID_MIN_STEPS,
    MAX_GRID,
    NOISE_FLOOR_COUNTS,
    NOISE_PLAUSIBLE_COUNTS,
    ON_GRID_SHARE,
    Hypothesis,
    signature_of,
)
from furuta_drake.drive import CONTACT_FREQUENCY
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import (
    BACKLASH_BOUNDS,
    CANDIDATES,
    COMPLIANCE_FREQUENCIES,
    PRESLIDING_STARTS,
    UNITS,
    Effect,
    Scales,
    apply_effects,
)
from furuta_drake.rig import encoder_resolution

BISECTIONS = 14  # halvings of the log-scale bracket: the limit to within about 1 % of its bracket's ratio


@dataclass(frozen=True)
class Injection:
    """How an effect is injected at a size s > 0: its :class:`Effect` and the reported main parameter's value."""

    param: str
    bracket: Callable[[Scales, Model], tuple[float, float]]  # (smallest, largest) size tried
    effect: Callable[[float, Scales, Model], Effect]
    value: Callable[[float, Scales, Model], float]
    note: str = ""
    rate_note: Callable[[float, Scales], str] | None = None  # what the logs' rate shows of the effect at the
    # reported value (appended to the note)


def _same(s, scales, model):
    return s


def _arm_level(model: Model) -> float:
    """The model's arm Coulomb level [N m] (the larger of the two directions; 0 without arm friction)."""
    p = model.arm_friction
    return max(p.coulomb_pos, p.coulomb_neg) if p.model != "none" else 0.0


COMPLIANCE_INJECTED_RATIO = 0.1  # the damping ratio of an injected drive compliance


def _ringing(s: float) -> float:
    """The ringing [Hz] of a drive compliance injected at the size s: CONTACT_FREQUENCY / (1 + s) (s = 0: as stiff
    as a gear's tooth contact)."""
    return CONTACT_FREQUENCY / (1.0 + s)


def _compliance_stiffness(s: float, scales: Scales) -> float:
    """k = mu (2 pi f)^2 [N m/rad] of the ringing f of :func:`_ringing`, mu the drive pair's reduced inertia."""
    return scales.drive_inertia * (2.0 * np.pi * _ringing(s)) ** 2


def _compliance_damping(s: float, scales: Scales) -> float:
    """c = 2 zeta sqrt(k mu) [N m s/rad] at ``COMPLIANCE_INJECTED_RATIO``."""
    return 2.0 * COMPLIANCE_INJECTED_RATIO * np.sqrt(_compliance_stiffness(s, scales) * scales.drive_inertia)


def _ringing_note(stiffness: float, scales: Scales) -> str:
    """Where the ringing sqrt(k / mu) of a drive of ``stiffness`` [N m/rad] lies against the logs' Nyquist frequency."""
    ringing = np.sqrt(stiffness / scales.drive_inertia) / (2.0 * np.pi)
    nyquist = 0.5 / scales.period
    if ringing <= nyquist:
        return f"; it rings at {ringing:.3g} Hz, below these logs' Nyquist frequency ({nyquist:.3g} Hz)"
    return (
        f"; it rings at {ringing:.3g} Hz, above these logs' Nyquist frequency ({nyquist:.3g} Hz): a stiffer "
        f"drive shows as a lag, not a ringing; logs at {2.0 * ringing:.3g} Hz or faster would sample the ringing"
    )


INJECTIONS: dict[str, Injection] = {
    "arm_coulomb_friction": Injection(
        "coulomb",
        lambda sc, m: (1e-5 * sc.torque, 0.5 * sc.torque),
        lambda s, sc, m: Effect("presliding", (_arm_level(m) + s, PRESLIDING_STARTS[0])),
        _same,
        f"added to the model's Coulomb level, presliding {PRESLIDING_STARTS[0] * 1e3:g} mrad",
    ),
    "arm_viscous_friction": Injection(
        "viscous",
        lambda sc, m: (1e-4 * sc.arm_inertia, 50.0 * sc.arm_inertia),
        lambda s, sc, m: Effect("", (m.arm_friction.viscous + s,)),
        _same,
        "added to the model's",
    ),
    "arm_stribeck": Injection(
        "static",
        lambda sc, m: (1e-5 * sc.torque, 0.5 * sc.torque),
        lambda s, sc, m: Effect("presliding", (_arm_level(m), _arm_level(m) + s, 0.1, PRESLIDING_STARTS[0])),
        _same,
        "static level above the model's Coulomb level, Stribeck velocity 0.1 rad/s",
    ),
    "friction_asymmetry": Injection(
        "coulomb_neg",
        lambda sc, m: (1e-5 * sc.torque, 0.5 * sc.torque),
        lambda s, sc, m: Effect(
            "presliding", (_arm_level(m) + 1e-6 * sc.torque, _arm_level(m) + s, PRESLIDING_STARTS[0])
        ),
        _same,
        "added to the model's Coulomb level in the negative direction only",
    ),
    "pendulum_friction": Injection(
        "coulomb",
        lambda sc, m: (1e-6 * sc.torque, 0.1 * sc.torque),
        lambda s, sc, m: Effect("", (m.pendulum_friction.coulomb_pos + s, m.pendulum_friction.viscous)),
        _same,
        "added to the model's Coulomb level",
    ),
    "input_delay": Injection(
        "delay",
        lambda sc, m: (0.01 * sc.period, 20.0 * sc.period),
        lambda s, sc, m: (
            Effect("jitter", (m.delay + s, m.delay_spread)) if m.delay_spread > 0 else Effect("fixed", (m.delay + s,))
        ),
        _same,
        "added to the model's",
    ),
    "torque_gain_error": Injection(
        "gain",
        lambda sc, m: (1e-3, 1.0),
        lambda s, sc, m: Effect("", (1.0 + s,)),
        lambda s, sc, m: 1.0 + s,
        "a gain above 1 (a gain below 1 is detected at about the same distance from 1)",
    ),
    "actuator_deadzone": Injection(
        "deadzone",
        lambda sc, m: (1e-4 * sc.command, 0.5 * sc.command),
        lambda s, sc, m: Effect("subtract", (m.deadzone + s,)),
        _same,
        "the subtract form",
    ),
    "actuator_lag": Injection(
        "time_constant",
        lambda sc, m: (0.01 * sc.period, 0.1),
        lambda s, sc, m: Effect("", (m.lag + s,)),
        _same,
        "added to the model's",
    ),
    "actuator_saturation": Injection(
        "limit",
        lambda sc, m: (1e-3, 0.95),
        lambda s, sc, m: Effect("hard", ((1.0 - s) * sc.command,)),
        lambda s, sc, m: (1.0 - s) * sc.command,
        "the largest limit detected, below the largest command",
    ),
    "arm_spring": Injection(
        "stiffness",
        lambda sc, m: (1e-5 * sc.torque, 5.0 * sc.torque),
        lambda s, sc, m: Effect("linear", (m.spring_stiffness + s, m.spring_equilibrium)),
        _same,
        "a linear spring added to the model's",
    ),
    "drive_backlash": Injection(
        "backlash",
        lambda sc, m: (1e-5, BACKLASH_BOUNDS[1]),
        lambda s, sc, m: Effect("", (m.drive_backlash + s,)),
        _same,
        "added to the model's drive, its teeth touching through its spring or a gear's stiff contact",
    ),
    "drive_compliance": Injection(
        "stiffness",
        lambda sc, m: (1e-3, CONTACT_FREQUENCY / COMPLIANCE_FREQUENCIES[0] - 1.0),
        lambda s, sc, m: Effect("", (_compliance_stiffness(s, sc), _compliance_damping(s, sc))),
        lambda s, sc, m: _compliance_stiffness(s, sc),
        f"the stiffest coupling detected, damping ratio {COMPLIANCE_INJECTED_RATIO:g}",
        _ringing_note,
    ),
    "inertia_mismatch": Injection(
        "arm_inertia_scale",
        lambda sc, m: (1e-3, 1.0),
        lambda s, sc, m: Effect("", (1.0 + s, 1.0, 1.0, 1.0)),
        lambda s, sc, m: 1.0 + s,
        "the arm's inertia alone, scaled up",
    ),
}


@dataclass
class _Judge:
    """The accepted model's residuals and state sensitivities on the held-out windows, and the rule."""

    model: Model
    windows: Windows
    counts: int
    bootstrap: Bootstrap
    first: bool  # no effect accepted yet: a detection must also close the gap

    def __post_init__(self):
        self.raw, self.states, self.jacobians = projected_residuals(self.model, self.windows, self.counts)
        self.truth = window_excess(self.raw, self.windows.floor)

    def detected(self, residuals: list[np.ndarray]) -> bool:
        """Whether synthetic residuals of the model are detected against the truth (the model's own residuals)."""
        synthetic = window_excess(residuals, self.windows.floor)
        if self.bootstrap.at_floor(synthetic):
            return False
        evidence = self.bootstrap.evidence(synthetic, self.truth)
        return decide(evidence, first=self.first)

    def injected(self, effect_model: Model) -> list[np.ndarray]:
        count = encoder_resolution(self.counts)
        predicted = fixed_state_residuals(effect_model, self.windows, self.states, self.counts)
        return [
            raw + project_out_states(np.nan_to_num(p - raw, nan=1e6 / count), J)
            for raw, p, J in zip(self.raw, predicted, self.jacobians)
        ]


def detection_limits(
    model: Model,
    accepted: list[str],
    windows: Windows,
    scales: Scales,
    counts: int,
    bootstrap: Bootstrap,
    seed: int = 0,
) -> list[DetectionLimit]:
    """The detection limit of every vocabulary effect that is neither accepted nor a variant of an accepted
    effect's law, and is offered for ``model`` (a drive's with a drive), on the held-out ``windows`` of ``model``
    (the model holding the accepted effects)."""
    from furuta_drake.effects.vocabulary import law_of

    judge = _Judge(model, windows, counts, bootstrap, first=not accepted)
    taken = set().union(*(law_of(name) for name in accepted)) if accepted else set()
    out = []
    for name, candidate in CANDIDATES.items():
        if name in taken or not candidate.offered(model):
            continue
        if name == "measurement_noise":
            out.append(_noise_limit(judge, seed))
        elif name == "encoder_quantization":
            out.append(_quantization_limit(judge))
        else:
            out.append(_injected_limit(name, judge, scales))
    return out


def injected_limits(
    model: Model,
    accepted: list[str],
    windows: Windows,
    scales: Scales,
    counts: int,
    bootstrap: Bootstrap,
    names: list[str],
) -> list[DetectionLimit]:
    """The detection limits of the injected (actuator and plant) effects ``names`` alone, on the held-out
    ``windows`` of ``model``, as :func:`detection_limits` finds them."""
    judge = _Judge(model, windows, counts, bootstrap, first=not accepted)
    return [_injected_limit(name, judge, scales) for name in names]


def _bisect(detected: Callable[[float], bool], low: float, high: float) -> float | None:
    """The smallest size in [low, high] that is detected (log-scale bisection), None when ``high`` is not."""
    if not detected(high):
        return None
    if detected(low):
        return low
    for _ in range(BISECTIONS):
        middle = float(np.sqrt(low * high))
        low, high = (low, middle) if detected(middle) else (middle, high)
    return high


def _injected_limit(name: str, judge: _Judge, scales: Scales) -> DetectionLimit:
    injection = INJECTIONS[name]

    def detected(size: float) -> bool:
        effect_model = apply_effects(judge.model, {name: injection.effect(size, scales, judge.model)})
        return judge.detected(judge.injected(effect_model))

    low, high = injection.bracket(scales, judge.model)
    size = _bisect(detected, low, high)
    if size is None:
        value = injection.value(high, scales, judge.model)
        note = f"not detected even at {value:.3g} {UNITS[injection.param]}, the end of its search range"
        return DetectionLimit(
            name, injection.param, None, UNITS[injection.param], note + _rate_note(injection, value, scales)
        )
    value = injection.value(size, scales, judge.model)
    return DetectionLimit(
        name, injection.param, value, UNITS[injection.param], injection.note + _rate_note(injection, value, scales)
    )


def _rate_note(injection: Injection, value: float, scales: Scales) -> str:
    return "" if injection.rate_note is None else injection.rate_note(value, scales)


def _noise_limit(judge: _Judge, seed: int) -> DetectionLimit:
    """White noise of std s [counts] added to the model's residuals: detected when its third differences score
    better under that noise than under the model's own sensor (the 5 % bootstrap bound of the gain above 0) and s is
    at least ``NOISE_FLOOR_COUNTS``, the smallest size the noise reading names."""
    count = encoder_resolution(judge.counts)
    rng = np.random.default_rng(seed)
    unit_noise = [rng.standard_normal(r.shape) for r in judge.raw]
    step = encoder_resolution(judge.model.counts_per_rev) / count
    own = Hypothesis(step, judge.model.noise_std / count)

    base = signature_of(judge.model, judge.windows, judge.raw, judge.jacobians, judge.counts, extra=unit_noise)

    def detected(size: float) -> bool:
        sig = base.injected(size)
        gain = sig.scores(Hypothesis(step, float(np.hypot(own.sigma, size)))) - sig.scores(own)
        return float(np.quantile(judge.bootstrap.means(gain), 0.05)) > 0.0

    size = _bisect(detected, NOISE_FLOOR_COUNTS, NOISE_PLAUSIBLE_COUNTS)
    return DetectionLimit(
        "measurement_noise",
        "noise_std",
        None if size is None else size * count,
        "rad",
        "white noise on both angles"
        if size is not None
        else f"not detected up to {NOISE_PLAUSIBLE_COUNTS:g} counts (a larger noise is a model error)",
    )


def _quantization_limit(judge: _Judge) -> DetectionLimit:
    """The measured angles re-quantised to a k times coarser encoder; the largest counts_per_rev whose grid the
    held-out increments would show (``ON_GRID_SHARE`` of at least ``GRID_MIN_STEPS`` non-zero increments)."""
    count = encoder_resolution(judge.counts)
    for k in range(2, MAX_GRID + 1):
        steps = []
        for measured in judge.windows.measured:
            coarse = np.round(measured / (k * count)) * k
            moved = np.abs(np.diff(coarse, axis=0))
            steps.append(moved[moved != 0])
        steps = np.concatenate(steps)
        if steps.size >= GRID_MIN_STEPS and np.mean(steps % k == 0) >= ON_GRID_SHARE:
            return DetectionLimit(
                "encoder_quantization",
                "counts_per_rev",
                judge.counts / k,
                "counts/rev",
                f"an encoder {k} times coarser than the rig file's",
            )
    return DetectionLimit(
        "encoder_quantization", "counts_per_rev", None, "counts/rev", f"not detected up to {MAX_GRID} times coarser"
    )
