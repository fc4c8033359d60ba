"""``simulate``: build the diagram of a config, run it with Drake's Simulator, return a tape.

One entry point shared by the CLI, notebooks, benchmarks and tests (Drake's ``examples/acrobot`` idiom). A
monitor stops a run that leaves its envelope (NaN, a fallen pendulum, a runaway joint) and raises
:class:`~furuta_drake.errors.SimulationDiverged` saying when and why.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import EventStatus

from furuta_drake.config import SimulationConfig
from furuta_drake.diagram import FurutaDiagram, build_furuta_diagram
from furuta_drake.errors import SimulationDiverged
from furuta_drake.plant import joint_indices


@dataclass
class SimulationResult:
    """Signals sampled at the control period, rows aligned so that row k holds the encoder sample taken at
    ``time[k]``, the true state at that instant and the torque command applied from ``time[k]`` on.

    ``state`` is the true paper-order state [theta, phi, theta_dot, phi_dot]; ``measured`` the encoder angles;
    ``torque`` the commanded arm torque [N m]; ``true_friction`` the friction torques [F_theta, F_phi] the
    simulation applied; ``estimates`` each observer's state estimate; ``signals`` further logged signals
    (``friction_estimate``, ``friction_error_estimate``, ``K_sigma``, ``dahl_parameters``, ``swingup_mode``,
    ``pendulum_energy_J``) when their blocks ran.
    """

    time: np.ndarray
    state: np.ndarray
    measured: np.ndarray
    torque: np.ndarray
    true_friction: np.ndarray
    estimates: dict[str, np.ndarray] = field(default_factory=dict)
    signals: dict[str, np.ndarray] = field(default_factory=dict)
    lqr_gain: np.ndarray | None = None
    wall_time: float = 0.0


def simulate(
    config: SimulationConfig,
    *,
    meshcat=None,
    progress: Callable[[float], None] | None = None,
    built: FurutaDiagram | None = None,
) -> SimulationResult:
    """Simulate ``config`` for ``config.duration`` seconds; ``progress(t)`` is called about every 0.5 s.

    Raises SimulationDiverged when the monitor stops the run.
    """
    import time as _time

    built = built or build_furuta_diagram(config, meshcat=meshcat)
    diagram, plant = built.diagram, built.plant
    simulator = Simulator(diagram)
    ApplySimulatorConfig(
        SimulatorConfig(
            integration_scheme=config.simulator.integration_scheme,
            max_step_size=config.simulator.max_step_size,
            accuracy=config.simulator.accuracy,
            use_error_control=config.simulator.use_error_control,
        ),
        simulator,
    )
    context = simulator.get_mutable_context()
    diagram.SetRandomContext(context, RandomGenerator(config.seed))
    built.world.set_state(context, np.asarray(config.initial_state, dtype=float))

    monitor = _EnvelopeMonitor(plant, joint_indices(plant)[0], config)
    simulator.set_monitor(monitor)
    start = _time.perf_counter()
    simulator.Initialize()
    step = 0.5
    t = 0.0
    while t < config.duration - 1e-12:
        t = min(t + step, config.duration)
        simulator.AdvanceTo(t)
        if monitor.reason is not None:
            raise SimulationDiverged(
                f"simulation diverged at t = {monitor.time:.4f} s: {monitor.reason}", monitor.time, monitor.reason
            )
        if progress is not None:
            progress(t)
    wall = _time.perf_counter() - start
    return _tape(built, context, config, wall)


class _EnvelopeMonitor:
    """Simulator monitor: NaN or infinite state, |theta| above the bound, a joint faster than the bound.

    Called after every integrator step, so the common case is a few float comparisons on the plant's state
    (a NaN or inf makes the sum non-finite), read through a view of the context's state vector taken at the
    first call (the simulator writes the state in place); only a failed check looks for the reason."""

    def __init__(self, plant, theta_index: int, config: SimulationConfig):
        self.plant = plant
        self.theta_index = theta_index
        self.theta_bound = math.inf if config.monitor.theta_bound is None else config.monitor.theta_bound
        self.speed_bound = config.monitor.speed_bound
        self.nq = plant.num_positions()
        self.reason: str | None = None
        self.time = math.nan
        self._state = None  # a read-only view of the plant's continuous state, taken on the first call
        self._succeeded = EventStatus.Succeeded()

    def __call__(self, root_context):
        if self._state is None:
            self._state = self.plant.GetMyContextFromRoot(root_context).get_continuous_state_vector().value()
        x = self._state.tolist()
        velocities = x[self.nq :]
        if (
            math.isfinite(sum(x))
            and abs(x[self.theta_index]) <= self.theta_bound
            and -self.speed_bound <= min(velocities)
            and max(velocities) <= self.speed_bound
        ):
            return self._succeeded
        if not all(math.isfinite(value) for value in x):
            reason = "non-finite state (NaN or inf)"
        elif abs(x[self.theta_index]) > self.theta_bound:
            reason = (
                f"pendulum fell: |theta| = {abs(x[self.theta_index]):.3f} rad exceeds the bound {self.theta_bound} rad"
            )
        elif max(abs(v) for v in velocities) > self.speed_bound:
            reason = f"runaway joint speed {max(abs(v) for v in velocities):.1f} rad/s exceeds {self.speed_bound} rad/s"
        else:  # finite values whose sum overflowed
            return self._succeeded
        self.reason, self.time = reason, root_context.get_time()
        return EventStatus.ReachedTermination(None, reason)


def _tape(built: FurutaDiagram, context, config: SimulationConfig, wall: float) -> SimulationResult:
    """Read the loggers. Every logged signal is held at the control period, and a logger publishing at t_k
    sees the value sampled at t_{k-1} (Drake publishes after the step that ends at t_k and before that instant's
    discrete update); rows are re-timed by one period so that row k is the sample taken at t_k."""
    logs = {name: logger.FindLog(context) for name, logger in built.loggers.items()}
    period = config.control_period

    def data(name):
        return logs[name].data().T[1:]

    time = logs["state"].sample_times()[1:] - period
    estimates = {name[len("estimate_") :]: data(name) for name in logs if name.startswith("estimate_")}
    signals = {name[len("signal_") :]: data(name) for name in logs if name.startswith("signal_")}
    return SimulationResult(
        time=time,
        state=data("state"),
        measured=data("measured_angles"),
        torque=data("torque")[:, 0],
        true_friction=data("true_friction"),
        estimates=estimates,
        signals=signals,
        lqr_gain=built.lqr_gain,
        wall_time=wall,
    )
