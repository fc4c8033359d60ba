"""Predicted balancing: a controller run in Drake on a model (:func:`~furuta_drake.simulate.simulate` of
:func:`~furuta_drake.tune.controller.closed_loop`), read with the rig's encoders as a lab reads its rig, and its
figures (:func:`~furuta_drake.tune.limit_cycle.balancing_figures`). A run the envelope monitor stops (the pendulum
fell, a joint ran away) has no figures, and says when and why."""

from __future__ import annotations

from dataclasses import dataclass

from furuta_drake.config import SimulationConfig
from furuta_drake.errors import SimulationDiverged
from furuta_drake.simulate import SimulationResult, simulate
from furuta_drake.tune.controller import Controller, closed_loop
from furuta_drake.tune.limit_cycle import balancing_figures


@dataclass
class Prediction:
    """A predicted balancing run: ``figures`` (the contract's ``predicted``; None when it fell), ``fell`` (the
    monitor's reason, '' when it balanced) and its tape (None when it fell)."""

    figures: dict | None
    fell: str
    result: SimulationResult | None

    @property
    def balanced(self) -> bool:
        return self.figures is not None


def predict(world: SimulationConfig, controller: Controller, *, duration: float, seed: int) -> Prediction:
    """``controller`` balancing ``world`` for ``duration`` [s] from the seeded disturbance (module docstring)."""
    config = closed_loop(world, controller, duration=duration, seed=seed)
    try:
        result = simulate(config)
    except SimulationDiverged as err:
        return Prediction(None, str(err), None)
    figures = balancing_figures(result.measured[:, 0], result.measured[:, 1], result.torque, config.control_period)
    return Prediction(figures, "", result)
