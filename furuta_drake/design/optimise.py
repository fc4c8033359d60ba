"""The search over the excitation family: the band amplitudes that best separate every pair within the bounds.

A design is a shape (the share of each band, a point of the simplex) at the largest level the bounds allow: the
level starts at the one the command limit and the aimed arm motion allow, and every hypothesis is simulated on
the surrogate (all candidate designs in one batch); a design whose arm angle or pendulum excursion exceeds
``SAFETY`` of its bound under any hypothesis is scaled down by the worst ratio and simulated again, up to
``RESCALES`` times; one still outside is infeasible. Feasible designs are scored by the smallest noncentrality
over the pairs' informative directions (:mod:`furuta_drake.design.criterion`): every pair must be
separated, so the weakest decides. The cheap, linearised noncentrality ranks a generation; its ``ELITE`` best
designs are scored again with iterated refits (a rival fitted further can mimic more), and that score chooses.

The search is a seeded cross-entropy method: the first generation holds each band alone, all bands equally and
random shapes; each later one draws shapes around the best ones so far (Dirichlet draws centred on them).
A direction whose noncentrality stays below ``SEPARABLE`` for every design of the first generation (which spans
the family's bands) is one no experiment of the family separates: it leaves the objective and is reported so.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

from furuta_drake.design.criterion import (
    Parametrised,
    experiment_windows,
    linearised_noncentrality,
    refit_residuals,
)
from furuta_drake.design.family import BANDS, Family
from furuta_drake.design.hypotheses import Hypotheses
from furuta_drake.effects.surrogate import sensor_variance
from furuta_drake.rig import RigParameters

SAFETY = 0.9  # the surrogate's peaks must stay within this share of each bound (the Drake check has the rest)
RESCALES = 3
SEPARABLE = 1.0  # a noncentrality below this is no separation (less than one sample's noise variance in all)
ELITE = 3
CONCENTRATION = 20.0  # Dirichlet concentration of the draws around an elite shape


@dataclass(frozen=True)
class Bounds:
    """What the experiment must respect under every hypothesis."""

    arm: float  # peak |phi| [rad]
    pendulum: float  # peak excursion of theta from hanging (or upright) [rad]
    command: float  # peak |command| [N m]


@dataclass(frozen=True)
class Direction:
    """One way a pair can be told apart: ``truth`` generates the log, ``rival`` is fitted to it."""

    pair: int
    truth: int
    rival: int


@dataclass
class EvaluatedDesign:
    """One evaluated design."""

    shape: np.ndarray  # (BANDS,) share of each band
    level: float  # [rad] (or [N m] for a dither)
    command: np.ndarray  # (N,) the played command [N m]
    runs: dict[int, tuple[np.ndarray, np.ndarray]]  # hypothesis -> (angles (N, 2), logged command (N,))
    peaks: dict[int, dict[str, float]]  # hypothesis -> peak arm angle, pendulum excursion, command
    feasible: bool
    noncentrality: dict[Direction, float] = field(default_factory=dict)  # linearised
    refined: dict[Direction, float] = field(default_factory=dict)  # with iterated refits

    @property
    def amplitudes(self) -> np.ndarray:
        return self.level * self.shape

    def score(self, directions: list[Direction], refined: bool = False) -> float:
        """The smallest noncentrality over ``directions`` (-1 for an infeasible design)."""
        values = self.refined if refined else self.noncentrality
        return min((values.get(d, 0.0) for d in directions), default=0.0) if self.feasible else -1.0


# runner(model, commands (D, N) [N m]) -> (angles (N, 2, D) [rad], logged commands (D, N) [N m])
Runner = Callable[[object, np.ndarray], tuple[np.ndarray, np.ndarray]]


@dataclass
class Search:
    """What :func:`optimise` found: the best design, every candidate, and the directions left out."""

    best: EvaluatedDesign | None
    candidates: list[EvaluatedDesign]
    directions: list[Direction]
    inseparable: list[Direction]


def directions_of(hypotheses: Hypotheses) -> list[Direction]:
    """Both directions of every pair, only the larger model as the truth for a nested one."""
    out = []
    for i, pair in enumerate(hypotheses.pairs):
        out.append(Direction(i, pair.second, pair.first))
        if not pair.nested:
            out.append(Direction(i, pair.first, pair.second))
    return out


class Evaluator:
    """Scores batches of shapes: levels, surrogate runs under every hypothesis, bounds and noncentralities.

    Parameters
    ----------
    family : the excitation family of the simulated experiment (its duration and sample period).
    hypotheses : the hypotheses and pairs; rig : the rig file (encoder counts, windows); scales : the
        candidates' scales (the refits' parameter bounds); bounds : what every run must respect.
    runner : plays (D, N) commands [N m] on a model: (angles (N, 2, D) [rad], logged commands (D, N) [N m]).
    unit_command : (D, BANDS) shapes -> (D, N) commands [N m] at level 1.
    aimed_motion : (D, BANDS) shapes -> (D, N) arm angles [rad] the command aims at, at level 1 (None for a
        dither: the LQR holds the arm).
    hanging : the runs start hanging (the pendulum's excursion is from pi), else upright.
    """

    def __init__(
        self,
        family: Family,
        hypotheses: Hypotheses,
        rig: RigParameters,
        scales,
        bounds: Bounds,
        runner: Runner,
        unit_command: Callable[[np.ndarray], np.ndarray],
        aimed_motion: Callable[[np.ndarray], np.ndarray] | None,
        hanging: bool,
    ):
        self.family, self.hypotheses, self.rig, self.scales, self.bounds = family, hypotheses, rig, scales, bounds
        self.runner, self.unit_command, self.aimed_motion, self.hanging = runner, unit_command, aimed_motion, hanging

    def __call__(self, shapes: np.ndarray, directions: list[Direction]) -> list[EvaluatedDesign]:
        unit = self.unit_command(shapes)  # (D, N) at level 1
        limits = [self.bounds.command / np.maximum(np.abs(unit).max(axis=1), 1e-300)]
        if self.aimed_motion is not None:
            limits.append(SAFETY * self.bounds.arm / np.maximum(np.abs(self.aimed_motion(shapes)).max(axis=1), 1e-300))
        levels = np.min(limits, axis=0)
        used = sorted({d.truth for d in directions} | {d.rival for d in directions})
        for _ in range(RESCALES + 1):
            commands = levels[:, None] * unit
            runs = {h: self.runner(self.hypotheses.hypotheses[h].model, commands) for h in used}
            peaks = {h: self._peaks(*runs[h]) for h in used}
            with np.errstate(divide="ignore", invalid="ignore"):
                ratio = np.min(
                    [
                        np.minimum(
                            SAFETY * self.bounds.arm / peaks[h]["arm"],
                            SAFETY * self.bounds.pendulum / peaks[h]["pendulum"],
                        )
                        for h in used
                    ],
                    axis=0,
                )
            ratio = np.where(np.isnan(ratio), 0.0, ratio)
            command_ok = np.all([peaks[h]["command"] <= self.bounds.command * (1 + 1e-9) for h in used], axis=0)
            if np.all((ratio >= 1.0) & command_ok):
                break
            levels = levels * np.minimum(ratio, 1.0) * np.where(command_ok, 1.0, 0.9)
        feasible = (ratio >= 1.0) & command_ok & (levels > 0)
        candidates = [
            EvaluatedDesign(
                shapes[d],
                float(levels[d]),
                commands[d],
                {h: (runs[h][0][:, :, d], runs[h][1][d]) for h in used},
                {h: {key: float(value[d]) for key, value in peaks[h].items()} for h in used},
                bool(feasible[d]),
            )
            for d in range(shapes.shape[0])
        ]
        self._score([c for c in candidates if c.feasible], directions)
        return candidates

    def _peaks(self, angles: np.ndarray, logged: np.ndarray) -> dict[str, np.ndarray]:
        """(D,) peak |phi|, pendulum excursion from rest and |command| (NaN for a diverged run)."""
        rest = np.pi if self.hanging else 0.0
        return {
            "arm": np.max(np.abs(angles[:, 1]), axis=0),
            "pendulum": np.max(np.abs(angles[:, 0] - rest), axis=0),
            "command": np.max(np.abs(logged), axis=1),
        }

    def _score(self, candidates: list[EvaluatedDesign], directions: list[Direction]) -> None:
        if not candidates:
            return
        counts = self.rig.counts_per_rev
        for truth in sorted({d.truth for d in directions}):
            angles = np.stack([c.runs[truth][0] for c in candidates], axis=-1)
            logged = np.stack([c.runs[truth][1] for c in candidates])
            train, heldout = experiment_windows(angles, logged, self.family.period, self.rig)
            variance = sensor_variance(self.hypotheses.hypotheses[truth].model, counts)
            for direction in (d for d in directions if d.truth == truth):
                rival = self.hypotheses.hypotheses[direction.rival]
                values = linearised_noncentrality(
                    Parametrised(self.hypotheses.nominal, rival.effects, self.scales), train, heldout, counts, variance
                )
                for candidate, value in zip(candidates, values):
                    candidate.noncentrality[direction] = float(value)

    def refine(self, candidates: list[EvaluatedDesign], directions: list[Direction], iterations: int) -> None:
        """The noncentralities of ``candidates`` with ``iterations`` refit steps and exact held-out residuals."""
        counts = self.rig.counts_per_rev
        for candidate in candidates:
            for direction in directions:
                angles, logged = candidate.runs[direction.truth]
                train, heldout = experiment_windows(angles[:, :, None], logged[None], self.family.period, self.rig)
                rival = self.hypotheses.hypotheses[direction.rival]
                fit = refit_residuals(
                    Parametrised(self.hypotheses.nominal, rival.effects, self.scales),
                    train,
                    heldout,
                    counts,
                    iterations,
                )
                variance = sensor_variance(self.hypotheses.hypotheses[direction.truth].model, counts)
                candidate.refined[direction] = float(np.sum(fit.residuals[1:] ** 2) / variance)


def optimise(
    evaluator: Evaluator,
    hypotheses: Hypotheses,
    generations: int,
    population: int,
    iterations: int,
    seed: int,
    progress: Callable[[str], None] | None = None,
) -> Search:
    """The cross-entropy search of the module docstring; ``iterations``: refit steps of the elite's scores."""
    rng = np.random.default_rng(seed)
    directions = directions_of(hypotheses)
    first = np.vstack(
        [np.eye(BANDS), np.full((1, BANDS), 1.0 / BANDS), rng.dirichlet(np.ones(BANDS), max(population - BANDS - 1, 0))]
    )
    candidates = evaluator(first, directions)
    feasible = [c for c in candidates if c.feasible]
    inseparable = [
        d for d in directions if max((c.noncentrality.get(d, 0.0) for c in feasible), default=0.0) < SEPARABLE
    ]
    active = [d for d in directions if d not in inseparable]
    generation, elite = candidates, []
    for number in range(1, generations + 1):
        if number > 1:
            draws = [
                rng.dirichlet(CONCENTRATION * c.shape + 0.2)
                for c in elite
                for _ in range(int(np.ceil(population / len(elite))))
            ][:population]
            generation = evaluator(np.array(draws), directions)
            candidates += generation
        if not active:
            break
        ranked = sorted((c for c in generation if c.feasible), key=lambda c: -c.score(active))[:ELITE]
        evaluator.refine(ranked, active, iterations)
        elite = sorted((c for c in candidates if c.refined), key=lambda c: -c.score(active, refined=True))[:ELITE]
        if progress:
            progress(
                f"generation {number}: {sum(c.feasible for c in generation)}/{len(generation)} designs within "
                f"the bounds; best weakest noncentrality "
                f"{max((c.score(active, refined=True) for c in elite), default=0.0):.3g}"
            )
        if not elite:
            break
    best = elite[0] if elite and active else None
    return Search(best, candidates, active, inseparable)
