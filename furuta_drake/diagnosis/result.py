"""What a diagnosis returns: :class:`Diagnosis`, a dataclass a notebook can inspect and ``report.json`` serialises.

``report.json`` is :meth:`Diagnosis.to_json`: the contract's keys first, in the contract's order (``verdict``,
``effects``, ``gap``, ``ranking``, ``localization``), then its later keys (``steps``, ``uncertainty``,
``detection_limits``, ``confusable``, ``consistency``) and this package's own; :meth:`Diagnosis.from_json`
reads it back, including a report written before the later keys existed. What the report's files need beyond the
JSON (the residual windows behind the plots, the fitted model as a simulate config and as a rig file, the input
record) travels in :class:`Artifacts`.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from furuta_drake.diagnosis.logs.load import WindowResiduals

Number = float | None  # None: not finite (e.g. a diverged candidate's gap)


SPEC_KEYS = ("verdict", "effects", "gap", "ranking", "localization")  # report.json's required keys, in this order


@dataclass
class GapFigures:
    """The gap metric's figures: nominal and with the accepted effects, train and held-out [counts]."""

    metric: str
    nominal: dict[str, Number]  # {"train": ..., "heldout": ...}
    with_effects: dict[str, Number]
    heldout_reduction: Number  # 1 - gap(with effects) / gap(nominal), held-out
    per_signal_nominal_heldout: dict[str, Number] = field(default_factory=dict)
    evaluated_by: str = ""
    heldout_rms_per_log: list[dict] = field(default_factory=list)  # {log, nominal, with_effects}: RMS [counts]
    sensor_variance: dict[str, Number] = field(default_factory=dict)  # {nominal, with_effects}: what each model
    # attributes to the sensor (and a credited jitter's draws) [counts^2]
    sensor_share: Number = None  # the share of the nominal held-out mean squared excess the accepted sensor
    # effects and a credited jitter account for (apart from heldout_reduction, what the predictions remove)


@dataclass
class RankedCandidate:
    """One candidate model tried: a single effect, or the effects of a step joined by '+' (the earlier accepted
    ones first). ``heldout_reduction`` and ``evidence`` (its 5 % bootstrap lower bound) are over the nominal
    model; ``*_over_previous`` over the model holding the earlier effects, which the acceptance rule reads.
    ``status`` is ``failed`` when the fit or its prediction failed, ``screened`` when its step's screen left it
    too far behind the best to fit it further (its values are the screen's, without intervals); ``reason`` says
    why."""

    effect: str
    params: dict[str, Any]
    heldout_gap: Number
    heldout_reduction: Number
    evidence: Number
    params_ci: dict[str, list[float]] = field(default_factory=dict)
    params_ci_if_complete: dict[str, list[float]] = field(default_factory=dict)  # the final model's own
    # bootstrap intervals before the widening by a rival effect (furuta_drake.diagnosis.selection.rival)
    step: int = 1
    reduction_over_previous: Number = None
    evidence_over_previous: Number = None
    train_gap: Number = None
    at_bounds: list[str] = field(default_factory=list)
    at_bound: dict[str, str] = field(default_factory=dict)  # param -> "lower" | "upper": fitted at its search range's
    # end (no interval is reported for it)
    evaluated_by: str = "surrogate"
    status: str = "ok"
    reason: str = ""
    sensor_share: Number = None  # a sensor effect: the share of the nominal held-out mean squared excess it explains
    score_gain: Number = None  # a sensor effect: its held-out log score over the rig file's sensor [nats per window]
    score_evidence: Number = None  # its 5 % bootstrap lower bound
    note: str = ""  # a sensor effect not accepted: why


@dataclass
class Step:
    """One accepted effect and the held-out gap of the model holding it and the earlier ones; what the effect
    brings to the model holding all the other accepted effects (``*_over_others``, which the rule reads)."""

    effect: str
    params: dict[str, Any]
    heldout_gap: Number
    heldout_reduction: Number  # over the nominal model
    reduction_over_previous: Number = None  # over the model of the step before
    reduction_over_others: Number = None
    evidence_over_others: Number = None  # its 5 % bootstrap lower bound
    at_bound: dict[str, str] = field(default_factory=dict)  # param -> "lower" | "upper" (see RankedCandidate)
    sensor_share: Number = None  # a sensor effect: the share of the nominal held-out mean squared excess it explains
    score_gain: Number = None  # a sensor effect: its held-out log score over the rig file's sensor [nats per window]
    score_evidence: Number = None  # its 5 % bootstrap lower bound


