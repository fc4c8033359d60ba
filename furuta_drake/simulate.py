"""``simulate``: build the diagram of a config, run it with Drake's Simulator, return a tape.

One entry point shared by the CLI, notebooks, benchmarks and tests (Drake's ``examples/acrobot`` idiom). A
run that leaves its envelope (NaN, a fallen pendulum, a runaway joint) is stopped within ``CHECK_INTERVAL`` of
simulated time and raises :class:`~furuta_drake.errors.SimulationDiverged` saying at which control sample and
why.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from pydrake.common import RandomGenerator
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig

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

    Raises SimulationDiverged when the run leaves its envelope (``config.monitor``).
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

    plant_context = plant.GetMyMutableContextFromRoot(context)
    envelope = _Envelope(config)
    state_log = built.loggers["state"].FindLog(context)
    start = _time.perf_counter()
    simulator.Initialize()
    # Chunks end on sample instants (k periods, as Drake times the samples): the integrator stops there anyway.
    period = config.control_period
    per_check = max(1, round(CHECK_INTERVAL / period))
    t, samples, checked, reported = 0.0, 0, 0, 0.0
    while t < config.duration - 1e-12:
        samples += per_check
        t = min(samples * period, config.duration)
        try:
            simulator.AdvanceTo(t)
        except SimulationDiverged:
            raise
        except RuntimeError:
            # A blown-up state can stop the integrator before the check sees it: name it if so.
            envelope.check(state_log, checked, plant, plant_context)
            raise
        checked = envelope.check(state_log, checked, plant, plant_context)
        if progress is not None and (t >= reported + PROGRESS_INTERVAL - 1e-12 or t >= config.duration - 1e-12):
            reported = t
            progress(t)
    wall = _time.perf_counter() - start
    return _tape(built, context, config, wall)


CHECK_INTERVAL = 0.05  # [s] simulated between two checks of the envelope: at most this much runs past a fall
PROGRESS_INTERVAL = 0.5  # [s] simulated between two calls of ``progress``


class _Envelope:
    """The run's envelope: a finite state, |theta| within the bound, every joint slower than the bound. Checked at
    every control sample of the true state (the ``state`` logger's samples) and on the plant's state, after each
    ``CHECK_INTERVAL`` of simulated time: vectorised over the samples, where a Simulator monitor would cross from
    C++ into Python after every integrator step."""

    def __init__(self, config: SimulationConfig):
        self.theta_bound = math.inf if config.monitor.theta_bound is None else config.monitor.theta_bound
        self.speed_bound = config.monitor.speed_bound
        self.period = config.control_period

    def check(self, log, checked: int, plant, plant_context) -> int:
        """Raise :class:`SimulationDiverged` at the first sample of ``log`` from index ``checked`` on, then at the
        plant's current state, that is outside the envelope; else return the number of samples checked."""
        states = log.data()[:, checked:]  # paper order [theta, phi, theta_dot, phi_dot]; a view, no copy
        finite = np.isfinite(states).all(axis=0)
        outside = ~finite | (np.abs(states[0]) > self.theta_bound)
        outside |= np.abs(states[2:]).max(axis=0, initial=0.0) > self.speed_bound
        if outside.any():
            k = int(np.argmax(outside))
            # A logger publishing at t_k holds the sample taken at t_(k-1) (see _tape).
            self._stop(log.sample_times()[checked + k] - self.period, states[0, k], states[2:, k], finite[k])
        x = plant.GetPositionsAndVelocities(plant_context)
        theta, velocities = x[joint_indices(plant)[0]], x[plant.num_positions() :]
        self._stop(plant_context.get_time(), theta, velocities, bool(np.isfinite(x).all()))
        return checked + states.shape[1]

    def _stop(self, time: float, theta: float, velocities: np.ndarray, finite: bool) -> None:
        """Raise :class:`SimulationDiverged` at ``time`` [s] if the state of pendulum angle ``theta`` [rad] and
        joint ``velocities`` [rad/s] (``finite``: the whole state is) is outside the envelope."""
        speed = float(np.max(np.abs(velocities)))
        if not finite:
            reason = "non-finite state (NaN or inf)"
        elif abs(theta) > self.theta_bound:
            reason = f"pendulum fell: |theta| = {abs(theta):.3f} rad exceeds the bound {self.theta_bound} rad"
        elif speed > self.speed_bound:
            reason = f"runaway joint speed {speed:.1f} rad/s exceeds {self.speed_bound} rad/s"
        else:
            return
        raise SimulationDiverged(f"simulation diverged at t = {time:.4f} s: {reason}", time, reason)


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
