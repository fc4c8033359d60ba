"""``tune``: the nominal and the tuned controller of a diagnosed rig, predicted side by side on the corrected model.

1. Read the diagnosis (:mod:`.inputs`) and build the corrected model (the fitted rig file as a simulate config).
2. The **nominal** controller: the package's LQ design on the rig file's rigid body (:mod:`.controller`).
3. The **tuned** gain: the same LQ weights on the corrected model's design model (:mod:`.design`: Drake's
   linearization, the delay and lag as states). It must meet the margins at every linear corner of the intervals
   (:mod:`.robustness`); if it does not, the input weight R is raised (``TuneSettings.input_weight_scales``: a
   gentler loop) until one does.
4. Its observer follows the corrected model's time scale, its Dahl observer the fitted friction; the friction
   compensation's gain (the initial K_sigma) is chosen among ``TuneSettings.compensation_gains`` by simulating each
   candidate on the corrected model: the smallest balancing limit cycle wins (amplitudes within one encoder count
   of the smallest are a tie, decided by theta's RMS); no compensation when no arm friction was found.
5. The chosen candidate is run at each accepted effect's extremes (:func:`.robustness.effect_extremes`); one that
   falls there is passed over for the next. No candidate left: :class:`~.robustness.NotRobust`.
6. The nominal controller is run on the same model and extremes, for the side-by-side figures.

Every run starts from the same seeded disturbance and encoder noise (common random numbers: the candidates differ
only by their design). Runs go to worker processes (:func:`~furuta_drake.diagnosis.parallel.run_tasks`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.systems.controllers import DiscreteTimeLinearQuadraticRegulator

from furuta_drake.config import SimulationConfig
from furuta_drake.controllers.lqr import LqrParameters, design_lqr, zero_order_hold
from furuta_drake.diagnosis.parallel import Failure, run_tasks
from furuta_drake.errors import ConfigError
from furuta_drake.plant import make_furuta_plant
from furuta_drake.tune.controller import (
    Controller,
    arm_friction_observer,
    observer_for,
    upright_rate,
    with_compensation,
)
from furuta_drake.tune.design import DesignModel, design_model, output_lqr, upright_model
from furuta_drake.tune.inputs import TuneInputs, corner_rig, read_diagnosis, world_config
from furuta_drake.tune.margins import Margins, margins
from furuta_drake.tune.predict import Prediction, predict
from furuta_drake.tune.robustness import NotRobust, effect_extremes, linear_corners, margin_failure


@dataclass(frozen=True)
class TuneSettings:
    """How much ``tune`` simulates: ``duration`` [s] of each predicted balancing run (its second half is the
    steady part), the ``seed`` of the disturbance and the encoder noise, the compensation gains (initial K_sigma)
    tried, the input-weight scales tried in turn when a gain falls short of the margins, and the worker processes
    (None: all cores)."""

    duration: float = 10.0
    seed: int = 0
    compensation_gains: tuple[float, ...] = (0.0, 0.5, 0.8, 1.0)
    input_weight_scales: tuple[float, ...] = (1.0, 4.0, 16.0)
    workers: int | None = None

    def validate(self) -> None:
        if not (math.isfinite(self.duration) and self.duration >= 1.0):
            raise ConfigError(f"--duration must be at least 1 s, got {self.duration!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed < 2**32:
            raise ConfigError(f"--seed must be an integer in [0, 2^32), got {self.seed!r}")
        if not self.compensation_gains or any(not (0.0 <= g <= 2.0) for g in self.compensation_gains):
            raise ConfigError(f"compensation gains must lie in [0, 2], got {self.compensation_gains!r}")
        if not self.input_weight_scales or any(not s > 0 for s in self.input_weight_scales):
            raise ConfigError(f"input weight scales must be positive, got {self.input_weight_scales!r}")
        if self.workers is not None and self.workers < 1:
            raise ConfigError(f"--workers must be >= 1, got {self.workers}")


FAST = TuneSettings(duration=3.0, compensation_gains=(0.0, 1.0), input_weight_scales=(1.0, 16.0))
"""Settings for quick checks: short runs, two compensation gains."""


@dataclass
class DesignOutcome:
    """A controller and how it does on the corrected model: ``margins`` at the fit and at every linear corner
    (``corner_margins``: label -> Margins), the predicted run at the fit and at each effect extreme
    (``extremes``: label -> Prediction), and whether it meets the requirements there (``failure``: why not)."""

    controller: Controller
    margins: Margins
    corner_margins: dict[str, Margins]
    prediction: Prediction
    extremes: dict[str, Prediction] = field(default_factory=dict)
    failure: str = ""

    @property
    def robust(self) -> bool:
        return not self.failure

    def worst_corner(self) -> tuple[str, Margins]:
        """The linear corner of the smallest delay margin (the fit when there is none)."""
        items = list(self.corner_margins.items()) or [("the fit", self.margins)]
        return min(items, key=lambda item: (item[1].stable, item[1].delay_s))


@dataclass
class Tuning:
    """A finished ``tune``: its inputs, the corrected model (``world``), the design model at the fit, the two
    designs, every candidate tried (``candidates``: rows with the reason it was not chosen) and notes."""

    inputs: TuneInputs
    world: SimulationConfig
    model: DesignModel
    settings: TuneSettings
    nominal: DesignOutcome
    tuned: DesignOutcome
    candidates: list[dict]
    notes: list[str]


def _run(task) -> Prediction:
    world, controller, duration, seed = task
    return predict(world, controller, duration=duration, seed=seed)


def run_predictions(tasks: list, settings: TuneSettings) -> list[Prediction]:
    """The predictions of (world, controller) pairs with the settings' duration and seed, on worker processes; a
    run that raised is a fallen one, with the reason."""
    calls = [(world, controller, settings.duration, settings.seed) for world, controller in tasks]
    results = run_tasks(_run, calls, workers=settings.workers)
    return [Prediction(None, result.reason, None) if isinstance(result, Failure) else result for result in results]


def nominal_controller(inputs: TuneInputs) -> Controller:
    """The package's LQ design on the rig file's rigid body, on the HG observer at its defaults."""
    rig = inputs.nominal
    lqr = dataclasses.replace(LqrParameters(), torque_limit=rig.torque_limit)
    K = design_lqr(make_furuta_plant(rig), lqr, period=rig.sample_period)
    return Controller(tuple(float(k) for k in K.ravel()), "hg", rig.torque_limit, lqr)


def delay_free_gain(A: np.ndarray, B: np.ndarray, lqr: LqrParameters, period: float) -> np.ndarray:
    """The DARE gain of the design model's plant without its delay and lag (a start of the output LQ design):
    with a lag state, the torque enters x through the lag state's column."""
    B_plant = A[:4, 4:] if A.shape[0] > 4 else B[:4]
    Ad, Bd = zero_order_hold(A[:4, :4], B_plant[:, :1], period)
    K, _ = DiscreteTimeLinearQuadraticRegulator(Ad, Bd, np.diag(lqr.state_weights), np.array([[lqr.input_weight]]))
    return K


