"""``tune``: the nominal and the tuned controller of a diagnosed rig, predicted side by side on the corrected model.

1. Read the diagnosis (:mod:`.inputs`) and build the corrected model (the fitted rig file as a simulate config),
   its design model (:mod:`.design`: Drake's linearization, the delay and lag as states), the linear corners and
   the effect extremes of the parameters' 95 % intervals (:mod:`.robustness`).
2. The **nominal** controller: the package's LQ design on the rig file's rigid body, on the HG observer at its
   defaults with the rig file's model (:mod:`.controller`); its margins and runs at the fit and the extremes.
3. The **tuned** controller: the best of a family of designs on the corrected model (:mod:`.family`: LQ weight
   scalings, the observer's time scale, the compensation gain), chosen by the worst case over the intervals of
   theta's RMS and the limit cycle against the nominal design's, the margins at every linear corner a
   requirement; the nominal design is a member. No design left: :class:`~.robustness.NotRobust`.
4. With a swing-up configured (``TuneSettings.swingup``), each design's catch time behind it (:mod:`.swingup`).

Under the rig's ongoing disturbance (the diagnosis' ``disturbance``), every prediction is the mean over seeded
draws of it, and each design is also predicted at half and twice its level (:mod:`.disturbance`).

Every run starts from the same seeded disturbance and encoder noise (common random numbers: the designs differ
only by their design). Runs go to worker processes (:func:`~furuta_drake.parallel.run_tasks`).
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from furuta_drake.config import SimulationConfig
from furuta_drake.controllers.lqr import LqrParameters, design_lqr
from furuta_drake.effects.corrected import rig_config
from furuta_drake.errors import ConfigError
from furuta_drake.plant import make_furuta_plant
from furuta_drake.tune.controller import Controller, arm_friction_observer
from furuta_drake.tune.design import DesignModel, design_model, upright_model
from furuta_drake.tune.disturbance import quiet_winner_note, under_disturbance
from furuta_drake.tune.family import DesignOutcome, Problem, disturbed, run_budget, search, shortfall
from furuta_drake.tune.inputs import TuneInputs, corner_rig, read_diagnosis
from furuta_drake.tune.robustness import effect_extremes, linear_corners
from furuta_drake.tune.swingup import SwingUpCheck, catch_times

WEIGHT_SETS = (
    (1.0, 1.0, 1.0),
    (1.0, 1.0, 4.0),
    (1.0, 1.0, 16.0),
    (1.0, 1.0, 0.25),
    (4.0, 1.0, 1.0),
    (16.0, 1.0, 1.0),
    (1.0, 0.25, 1.0),
)
"""The family's LQ weights: scales of (Q_theta, Q_phi, R) over the package's: its own, gentler (R x 4, x 16),
stiffer (R / 4), the pendulum weighted more (Q_theta x 4, x 16: the pendulum held harder against an ongoing push),
the arm held more loosely (Q_phi / 4)."""


@dataclass(frozen=True)
class TuneSettings:
    """How much ``tune`` simulates: ``duration`` [s] of each predicted balancing run (its second half is the
    steady part), the ``seed`` of the disturbance and the encoder noise, the family searched
    (:mod:`.family`: ``weight_sets`` of (Q_theta, Q_phi, R) scales, the other ``observer_scales`` tried, the
    ``compensation_gains`` (initial K_sigma; the first in round 1) and the number of ``finalists`` run over the
    intervals), the seeded ``draws`` of the rig's disturbance each prediction averages (when the diagnosis read
    one; :mod:`.disturbance`), the worker processes (None: all cores) and the configured swing-up whose catch
    time each design is predicted with (``swingup``, :mod:`.swingup`; None: none configured)."""

    duration: float = 10.0
    seed: int = 0
    weight_sets: tuple[tuple[float, float, float], ...] = WEIGHT_SETS
    observer_scales: tuple[float, ...] = (0.5, 2.0)
    compensation_gains: tuple[float, ...] = (0.5, 0.0, 1.0)
    finalists: int = 2
    draws: int = 3
    workers: int | None = None
    swingup: SwingUpCheck | None = None

    def validate(self) -> None:
        if not (math.isfinite(self.duration) and self.duration >= 1.0):
            raise ConfigError(f"--duration must be at least 1 s, got {self.duration!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed < 2**32:
            raise ConfigError(f"--seed must be an integer in [0, 2^32), got {self.seed!r}")
        if not self.compensation_gains or any(not (0.0 <= g <= 2.0) for g in self.compensation_gains):
            raise ConfigError(f"compensation gains must lie in [0, 2], got {self.compensation_gains!r}")
        if not self.weight_sets or any(
            len(w) != 3 or not all(math.isfinite(v) and v > 0 for v in w) for w in self.weight_sets
        ):
            raise ConfigError(f"weight sets must be positive (Q_theta, Q_phi, R) scales, got {self.weight_sets!r}")
        if any(not (math.isfinite(s) and s > 0) for s in self.observer_scales):
            raise ConfigError(f"observer scales must be positive, got {self.observer_scales!r}")
        if isinstance(self.finalists, bool) or not isinstance(self.finalists, int) or self.finalists < 1:
            raise ConfigError(f"finalists must be a positive integer, got {self.finalists!r}")
        if isinstance(self.draws, bool) or not isinstance(self.draws, int) or self.draws < 1:
            raise ConfigError(f"--draws must be a positive integer, got {self.draws!r}")
        if self.workers is not None and self.workers < 1:
            raise ConfigError(f"--workers must be >= 1, got {self.workers}")


FAST = TuneSettings(
    duration=3.0,
    weight_sets=((1.0, 1.0, 1.0), (1.0, 1.0, 16.0)),
    observer_scales=(),
    compensation_gains=(0.0, 1.0),
    draws=1,
)
"""Settings for quick checks: short runs, two weight sets, two compensation gains, one draw of a disturbance."""


@dataclass
class Tuning:
    """A finished ``tune``: its inputs, the corrected model (``world``), the design model at the fit, the two
    designs, every candidate tried (``candidates``: rows with the reason it was not chosen), the search's budget
    of Drake runs (``budget``) and notes."""

    inputs: TuneInputs
    world: SimulationConfig
    model: DesignModel
    settings: TuneSettings
    nominal: DesignOutcome
    tuned: DesignOutcome
    candidates: list[dict]
    notes: list[str]
    budget: int = 0
    swingup: dict | None = None
    under_disturbance: dict = dataclasses.field(default_factory=dict)  # design -> scale -> figures


def nominal_controller(inputs: TuneInputs) -> Controller:
    """The package's LQ design on the rig file's rigid body, on the HG observer at its defaults with the rig file's
    model."""
    rig = inputs.nominal
    lqr = dataclasses.replace(LqrParameters(), torque_limit=rig.torque_limit)
    K = design_lqr(make_furuta_plant(rig), lqr, period=rig.sample_period)
    return Controller(tuple(float(k) for k in K.ravel()), "hg", rig.torque_limit, lqr, model=rig)


def tune(
    directory: str | Path, settings: TuneSettings = TuneSettings(), progress: Callable[[str], None] | None = None
) -> Tuning:
    """Design and predict both controllers of the diagnosis in ``directory`` (module docstring); NotRobust when
    no design meets the requirements over the intervals."""
    settings.validate()
    say = progress or (lambda line: None)
    inputs = read_diagnosis(directory)
    world = corner_config(inputs, "", {})
    A, B = upright_model(world)
    problem = Problem(
        inputs,
        world,
        design_model(world),
        A,
        B,
        [(label, design_model(corner_config(inputs, label, c))) for label, c in linear_corners(inputs)],
        [(label, corner_config(inputs, label, c)) for label, c in effect_extremes(inputs)],
        arm_friction_observer(world.friction.arm, world.encoder.encoder_resolution),
        nominal_controller(inputs),
        settings,
    )
    budget = run_budget(settings, problem.dahl is not None, len(inputs.accepted), disturbed(world))
    say(
        f"design model: {problem.model.size} states; {len(problem.corners)} linear corners, "
        f"{len(problem.extremes)} effect extremes; at most {budget} Drake runs"
    )
    say("the nominal design on the corrected model")
    nominal = nominal_outcome(problem)
    tuned, candidates, finalists = search(problem, nominal, say)
    notes = list(inputs.notes)
    if disturbed(world):
        say("both designs at 0.5 and 2 times the rig's disturbance")
        notes += [note for note in [quiet_winner_note(problem, nominal, tuned, finalists)] if note]
    tuning = Tuning(inputs, world, problem.model, settings, nominal, tuned, candidates, notes, budget)
    tuning.under_disturbance = under_disturbance(problem, {"nominal": nominal, "tuned": tuned})
    if settings.swingup is not None:
        say("both designs behind the configured swing-up, at the fit and the effect extremes")
        tuning.swingup = catch_times(
            [("the fit", world), *problem.extremes],
            {"nominal": nominal.controller, "tuned": tuned.controller},
            settings.swingup,
            seed=settings.seed,
            workers=settings.workers,
        )
    return tuning


def corner_config(inputs: TuneInputs, label: str, corner: dict) -> SimulationConfig:
    """The corrected model at a ``corner`` of the intervals as a simulate config; ConfigError naming the corner
    when its parameters make a rig that is not physical (an interval wider than the rig allows)."""
    try:
        config = rig_config(corner_rig(inputs, corner))
        config.rig.validate()
        return config
    except ConfigError as err:
        raise ConfigError(
            f"{inputs.directory}: the fitted effects give a rig that is not physical "
            + (f"at the intervals' corner {label}" if label else "at the fit")
            + f": {err}"
        ) from None


def nominal_outcome(problem: Problem) -> DesignOutcome:
    """The nominal design on the corrected model: its margins at the fit and corners, its runs at the fit and the
    effect extremes, and the first requirement it misses."""
    nominal = problem.nominal
    fit_margins, corner_margins = problem.margins_of(nominal.gain)
    worlds = [("the fit", problem.world), *problem.extremes]
    runs = problem.predictions([(world, nominal) for _, world in worlds])
    fit, extremes = runs[0], {label: run for (label, _), run in zip(problem.extremes, runs[1:])}
    outcome = DesignOutcome(nominal, fit_margins, corner_margins, fit, extremes)
    outcome.failure = shortfall(
        {"the fit": fit_margins, **corner_margins}, {"the fit": fit, **outcome.extremes}, problem.period
    )
    return outcome


__all__ = ["TuneSettings", "FAST", "Tuning", "DesignOutcome", "nominal_controller", "tune", "nominal_outcome"]