@dataclass
class DetectionLimit:
    """The smallest size of an effect's main parameter these logs would have detected under the same rule."""

    effect: str
    param: str
    value: Number
    unit: str
    note: str = ""


@dataclass
class Consistency:
    """The decision repeated on ``folds`` splits of the logs."""

    folds: int
    verdicts: list[str]
    effects: list[list[str]] = field(default_factory=list)
    params_range: dict[str, list[float]] = field(default_factory=dict)
    judgement: str = ""
    settled: list[str] = field(default_factory=list)  # the diagnosis' effects that every fold names
    unsettled: dict[str, int] = field(default_factory=dict)  # effect -> folds naming it, for every effect the
    # diagnosis or a fold names that not every fold names: what these logs cannot pin down


@dataclass
class Diagnosis:
    """A finished diagnosis (see the module docstring and ``docs/diagnose.md`` for every key)."""

    verdict: str
    effects: list[str]
    gap: GapFigures
    ranking: list[RankedCandidate]
    localization: dict
    steps: list[Step] = field(default_factory=list)
    uncertainty: str = ""
    detection_limits: list[DetectionLimit] = field(default_factory=list)
    confusable: list[dict] = field(default_factory=list)
    consistency: Consistency | None = None
    choice: str = ""  # why the verdict, in one paragraph
    holdout: str = ""  # how the held-out data were chosen
    rule: str = ""  # the acceptance rule
    notes: list[str] = field(default_factory=list)  # what the command tells its user (e.g. ignored columns)
    unmodelled_torque: dict = field(default_factory=dict)  # joint -> the torque beyond the vocabulary (kept only)
    beside_torque: dict = field(default_factory=dict)  # the listed effects kept beside that torque
    remaining: dict = field(default_factory=dict)  # what the accepted effects leave, when it is not negligible
    disturbance: dict = field(default_factory=dict)  # the arm torque the corrected model misses on held-out logs
    artifacts: Artifacts | None = field(default=None, repr=False, compare=False)  # not in report.json

    @property
    def failed(self) -> list[RankedCandidate]:
        """The ranked candidates whose fit failed (a candidate its step's screen left behind did not fail)."""
        return [entry for entry in self.ranking if entry.status == "failed"]

    def to_json(self) -> dict:
        """The ``report.json`` object (plain dicts and lists; optional keys without content left out)."""
        out = {f.name: _plain(getattr(self, f.name)) for f in dataclasses.fields(self) if f.name != "artifacts"}
        if self.consistency is None:
            del out["consistency"]
        if not self.confusable:
            del out["confusable"]
        for key in ("unmodelled_torque", "beside_torque", "remaining", "disturbance"):
            if not getattr(self, key):
                del out[key]
        return {**{key: out.pop(key) for key in SPEC_KEYS}, **out}

    @classmethod
    def from_json(cls, data: dict) -> Diagnosis:
        """A :class:`Diagnosis` from a ``report.json`` object, also one written before the later keys."""
        known = {f.name for f in dataclasses.fields(cls)}
        values = {key: value for key, value in data.items() if key in known}
        values["gap"] = _build(GapFigures, data["gap"])
        values["ranking"] = [_build(RankedCandidate, entry) for entry in data["ranking"]]
        values["steps"] = [_build(Step, entry) for entry in data.get("steps", [])]
        values["detection_limits"] = [_build(DetectionLimit, entry) for entry in data.get("detection_limits", [])]
        if data.get("consistency") is not None:
            values["consistency"] = _build(Consistency, data["consistency"])
        return cls(**values)


def _plain(value):
    return (
        dataclasses.asdict(value)
        if dataclasses.is_dataclass(value)
        else ([_plain(v) for v in value] if isinstance(value, list) else value)
    )


def _build(cls, data: dict):
    names = {f.name for f in dataclasses.fields(cls)}
    return cls(**{key: value for key, value in data.items() if key in names})


@dataclass
class Artifacts:
    """What the report's files need beside :class:`Diagnosis`: the held-out residual windows of the nominal model
    and of the model with the accepted effects (Drake replays), their sensor variances [count^2], the fitted
    effects' curves, the corrected model as a simulate config and as a rig file, and the input record."""

    before: list[WindowResiduals]
    after: list[WindowResiduals] | None
    noise_variance: float
    curves: list = field(default_factory=list)
    fitted_config: Any = None  # SimulationConfig
    fitted_rig: Any = None  # RigParameters
    corrected: Any = None  # the corrected surrogate Model (furuta_drake.effects.surrogate)
    record: dict = field(default_factory=dict)
    torque_scatter: dict = field(default_factory=dict)  # joint -> the unmodelled torque's plot data