@dataclass
class _Problem:
    """What every candidate is judged on: the corrected model (``world``, its design model and linearization), the
    linear corners' design models, the effect extremes' models, the fitted friction's Dahl observer, the
    nominal controller, the settings."""

    inputs: TuneInputs
    world: SimulationConfig
    model: DesignModel
    A: np.ndarray
    B: np.ndarray
    corners: list[tuple[str, DesignModel]]
    extremes: list[tuple[str, SimulationConfig]]
    dahl: object
    nominal: Controller
    settings: TuneSettings

    @property
    def period(self) -> float:
        return self.world.control_period

    def margins_of(self, K) -> tuple[Margins, dict[str, Margins]]:
        """K's margins at the fit and at every linear corner."""
        return margins(self.model, K), {label: margins(model, K) for label, model in self.corners}

    def at_extremes(self, controller: Controller) -> dict[str, Prediction]:
        return dict(
            zip(
                [label for label, _ in self.extremes],
                run_predictions([(world, controller) for _, world in self.extremes], self.settings),
            )
        )


def tune(
    directory: str | Path, settings: TuneSettings = TuneSettings(), progress: Callable[[str], None] | None = None
) -> Tuning:
    """Design and predict both controllers of the diagnosis in ``directory`` (module docstring); NotRobust when
    no tuned controller meets the requirements over the intervals."""
    settings.validate()
    say = progress or (lambda line: None)
    inputs = read_diagnosis(directory)
    world = world_config(inputs.rig)
    A, B = upright_model(world)
    problem = _Problem(
        inputs,
        world,
        design_model(world),
        A,
        B,
        [(label, design_model(world_config(corner_rig(inputs, c)))) for label, c in linear_corners(inputs)],
        [(label, world_config(corner_rig(inputs, c))) for label, c in effect_extremes(inputs)],
        arm_friction_observer(world.friction.arm, world.encoder.encoder_resolution),
        nominal_controller(inputs),
        settings,
    )
    say(
        f"design model: {problem.model.size} states; {len(problem.corners)} linear corners, "
        f"{len(problem.extremes)} effect extremes"
    )
    candidates, failures = [], []
    tuned = next(
        (
            outcome
            for scale in settings.input_weight_scales
            if (outcome := _tuned_at(problem, scale, candidates, failures, say)) is not None
        ),
        None,
    )
    if tuned is None:
        raise NotRobust(
            "no tuned design is robust over the parameters' 95 % intervals: " + " | ".join(failures or ["no candidate"])
        )
    say("the nominal design on the corrected model")
    nominal = _nominal_outcome(problem)
    return Tuning(inputs, world, problem.model, settings, nominal, tuned, candidates, list(inputs.notes))


