"""Study: the paper's observers on measured data. The HG observer (Eq. 4-6) and the VFE observer with the Dahl
observer (Eq. 8-13) replayed offline (:func:`furuta_drake.paper.reproduce.replay_observers`) on the real QUBE runs of
:mod:`furuta_drake.real_rig.runs`: the balancing part of the swing-ups, linearised at the upright, and the
hanging chirp, linearised at the hanging equilibrium (:func:`furuta_drake.linearization.observer_model`), each with
the nominal rig model and with the model the diagnosis fitted (its rigid body, and its arm friction as the Dahl
observer's calibration when it has one; without one, F_hat = 0 and the VFE's eps_hat_F carries all the friction).

Fairness as in the simulated Table II (:func:`furuta_drake.paper.reproduce.observer_sweep`): every candidate of
:func:`furuta_drake.paper.reproduce.sweep_candidates` (HG eps, VFE eigenvalue scale) is replayed on the train
segments of its equilibrium and each observer, per model and equilibrium, keeps the candidate with the lowest arm
velocity error against the reference; the table is read on the held-out segments only. The reference is the paper's
zero-phase Butterworth velocity at :data:`~furuta_drake.real_rig.runs.REFERENCE_CUTOFF_HZ`: on a real rig there is
no true velocity, so both observers are judged against a filter of the same encoder angles they read.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from furuta_drake.config import SimulationConfig
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.linearization import Equilibrium, equilibrium_angle, observer_model
from furuta_drake.observers.dahl import DahlObserverParameters
from furuta_drake.paper import reproduce
from furuta_drake.real_rig.runs import (
    CHIRP,
    SWINGUPS,
    RealRuns,
    balancing_samples,
    catch_index,
    chirp_blocks,
    hanging_samples,
    log_result,
    reference_velocity,
)

SMALL_HG_EPS = (0.005, 0.01, 0.02)  # [s] the small run's HG candidates
SMALL_VFE_SCALES = (1.0, 2.0, 3.0)  # the small run's VFE candidates


@dataclass
class Segment:
    """A stretch of a real run the observers replay: the run's tape from ``start`` on with theta relative to the
    equilibrium (``result``), the reference velocity over it, the samples it is judged on (``judged``), its
    equilibrium and its part ('train' or 'heldout')."""

    log: str
    part: str
    equilibrium: Equilibrium
    result: object
    reference: np.ndarray
    judged: np.ndarray
    start_time: float


@dataclass
class ModelObservers:
    """One model's observers: its simulate config, its Dahl observer (None: no friction model) and the (A, B_F)
    of each equilibrium."""

    config: SimulationConfig
    dahl: DahlObserverParameters | None
    linearizations: dict[str, tuple[np.ndarray, np.ndarray]] = field(default_factory=dict)


@dataclass
class ObserverStudy:
    """``rows``: real_observers.csv (observer, model, log, phi_dot_mse, theta_dot_mse on held-out segments);
    ``sweep``: every candidate's train errors (the fairness sweep); ``tuned``: the chosen value per (model,
    equilibrium, observer); ``estimates``: {(model, log): {observer: estimate}} of the held-out segments, for the
    plots; ``segments``: what was replayed."""

    rows: list[dict]
    sweep: list[dict]
    tuned: dict
    estimates: dict
    segments: list[Segment]


def segments(runs: RealRuns) -> list[Segment]:
    """The balancing part of every swing-up (from its catch, judged ``SETTLE`` after it; the train swing-up
    trains, the others are held out) and the chirp's hanging segment twice: judged on its train blocks and on
    its held-out blocks."""
    out = []
    for name in SWINGUPS:
        if name not in runs.logs:
            continue
        log = runs.logs[name]
        whole = log_result(log)
        catch, window = catch_index(whole), balancing_samples(whole)
        if catch is None or window is None:
            continue
        samples = slice(catch, None)
        result = log_result(log, theta_offset=equilibrium_angle(log.theta[catch], "upright"), samples=samples)
        judged = np.zeros(result.time.size, bool)
        judged[window.start - catch :] = True
        out.append(
            Segment(
                name,
                "train" if runs.part(name) == "train" else "heldout",
                "upright",
                result,
                reference_velocity(log)[samples],
                judged,
                float(log.time[catch]),
            )
        )
    if CHIRP in runs.logs:
        chirp = runs.logs[CHIRP]
        samples = hanging_samples(chirp)
        result = log_result(chirp, theta_offset=equilibrium_angle(chirp.theta[0], "hanging"), samples=samples)
        for part, mask in zip(("train", "heldout"), chirp_blocks(chirp)):
            out.append(
                Segment(
                    CHIRP,
                    part,
                    "hanging",
                    result,
                    reference_velocity(chirp)[samples],
                    mask[samples],
                    float(chirp.time[0]),
                )
            )
    return out


def dahl_of(friction: JointFrictionParameters) -> DahlObserverParameters | None:
    """The Dahl observer calibrated on a model's arm friction: its Coulomb levels, stiffness sigma0 and (LuGre)
    Stribeck levels, sigma1 and viscous term; None when the model has no Coulomb level (no friction model)."""
    if friction.model == "none" or max(friction.coulomb_pos, friction.coulomb_neg) <= 0:
        return None
    lugre = friction.model == "lugre"
    return DahlObserverParameters(
        coulomb_pos=friction.coulomb_pos,
        coulomb_neg=friction.coulomb_neg,
        sigma0=friction.sigma0,
        sigma1=friction.sigma1 if lugre else 0.0,
        static_pos=friction.static_pos,
        static_neg=friction.static_neg,
        stribeck_velocity=friction.stribeck_velocity,
        sigma2=friction.viscous if lugre else 0.0,
    )


def model_observers(config: SimulationConfig) -> ModelObservers:
    """The observers' view of a model config: (A, B_F) at both equilibria with the motor's back-EMF and the
    Dahl observer of its arm friction."""
    return ModelObservers(
        config, dahl_of(config.friction.arm), {eq: observer_model(config.rig, eq) for eq in ("upright", "hanging")}
    )


def replay(segment: Segment, model: ModelObservers, kwargs: dict) -> dict:
    """:func:`~furuta_drake.paper.reproduce.replay_observers` on ``segment`` with ``model``'s linearisation, the
    observers started at its first sample at rest."""
    config = dataclasses.replace(
        model.config,
        initial_state=[float(segment.result.measured[0, 0]), float(segment.result.measured[0, 1]), 0.0, 0.0],
        observers=dataclasses.replace(model.config.observers, start_at_initial_state=True),
    )
    return reproduce.replay_observers(segment.result, config, model=model.linearizations[segment.equilibrium], **kwargs)


def candidates(model: ModelObservers, small: bool) -> list[tuple[str, str, float, dict]]:
    """The fairness sweep's candidates (:func:`~furuta_drake.paper.reproduce.sweep_candidates`) for ``model``; ``small``
    keeps three of each."""
    rows = reproduce.sweep_candidates(model.config, model.dahl)
    if small:
        rows = [row for row in rows if row[2] in (SMALL_HG_EPS if row[0] == "hg" else SMALL_VFE_SCALES)]
    return rows


def study(runs: RealRuns, models: dict[str, SimulationConfig], small: bool = False, progress=None) -> ObserverStudy:
    """Tune on the train segments, then the Table II rows on the held-out ones, for every model of ``models``
    ({'nominal': config, 'fitted': config})."""
    parts = segments(runs)
    sweep, tuned, rows, estimates = [], {}, [], {}
    for model_name, config in models.items():
        model = model_observers(config)
        for equilibrium in ("upright", "hanging"):
            train = [s for s in parts if s.equilibrium == equilibrium and s.part == "train"]
            mine = []
            for observer, parameter, value, kwargs in candidates(model, small):
                errors = [
                    reproduce.velocity_errors(
                        replay(s, model, kwargs)[observer][s.judged, 2:], {"butterworth": s.reference[s.judged]}
                    )
                    for s in train
                ]
                mine.append(
                    {
                        "model": model_name,
                        "equilibrium": equilibrium,
                        "observer": observer,
                        "parameter": parameter,
                        "value": value,
                        **{key: float(np.mean([e[key] for e in errors])) for key in errors[0]},
                    }
                )
            reproduce.mark_best(mine, "phi_dot_mse_butterworth")
            sweep += mine
            best = {row["observer"]: row for row in mine if row["best"]}
            tuned[(model_name, equilibrium)] = {observer: row["value"] for observer, row in best.items()}
            chosen = {}
            for observer, row in best.items():
                chosen.update(next(c[3] for c in candidates(model, small) if c[0] == observer and c[2] == row["value"]))
            for segment in (s for s in parts if s.equilibrium == equilibrium and s.part == "heldout"):
                replayed = replay(segment, model, chosen)
                estimates[(model_name, segment.log)] = {"segment": segment, **replayed}
                for observer in ("hg", "vfe"):
                    errors = reproduce.velocity_errors(
                        replayed[observer][segment.judged, 2:], {"butterworth": segment.reference[segment.judged]}
                    )
                    rows.append(
                        {
                            "observer": observer.upper(),
                            "model": model_name,
                            "log": segment.log,
                            "phi_dot_mse": errors["phi_dot_mse_butterworth"],
                            "theta_dot_mse": errors["theta_dot_mse_butterworth"],
                        }
                    )
            reproduce.report_progress(progress, f"observers: {model_name} model, {equilibrium}")
    return ObserverStudy(rows, sweep, tuned, estimates, parts)


__all__ = [
    "Segment",
    "ModelObservers",
    "ObserverStudy",
    "segments",
    "dahl_of",
    "model_observers",
    "replay",
    "candidates",
    "study",
]
