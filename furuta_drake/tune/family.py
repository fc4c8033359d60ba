"""The family of designs ``tune`` chooses the tuned controller from, and the robust choice among them.

A :class:`Member` is a design recipe on the corrected model: the LQ weights as scales of the package's Q_theta,
Q_phi and R, the observer's time scale over the default of :func:`~.controller.observer_for` (HG eps, or the
inverse of the VFE's eigenvalues), and the friction compensation's initial K_sigma. Its gain is the output LQ gain
of those weights on the design model (:func:`~.design.output_lqr`).

Every member is judged against the **nominal design** (the rig file's LQR on its HG observer) by :func:`score`:
theta's RMS and the limit cycle's amplitude, each as a ratio to the nominal's; the larger ratio first (a design is
better only when it is better in both), their sum breaking ties. The search, within a fixed budget of Drake runs
(:func:`run_budget`):

0. each weight set's gain must keep the margins (:mod:`.robustness`) at the fit and at every linear corner of the
   intervals; a set that does not is out before any run;
1. round 1 runs each remaining weight set with the default observer and the first compensation gain (none without
   arm friction in the model) on the corrected model at the fit; round 2 the best member so far with each other
   observer scale, and with arm friction in the model each scale of the other observer (the HG beside the VFE);
   round 3, when the model has arm friction, the best so far with each other compensation gain;
2. the ``finalists`` best members at the fit are run at every effect extreme (each accepted effect's parameters at
   the lower, then the upper ends of their 95 % intervals); one that falls there is out;
3. the tuned design is the finalist of the smallest **robust score**: the score of each figure's worst over the fit
   and the extremes, as a ratio to the nominal design's worst. The nominal design itself competes when it meets
   the requirements over the intervals and wins ties: the tuned design's predicted worst case is never worse than
   the nominal's. A finalist replaces it only when it is predicted better by at least ``MIN_GAIN`` in one figure
   and no worse in the other (:func:`clears_nominal`): a smaller predicted gain is within what the seeds of the
   disturbance and the encoder noise alone move a balancing figure, so the change would be a coin toss on the rig.

Every run starts from the same seeded disturbance and encoder noise (common random numbers: members differ only by
their design), so the search is reproducible and its differences are the designs'.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pydrake.systems.controllers import DiscreteTimeLinearQuadraticRegulator

from furuta_drake.config import SimulationConfig
from furuta_drake.controllers.lqr import LqrParameters, zero_order_hold
from furuta_drake.errors import ConfigError
from furuta_drake.parallel import Failure, run_tasks
from furuta_drake.tune.controller import Controller, observer_for, upright_rate, with_compensation
from furuta_drake.tune.design import DesignModel, output_lqr
from furuta_drake.tune.inputs import TuneInputs
from furuta_drake.tune.margins import Margins, margins
from furuta_drake.tune.predict import Prediction, predict
from furuta_drake.tune.robustness import NotRobust, margin_failure

JUDGED = ("theta_rms", "limit_cycle_amplitude")  # the figures a design is judged by
FLOOR_COUNTS = 0.5  # a reference figure below half an encoder count is taken as half a count (no ratio blows up)
MIN_GAIN = 0.05  # the least predicted gain (relative, in one judged figure) for which a member replaces the nominal


@dataclass(frozen=True)
class Member:
    """A design recipe: ``weights`` (scales of Q_theta, Q_phi and R over the package's LQ weights), ``observer``
    (the observer's time scale over the default), ``compensation`` (the initial K_sigma; 0: none) and
    ``kind`` (the observer, 'hg' or 'vfe'; None: :func:`~.controller.observer_for`'s default for the model)."""

    weights: tuple[float, float, float] = (1.0, 1.0, 1.0)
    observer: float = 1.0
    compensation: float = 0.0
    kind: str | None = None

    def as_dict(self) -> dict:
        theta, phi, r = self.weights
        return {
            "theta_weight_scale": theta,
            "phi_weight_scale": phi,
            "input_weight_scale": r,
            "observer_kind": self.kind,
            "observer_scale": self.observer,
            "compensation_gain": self.compensation,
        }

    def lqr(self, base: LqrParameters) -> LqrParameters:
        """``base``'s weights scaled (module docstring)."""
        theta, phi, r = self.weights
        q = list(base.state_weights)
        return dataclasses.replace(
            base, state_weights=[q[0] * theta, q[1] * phi, *q[2:]], input_weight=base.input_weight * r
        )


@dataclass
class DesignOutcome:
    """A controller and how it does on the corrected model: ``margins`` at the fit and at every linear corner
    (``corner_margins``: label -> Margins), the predicted run at the fit and at each effect extreme
    (``extremes``: label -> Prediction), whether it meets the requirements there (``failure``: why not), and the
    family ``member`` it was made from (None: the nominal design)."""

    controller: Controller
    margins: Margins
    corner_margins: dict[str, Margins]
    prediction: Prediction
    extremes: dict[str, Prediction] = field(default_factory=dict)
    failure: str = ""
    member: Member | None = None

    @property
    def robust(self) -> bool:
        return not self.failure

    def worst_corner(self) -> tuple[str, Margins]:
        """The linear corner of the smallest delay margin (the fit when there is none)."""
        items = list(self.corner_margins.items()) or [("the fit", self.margins)]
        return min(items, key=lambda item: (item[1].stable, item[1].delay_s))

    def runs(self) -> list[Prediction]:
        """The predicted runs at the fit and at every effect extreme."""
        return [self.prediction, *self.extremes.values()]


@dataclass
class Problem:
    """What every design is judged on: the corrected model (``world``, its design model and linearization ``A``,
    ``B``), the linear corners' design models, the effect extremes' models, the fitted friction's Dahl observer,
    the nominal controller and the settings (:class:`~.pipeline.TuneSettings`)."""

    inputs: TuneInputs
    world: SimulationConfig
    model: DesignModel
    A: np.ndarray
    B: np.ndarray
    corners: list[tuple[str, DesignModel]]
    extremes: list[tuple[str, SimulationConfig]]
    dahl: object
    nominal: Controller
    settings: object

    @property
    def period(self) -> float:
        return self.world.control_period

    @property
    def count(self) -> float:
        """One encoder count [rad]."""
        return self.world.encoder.encoder_resolution

    def margins_of(self, K) -> tuple[Margins, dict[str, Margins]]:
        """K's margins at the fit and at every linear corner."""
        return margins(self.model, K), {label: margins(model, K) for label, model in self.corners}

    def predictions(self, tasks: list[tuple[SimulationConfig, Controller]]) -> list[Prediction]:
        """The predictions of (world, controller) pairs with the settings' duration, on worker processes: under a
        world's ongoing disturbance the mean over ``settings.draws`` seeded draws of it (seeds ``seed`` to
        ``seed + draws - 1``, the same for every pair), else one run at ``seed``; a run that raised is a fallen
        one, with the reason."""
        settings = self.settings
        counts = [draws_of(world, settings.draws) for world, _ in tasks]
        calls = [
            (world, controller, settings.duration, settings.seed + draw)
            for (world, controller), count in zip(tasks, counts)
            for draw in range(count)
        ]
        results = run_tasks(_run, calls, workers=settings.workers)
        runs = [Prediction(None, result.reason, None) if isinstance(result, Failure) else result for result in results]
        out, start = [], 0
        for count in counts:
            out.append(mean_prediction(runs[start : start + count]))
            start += count
        return out

    def at_extremes(self, controller: Controller) -> dict[str, Prediction]:
        runs = self.predictions([(world, controller) for _, world in self.extremes])
        return dict(zip([label for label, _ in self.extremes], runs))


def disturbed(world: SimulationConfig) -> bool:
    """Whether ``world`` carries an ongoing arm disturbance."""
    disturbance = world.disturbance.arm_torque
    return disturbance is not None and disturbance.active


def draws_of(world: SimulationConfig, draws: int) -> int:
    """The runs a prediction on ``world`` takes: ``draws`` under an ongoing disturbance, else 1."""
    return draws if disturbed(world) else 1


def mean_prediction(runs: list[Prediction]) -> Prediction:
    """One prediction of several draws: each figure's mean, the first draw's tape; fallen when one draw fell."""
    fallen = next((run for run in runs if not run.balanced), None)
    if fallen is not None:
        return fallen
    figures = {key: float(np.mean([run.figures[key] for run in runs])) for key in runs[0].figures}
    return Prediction(figures, "", runs[0].result)


def _run(task) -> Prediction:
    world, controller, duration, seed = task
    return predict(world, controller, duration=duration, seed=seed)


def delay_free_gain(A: np.ndarray, B: np.ndarray, lqr: LqrParameters, period: float) -> np.ndarray:
    """The DARE gain of the design model's plant without its delay and lag (a start of the output LQ design):
    with a lag state, the torque enters x through the lag state's column."""
    B_plant = A[:4, 4:] if A.shape[0] > 4 else B[:4]
    Ad, Bd = zero_order_hold(A[:4, :4], B_plant[:, :1], period)
    K, _ = DiscreteTimeLinearQuadraticRegulator(Ad, Bd, np.diag(lqr.state_weights), np.array([[lqr.input_weight]]))
    return K


def shortfall(corner_margins: dict[str, Margins], runs: dict[str, Prediction], period: float) -> str:
    """The first requirement a design misses: its margins at a corner (``corner_margins``), or a run that fell
    (``runs``); '' when it meets them all."""
    for label, m in corner_margins.items():
        reason = margin_failure(m, period)
        if reason:
            return f"at {label}: {reason}"
    return next((f"fell at {label}: {run.fell}" for label, run in runs.items() if not run.balanced), "")


def worst(runs: list[Prediction]) -> dict | None:
    """Each judged figure's largest over ``runs``; None when one of them fell."""
    if not runs or not all(run.balanced for run in runs):
        return None
    return {figure: max(run.figures[figure] for run in runs) for figure in JUDGED}


def ratios(figures: dict, reference: dict | None, count: float) -> list[float]:
    """The judged ``figures``' ratios to ``reference``'s, each reference at least ``FLOOR_COUNTS`` encoder counts
    (``count`` [rad]; all of it without a reference)."""
    floor = FLOOR_COUNTS * count
    return [figures[f] / max(reference[f] if reference else 0.0, floor) for f in JUDGED]


def score(figures: dict | None, reference: dict | None, count: float) -> tuple[float, float]:
    """(the larger, the sum) of :func:`ratios`; (inf, inf) for no figures. Smaller is better: below 1 in its first
    entry, a design is better than the reference in both figures."""
    if figures is None:
        return (math.inf, math.inf)
    judged = ratios(figures, reference, count)
    return (max(judged), sum(judged))


def observer_kinds(friction: bool) -> tuple[str, ...]:
    """The observers the search tries: the VFE and the HG with arm friction in the model, else the HG."""
    return ("vfe", "hg") if friction else ("hg",)


def clears_nominal(judged: list[float]) -> bool:
    """Whether a finalist whose worst case has the :func:`ratios` ``judged`` to the nominal design's worst case may
    replace a nominal design that meets the requirements: no figure worse, one better by ``MIN_GAIN`` at least."""
    return max(judged) <= 1.0 and min(judged) <= 1.0 - MIN_GAIN


def run_budget(settings, friction: bool, effects: int, disturbed: bool = False) -> int:
    """The most Drake runs the search makes (module docstring), the nominal design's fit and extremes included;
    under a disturbance each prediction takes ``settings.draws`` runs, and both designs are predicted at two more
    levels and, for the quiet check, once without it (:mod:`.disturbance`)."""
    compensation = len(settings.compensation_gains) - 1 if friction else 0
    observers = len(observer_kinds(friction)) * (1 + len(settings.observer_scales)) - 1
    fit = len(settings.weight_sets) + observers + compensation
    extremes = 2 * effects
    runs = fit + settings.finalists * extremes + 1 + extremes
    return runs * settings.draws + 2 * 2 * settings.draws + 2 if disturbed else runs


def member_gain(problem: Problem, member: Member) -> np.ndarray:
    """The output LQ gain of ``member``'s weights on the design model (ConfigError when none stabilises it)."""
    lqr = member.lqr(problem.nominal.lqr)
    starts = [np.asarray(problem.nominal.gain), delay_free_gain(problem.A, problem.B, lqr, problem.period)]
    return output_lqr(problem.model, lqr.state_weights, lqr.input_weight, starts)


def member_controller(problem: Problem, member: Member, K) -> Controller:
    """``member``'s controller with the gain ``K``: its observer on the corrected model, its compensation."""
    nominal = problem.nominal
    source, hg, vfe = observer_for(upright_rate(problem.A), problem.period, problem.dahl, member.observer, member.kind)
    gain = tuple(float(k) for k in np.ravel(K))
    base = Controller(gain, source, nominal.torque_limit, member.lqr(nominal.lqr), hg, vfe, problem.dahl)
    return with_compensation(base, member.compensation)


@dataclass
class _Search:
    """The search's state: the admissible weight sets' gains and margins, every member run at the fit, and the
    rows of ``tune.json``'s ``candidates``."""

    problem: Problem
    reference: dict | None  # the nominal design's figures at the fit
    gains: dict = field(default_factory=dict)  # weights -> (K, fit margins, corner margins)
    runs: dict = field(default_factory=dict)  # Member -> Prediction at the fit
    rows: dict = field(default_factory=dict)  # Member (or weights) -> candidate row
    controllers: list = field(default_factory=list)  # the controllers run, one per member run

    def fit_score(self, member: Member) -> tuple[float, float]:
        run = self.runs[member]
        return score(run.figures, self.reference, self.problem.count)

    def best(self) -> Member | None:
        balanced = [m for m, run in self.runs.items() if run.balanced]
        return min(balanced, key=self.fit_score) if balanced else None

    def run(self, members: list[Member]) -> None:
        """Run the members not run yet at the fit."""
        fresh = []
        for member in dict.fromkeys(members):
            if member in self.runs or member.weights not in self.gains:
                continue
            controller = member_controller(self.problem, member, self.gains[member.weights][0])
            if controller not in self.controllers:  # an observer scale at its floor makes no new design
                self.controllers.append(controller)
                fresh.append((member, controller))
        members, controllers = [m for m, _ in fresh], [c for _, c in fresh]
        for member, controller, run in zip(
            members, controllers, self.problem.predictions([(self.problem.world, c) for c in controllers])
        ):
            self.runs[member] = run
            self.rows[member] = {
                **member.as_dict(),
                "lqr_gain": list(controller.gain),
                "predicted": run.figures,
                "fell": run.fell,
                "score_at_fit": list(score(run.figures, self.reference, self.problem.count)),
            }


def search(
    problem: Problem, nominal: DesignOutcome, say: Callable[[str], None]
) -> tuple[DesignOutcome, list, list[DesignOutcome]]:
    """The tuned design (module docstring), the candidate rows and the finalists that balanced at every effect
    extreme, best at the fit first; NotRobust when no member nor the nominal design meets the requirements over
    the intervals."""
    settings = problem.settings
    found = _Search(problem, nominal.prediction.figures)
    failures = _admissible_gains(problem, found, settings.weight_sets)
    friction = problem.dahl is not None
    gains = settings.compensation_gains if friction else (0.0,)
    say(f"round 1: {len(found.gains)} weight set(s) on the corrected model")
    kinds = observer_kinds(friction)
    found.run([Member(weights, 1.0, gains[0], kinds[0]) for weights in settings.weight_sets])
    observers = [(kind, scale) for kind in kinds for scale in (1.0, *settings.observer_scales)]
    for label, variants in (("observers", observers), ("compensation gains", gains[1:])):
        best = found.best()
        if best is None:
            continue
        if label == "observers":
            others = [
                dataclasses.replace(best, kind=k, observer=s)
                for k, s in variants
                if (k, s) != (best.kind, best.observer)
            ]
        else:
            others = [dataclasses.replace(best, compensation=value) for value in variants]
        if others:
            say(f"the best so far with {len(others)} other {label}")
            found.run(others)
    balanced = sorted((m for m, run in found.runs.items() if run.balanced), key=found.fit_score)
    finalists = balanced[: settings.finalists]
    reference = worst(nominal.runs()) if nominal.robust else None
    options = [(score(reference, reference, problem.count), 0, nominal)] if nominal.robust else []
    standing = []
    for rank, member in enumerate(finalists, start=1):
        say(f"finalist {rank}: its runs at the effect extremes")
        outcome = _finalist(problem, found, member)
        row = found.rows[member]
        row["finalist"] = True
        if outcome.failure:
            row["rejected"] = outcome.failure
            failures.append(f"{member_label(member)}: {outcome.failure}")
            continue
        standing.append(outcome)
        figures = worst(outcome.runs())
        robust = score(figures, reference, problem.count)
        row["worst_over_intervals"] = figures
        row["robust_score"] = list(robust)
        if nominal.robust and not clears_nominal(ratios(figures, reference, problem.count)):
            row["rejected"] = (
                f"predicted better by less than {MIN_GAIN:.0%} over the intervals: the nominal design stays"
            )
            continue
        options.append((robust, rank, outcome))
    for member, row in found.rows.items():
        if isinstance(member, Member) and not row.get("finalist") and row.get("fell") == "":
            row["rejected"] = "not among the finalists at the fit"
    if not options:
        raise NotRobust(
            "no tuned design is robust over the parameters' 95 % intervals: "
            + " | ".join(failures + [f"the nominal design: {nominal.failure}"])
        )
    chosen = min(options, key=lambda option: (option[0], option[1]))[2]
    if chosen.member is not None:
        found.rows[chosen.member]["chosen"] = True
    rows = [{"design": "nominal", "chosen": chosen is nominal, "robust": nominal.robust}]
    return chosen, rows + list(found.rows.values()), standing


def _admissible_gains(problem: Problem, found: _Search, weight_sets) -> list[str]:
    """Each weight set's gain and margins into ``found.gains`` when they meet the requirements at every linear
    corner; a row and a reason for each set that does not (returned)."""
    failures = []
    for weights in dict.fromkeys(tuple(float(w) for w in ws) for ws in weight_sets):
        member = Member(weights)
        try:
            K = member_gain(problem, member)
        except ConfigError as err:
            failures.append(f"{member_label(member)}: {err}")
            found.rows[weights] = {**member.as_dict(), "rejected": str(err)}
            continue
        fit_margins, corner_margins = problem.margins_of(K)
        failure = shortfall({"the fit": fit_margins, **corner_margins}, {}, problem.period)
        if failure:
            failures.append(f"{member_label(member)}: {failure}")
            found.rows[weights] = {**member.as_dict(), "lqr_gain": np.ravel(K).tolist(), "rejected": failure}
            continue
        found.gains[weights] = (K, fit_margins, corner_margins)
    return failures


def _finalist(problem: Problem, found: _Search, member: Member) -> DesignOutcome:
    """A finalist's outcome: its margins and its runs at the fit and the effect extremes."""
    K, fit_margins, corner_margins = found.gains[member.weights]
    controller = member_controller(problem, member, K)
    extremes = problem.at_extremes(controller)
    failure = shortfall({}, extremes, problem.period)
    return DesignOutcome(controller, fit_margins, corner_margins, found.runs[member], extremes, failure, member)


def member_label(member: Member) -> str:
    theta, phi, r = member.weights
    return (
        f"Q_theta x {theta:g}, Q_phi x {phi:g}, R x {r:g}, {(member.kind or 'default').upper()} observer x "
        f"{member.observer:g}, K_sigma {member.compensation:g}"
    )