def _tuned_at(problem: _Problem, scale: float, candidates: list, failures: list, say) -> DesignOutcome | None:
    """The tuned design with the input weight times ``scale``, or None (the reasons appended to ``failures``, every
    candidate to ``candidates``)."""
    nominal = problem.nominal
    lqr = dataclasses.replace(nominal.lqr, input_weight=nominal.lqr.input_weight * scale)
    starts = [np.asarray(nominal.gain), delay_free_gain(problem.A, problem.B, nominal.lqr, problem.period)]
    try:
        K = output_lqr(problem.model, lqr.state_weights, lqr.input_weight, starts)
    except ConfigError as err:
        failures.append(f"R x {scale:g}: {err}")
        return None
    fit_margins, corner_margins = problem.margins_of(K)
    failure = shortfall({"the fit": fit_margins, **corner_margins}, {}, problem.period)
    gain = tuple(float(k) for k in K.ravel())
    if failure:
        failures.append(f"R x {scale:g}: {failure}")
        candidates.append({"input_weight_scale": scale, "lqr_gain": list(gain), "rejected": failure})
        return None
    source, hg, vfe = observer_for(upright_rate(problem.A), problem.period, problem.dahl)
    base = Controller(gain, source, nominal.torque_limit, lqr, hg, vfe, problem.dahl)
    gains = problem.settings.compensation_gains if problem.dahl is not None else (0.0,)
    trials = [with_compensation(base, g) for g in dict.fromkeys(gains)]
    say(f"R x {scale:g}: {len(trials)} candidate(s) on the corrected model")
    runs = run_predictions([(problem.world, trial) for trial in trials], problem.settings)
    rows = [
        {
            "input_weight_scale": scale,
            "lqr_gain": list(gain),
            "compensation_gain": trial.compensation,
            "predicted": run.figures,
            "fell": run.fell,
        }
        for trial, run in zip(trials, runs)
    ]
    candidates += rows
    for index in ranked(runs, problem.world.encoder.encoder_resolution):
        trial, row = trials[index], rows[index]
        say(f"R x {scale:g}, compensation {trial.compensation:g}: runs at the effect extremes")
        extremes = problem.at_extremes(trial)
        fell = [f"{label}: {run.fell}" for label, run in extremes.items() if not run.balanced]
        if fell:
            row["rejected"] = "fell at " + "; ".join(fell)
            failures.append(f"R x {scale:g}, compensation {trial.compensation:g}: {row['rejected']}")
            continue
        row["chosen"] = True
        return DesignOutcome(trial, fit_margins, corner_margins, runs[index], extremes)
    return None


def _nominal_outcome(problem: _Problem) -> DesignOutcome:
    """The nominal design on the corrected model: its margins at the fit and corners, its runs at the fit and the
    effect extremes, and the first requirement it misses."""
    nominal = problem.nominal
    fit_margins, corner_margins = problem.margins_of(np.asarray(nominal.gain))
    worlds = [("the fit", problem.world), *problem.extremes]
    runs = run_predictions([(world, nominal) for _, world in worlds], problem.settings)
    fit, extremes = runs[0], {label: run for (label, _), run in zip(problem.extremes, runs[1:])}
    outcome = DesignOutcome(nominal, fit_margins, corner_margins, fit, extremes)
    outcome.failure = shortfall(
        {"the fit": fit_margins, **corner_margins}, {"the fit": fit, **outcome.extremes}, problem.period
    )
    return outcome


def shortfall(corner_margins: dict[str, Margins], runs: dict[str, Prediction], period: float) -> str:
    """The first requirement a design misses: its margins at a corner (``corner_margins``), or a run that fell
    (``runs``); '' when it meets them all."""
    for label, m in corner_margins.items():
        reason = margin_failure(m, period)
        if reason:
            return f"at {label}: {reason}"
    return next((f"fell at {label}: {run.fell}" for label, run in runs.items() if not run.balanced), "")


def ranked(runs: list[Prediction], count: float) -> list[int]:
    """Indices of the balanced ``runs``, best first: the smallest limit-cycle amplitude, amplitudes within one
    encoder ``count`` [rad] of each other tied and ordered by theta's RMS."""
    balanced = [i for i, run in enumerate(runs) if run.balanced]
    if not balanced:
        return []
    order = sorted(balanced, key=lambda i: runs[i].figures["limit_cycle_amplitude"])
    out = []
    while order:
        best = runs[order[0]].figures["limit_cycle_amplitude"]
        tied = [i for i in order if runs[i].figures["limit_cycle_amplitude"] <= best + count]
        tied.sort(key=lambda i: runs[i].figures["theta_rms"])
        out.append(tied[0])
        order.remove(tied[0])
    return out
