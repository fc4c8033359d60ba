"""The swing-up's catch time of each design: the nominal and the tuned balance law behind the same swing-up.

A lab states its swing-up as a simulate config (``tune --swingup FILE``; :class:`SwingUpCheck` reads its swing-up
section, velocity source or filter, initial state and duration, not its rig and world sections: the swing-up runs
on the corrected model), one of

- ``controller.mode: swingup``, the package's energy swing-up (:mod:`furuta_drake.controllers.swingup`: energy
  pumping from hanging, then the LQR inside the catch window; :func:`furuta_drake.config.swingup_config` makes
  one): each design's gain K is the LQR, in the catch test and after the catch (its torque limit; the velocities
  from the swing-up's own source, as the swing-up needs them away from the upright; no friction compensation);
- ``controller.mode: quanser_swingup``, Quanser's swing-up of the QUBE (:mod:`furuta_drake.controllers.quanser_swingup`,
  a motor rig): its balance law V = k . [theta_w, phi, theta_dot, phi_dot] inside its window becomes each design's
  LQR in volts, k = -K_V (:func:`~.controller.volts_gain`), on the same filtered-derivative velocities, the same
  window and the same voltage clip.

Each design runs from the configured start. The **catch time** is the time of the last hand-over to the balance law
(:func:`~furuta_drake.controllers.swingup.catch_time`), None when the pendulum is not balancing at the end of the
run, with the envelope monitor's reason when the run was stopped.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass
from pathlib import Path

from furuta_drake.config import SimulationConfig, load_config, quanser_swingup_config, swingup_config
from furuta_drake.controllers.quanser_swingup import QuanserSwingUpParameters
from furuta_drake.controllers.swingup import SwingUpParameters, catch_time
from furuta_drake.errors import ConfigError, SimulationDiverged
from furuta_drake.observers.filtered_derivative import FilteredDerivativeParameters
from furuta_drake.parallel import Failure, run_tasks
from furuta_drake.simulate import simulate
from furuta_drake.tune.controller import Controller, volts_gain

MODES = ("swingup", "quanser_swingup")


@dataclass(frozen=True)
class SwingUpCheck:
    """The configured swing-up: its parameters (the energy swing-up's, or Quanser's), the velocity source the
    energy swing-up runs on or the filter of Quanser's, the pendulum's and the arm's start ``theta0``, ``phi0``
    [rad] (at rest) and the run's ``duration`` [s]."""

    params: SwingUpParameters | QuanserSwingUpParameters
    velocity_source: str = "kinematic_hg"
    theta0: float = math.pi
    duration: float = 10.0
    phi0: float = 0.0
    velocity_filter: FilteredDerivativeParameters | None = None

    @property
    def mode(self) -> str:
        return "quanser_swingup" if isinstance(self.params, QuanserSwingUpParameters) else "swingup"

    def as_dict(self) -> dict:
        return {
            "mode": self.mode,
            "parameters": dataclasses.asdict(self.params),
            "velocity_source": "filtered_derivative" if self.mode == "quanser_swingup" else self.velocity_source,
            "theta0": self.theta0,
            "phi0": self.phi0,
            "duration_s": self.duration,
        }


def read_swingup(path: str | Path) -> SwingUpCheck:
    """The swing-up of a simulate config file (module docstring); ConfigError naming the file and the key when it
    configures none."""
    config = load_config(path)
    control = config.controller
    if control.mode not in MODES:
        raise ConfigError(
            f"{path}: controller.mode must be 'swingup' (the package's energy swing-up) or 'quanser_swingup' "
            f"(Quanser's), whose balance law each design's gain replaces; got {control.mode!r}"
        )
    state = [float(v) for v in config.initial_state]
    if any(v != 0.0 for v in state[2:]):
        raise ConfigError(f"{path}: initial_state must start at rest, got {state}")
    if control.mode == "quanser_swingup":
        return SwingUpCheck(
            control.quanser_swingup,
            theta0=state[0],
            duration=float(config.duration),
            phi0=state[1],
            velocity_filter=config.observers.filtered_derivative,
        )
    return SwingUpCheck(control.swingup, control.velocity_source, state[0], float(config.duration), state[1])


def swingup_run(world: SimulationConfig, controller: Controller, check: SwingUpCheck, seed: int) -> SimulationConfig:
    """``controller``'s gain behind the configured swing-up on the model ``world`` (module docstring)."""
    control = dataclasses.replace(
        world.controller,
        gain=[float(k) for k in controller.gain],
        lqr=dataclasses.replace(controller.lqr, torque_limit=controller.torque_limit),
        friction_compensation=False,
    )
    config = dataclasses.replace(
        world, controller=control, encoder=dataclasses.replace(world.encoder, seed=seed), seed=seed
    )
    if check.mode == "quanser_swingup":
        volts = volts_gain(controller.gain, world)
        if volts is None:
            raise ConfigError("--swingup: Quanser's swing-up commands a voltage; the rig file has no motor section")
        return quanser_swingup_config(
            config,
            initial_state=[check.theta0, check.phi0, 0.0, 0.0],
            duration=check.duration,
            params=dataclasses.replace(check.params, balance_gains=[-k for k in volts]),
            velocity_filter=check.velocity_filter,
        )
    started = swingup_config(
        config,
        duration=check.duration,
        theta0=check.theta0,
        velocity_source=check.velocity_source,
        params=check.params,
    )
    return dataclasses.replace(started, initial_state=[check.theta0, check.phi0, 0.0, 0.0])


def predict_catch(world: SimulationConfig, controller: Controller, check: SwingUpCheck, seed: int) -> dict:
    """The swing-up run of ``controller`` on ``world``: ``catch_time_s`` (None when it does not balance at the
    end) and ``fell`` (the monitor's reason when it stopped the run, else '')."""
    try:
        result = simulate(swingup_run(world, controller, check, seed))
    except SimulationDiverged as err:
        return {"catch_time_s": None, "fell": str(err)}
    caught = catch_time(result)
    return {"catch_time_s": caught if math.isfinite(caught) else None, "fell": ""}


def _catch(task) -> dict:
    return predict_catch(*task)


def catch_times(
    worlds: list[tuple[str, SimulationConfig]],
    designs: dict[str, Controller],
    check: SwingUpCheck,
    *,
    seed: int,
    workers: int | None,
) -> dict:
    """Each design's swing-up on each of the labelled ``worlds`` (the fit first, then the effect extremes), on
    worker processes: design -> {``at_fit``, ``extremes`` (label -> run), ``catch_time_over_intervals`` ([min, max]
    of the catch times, None when one of the runs does not catch)}."""
    calls = [(world, controller, check, seed) for controller in designs.values() for _, world in worlds]
    results = run_tasks(_catch, calls, workers=workers)
    results = [{"catch_time_s": None, "fell": r.reason} if isinstance(r, Failure) else r for r in results]
    out = {}
    for index, name in enumerate(designs):
        runs = dict(zip([label for label, _ in worlds], results[index * len(worlds) : (index + 1) * len(worlds)]))
        times = [run["catch_time_s"] for run in runs.values()]
        fit_label = worlds[0][0]
        out[name] = {
            "at_fit": runs.pop(fit_label),
            "extremes": runs,
            "catch_time_over_intervals": None if None in times else [min(times), max(times)],
        }
    return out


__all__ = ["SwingUpCheck", "read_swingup", "swingup_run", "predict_catch", "catch_times"]
