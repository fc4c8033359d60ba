"""The designs under the rig's disturbance: the ongoing arm torque the diagnosis read from its held-out logs
(:class:`~furuta_drake.torque_disturbance.TorqueDisturbance`, the fitted rig file's ``disturbance:``).

Every predicted run of ``tune`` carries it at its level (the corrected model's config holds it), so the family's
choice, the finalists' worst case and the ``MIN_GAIN`` rule read figures under it. Beside that, each design is
predicted at the fit at 0.5 and 2 times the level (``SCALES``), and when the nominal design is kept while a finalist
balanced everywhere, both are predicted on the quiet rig: if the finalist would have replaced the nominal design
there, the report says the nominal design wins because of the disturbance.
"""

from __future__ import annotations

from furuta_drake.config import SimulationConfig
from furuta_drake.tune.family import DesignOutcome, Problem, clears_nominal, disturbed, member_label, ratios

SCALES = (0.5, 1.0, 2.0)  # the levels each design is predicted at, over the disturbance read


def at_scale(world: SimulationConfig, scale: float) -> SimulationConfig:
    """``world`` with its ongoing disturbance at ``scale`` times its level (0: none)."""
    disturbance = world.disturbance.arm_torque
    return world.with_arm_torque(None if disturbance is None or scale == 0 else disturbance.scaled(scale))


def under_disturbance(problem: Problem, outcomes: dict[str, DesignOutcome]) -> dict[str, dict[str, dict | None]]:
    """Each design's predicted figures at the fit at every scale of ``SCALES`` ({} without a disturbance): design
    -> "0.5" | "1" | "2" -> the figures (None when it fell); the level itself is its run at the fit."""
    if not disturbed(problem.world):
        return {}
    others = [scale for scale in SCALES if scale != 1.0]
    tasks = [(at_scale(problem.world, scale), outcome.controller) for outcome in outcomes.values() for scale in others]
    runs = iter(problem.predictions(tasks))
    out = {}
    for name, outcome in outcomes.items():
        figures = {scale: next(runs).figures for scale in others}
        figures[1.0] = outcome.prediction.figures
        out[name] = {f"{scale:g}": figures[scale] for scale in SCALES}
    return out


def quiet_winner_note(problem: Problem, nominal: DesignOutcome, tuned: DesignOutcome, finalists) -> str:
    """When the nominal design is kept under the disturbance: the sentence saying the best finalist would have
    replaced it on the quiet rig ('' when it would not, or nothing was kept because of it)."""
    if tuned is not nominal or not finalists or not disturbed(problem.world):
        return ""
    best = finalists[0]
    quiet = at_scale(problem.world, 0.0)
    ours, theirs = problem.predictions([(quiet, nominal.controller), (quiet, best.controller)])
    if not (ours.balanced and theirs.balanced):
        return ""
    judged = ratios(theirs.figures, ours.figures, problem.count)
    if not clears_nominal(judged):
        return ""
    return (
        f"The nominal design stays because of the rig's disturbance: on the quiet rig the best finalist "
        f"({member_label(best.member)}) would be predicted better (theta RMS x {judged[0]:.2f}, limit cycle x "
        f"{judged[1]:.2f}), under the disturbance the diagnosis read it is not."
    )
