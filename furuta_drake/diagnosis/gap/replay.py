"""Held-out figures from Drake: the windows replayed through a diagram of the project's own systems.

The diagram is the model's Furuta world (:func:`~furuta_drake.world.add_furuta_world`: the MultibodyPlant of
the model's rig, its friction, spring, back-EMF and unmodelled torques, and its actuator chain) driven by the logged
command. A held command (shifted by a pure input delay: an open-loop replay's delay is exactly a time shift) is the
diagram's input, fixed over each interval between the integrator's stops, so that every stage of a step, the one at
the step's end included, reads the value the drive holds there, as the simulate diagram's discrete hold gives it; a
jittering delay's expected command is continuous (piecewise linear) and comes from a ``TrajectorySource``. Each
window starts from the initial state the surrogate refined for this model, with a fresh integrator (Drake's
error-controlled third-order Runge-Kutta at accuracy 1e-5: a gap near the sensor floor is a square root, so the
integration error must stay far below a count, as it does here against a 1e-9 reference), which stops at every
sample and at every jump of the applied command so that no step straddles one; the residuals give the same gap as
:func:`furuta_drake.diagnosis.gap.metric.evaluate_gap` (a test checks the two agree).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import partial

import numpy as np
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from furuta_drake.diagnosis.gap.metric import GapResult, Windows, gap_from_residuals, substeps_for
from furuta_drake.effects.corrected import model_actuator, model_disturbance, model_rig
from furuta_drake.effects.surrogate import Model, expected_command_points, lag_states, split_states
from furuta_drake.effects.torque_library import torque_parameters_of
from furuta_drake.friction import FrictionParameters, JointFrictionParameters
from furuta_drake.parallel import Failure, run_tasks
from furuta_drake.rig import RigParameters, encoder_resolution
from furuta_drake.unmodelled import UnmodelledTorqueParameters
from furuta_drake.world import add_furuta_world

REPLAY_INTEGRATOR = SimulatorConfig(integration_scheme="runge_kutta3", accuracy=1e-5, max_step_size=1e-3)


def drake_friction(p: JointFrictionParameters) -> JointFrictionParameters:
    """``p``, or no friction where ``p`` is a static law of zero levels and zero viscosity (a diagnosis model of a
    frictionless rig file holds one): its torque is exactly zero, so the world's constant zero in place of a
    friction system evaluated at every integrator stage replays the windows to the last bit."""
    zero = p.model == "static" and p.viscous == 0.0 and max(p.coulomb_pos, p.coulomb_neg, *p.static_levels) == 0.0
    return JointFrictionParameters() if zero else p


class WindowReplayer:
    """One Drake diagram for a model and a log; :meth:`replay` integrates one window from a state.
    ``unmodelled_torque``: the expressions of the model's torque beyond the vocabulary, if it has one."""

    def __init__(
        self,
        model: Model,
        rig: RigParameters,
        time: np.ndarray,
        command: np.ndarray,
        unmodelled_torque: UnmodelledTorqueParameters | None = None,
    ):
        builder = DiagramBuilder()
        period = float(np.median(np.diff(time)))
        # The simulate world of the model: its rigid body, friction, spring and back-EMF, and its actuator but for
        # the delay, which is the time shift of the replayed command below.
        world = add_furuta_world(
            builder,
            rig=model_rig(model, rig),
            control_period=period,
            friction=FrictionParameters(
                arm=drake_friction(model.arm_friction), pendulum=drake_friction(model.pendulum_friction)
            ),
            actuator=model_actuator(model),
            back_emf_damping=model.back_emf_damping,
            disturbance=model_disturbance(model),
            unmodelled_torque=unmodelled_torque,
        )
        self.world, self.plant, self.P, self.friction = world, world.plant, world.to_paper, world.friction
        applied = _applied_command(model, time, command, period)
        # The integrator stops at every sample and at every jump (or kink) of the applied command between samples,
        # so that no error-controlled step straddles one (a break a fraction of a microsecond after a sample would
        # otherwise go unresolved).
        self.stops = np.union1d(time, _between_samples(np.asarray(applied.get_segment_times()), time, period))
        if model.delay_spread > 0:  # the expected command is continuous: a source of it evaluated at every stage
            source = builder.AddSystem(TrajectorySource(applied))
            builder.Connect(source.get_output_port(), world.arm_torque_input)
            self.held = None
        else:  # a held command, as the rig's drive holds it: each interval's value fixed while the interval runs,
            # its last stage included (a source read there would give the next sample's value)
            builder.ExportInput(world.arm_torque_input, "arm_torque_Nm")
            self.held = applied.vector_values(0.5 * (self.stops[:-1] + self.stops[1:]))[0]
        self.diagram = builder.Build()
        self.simulator = Simulator(self.diagram)
        self.integrator = REPLAY_INTEGRATOR  # the integrator every window starts afresh with
        ApplySimulatorConfig(self.integrator, self.simulator)
        self.context = self.simulator.get_mutable_context()
        self.command = None if self.held is None else self.diagram.get_input_port().FixValue(self.context, [0.0])
        self.plant_context = self.plant.GetMyMutableContextFromRoot(self.context)
        self.encoders = world.encoder_state  # [theta, phi or the rotor's psi, rates]
        self.encoders_context = self.encoders.get_system().GetMyContextFromRoot(self.context)
        self.default_context = self.context.Clone()
        self.lag = self.diagram.GetSubsystemByName("actuator_lag") if model.lag > 0 else None

    def replay(
        self,
        start_time: float,
        x0: np.ndarray,
        lag_at_start: float,
        times: np.ndarray,
        bristle: float | None = None,
        twist=(0.0, 0.0),
    ) -> np.ndarray:
        """Paper-order angles at ``times`` from state ``x0`` at ``start_time`` (the lag filter at
        ``lag_at_start``, :func:`~furuta_drake.effects.surrogate.lag_states`; the arm's Dahl bristle at
        ``bristle``; a drive's rotor at the ``twist`` [delta, delta_dot] from the arm, the surrogate's refined one).
        The angles are those the encoders read (the rotor's for an encoder on the motor). Every window starts with a
        fresh integrator, so its result does not depend on the step size the previous window ended with."""
        ApplySimulatorConfig(self.integrator, self.simulator)
        self.context.SetTimeStateAndParametersFrom(self.default_context)
        self.context.SetTime(start_time)
        if self.lag is not None:
            self.lag.GetMyMutableContextFromRoot(self.context).get_mutable_continuous_state_vector().SetFromVector(
                [lag_at_start]
            )
        if bristle is not None:  # the arm's is the friction system's only bristle (the pendulum's is static)
            self.friction.GetMyMutableContextFromRoot(self.context).get_mutable_continuous_state_vector().SetFromVector(
                [bristle]
            )
        self.world.set_state(self.context, x0, twist)
        stops = np.union1d(times, self.stops[(self.stops > times[0]) & (self.stops < times[-1])])
        self._hold(stops[0])
        self.simulator.Initialize()
        out = np.empty((times.size, 2))
        out[0] = self.encoders.Eval(self.encoders_context)[:2]
        sample = 1
        for stop in stops[1:]:
            self.simulator.AdvanceTo(stop)
            if stop == times[sample]:
                out[sample] = self.encoders.Eval(self.encoders_context)[:2]
                sample += 1
            self._hold(stop)
        return out

    def _hold(self, t: float) -> None:
        """Fix a held command's value over the interval of stops that starts at ``t`` [s]."""
        if self.command is not None:
            i = min(max(int(np.searchsorted(self.stops, t, side="right")) - 1, 0), self.held.size - 1)
            self.command.GetMutableData().get_mutable_value().SetAtIndex(0, self.held[i])


def _between_samples(breaks: np.ndarray, time: np.ndarray, period: float) -> np.ndarray:
    """The ``breaks`` [s] that fall between the samples ``time`` (further than a millionth of a ``period`` from
    every sample: a break on a sample is a stop already)."""
    i = np.clip(np.searchsorted(time, breaks), 1, time.size - 1)
    distance = np.minimum(np.abs(breaks - time[i - 1]), np.abs(breaks - time[i]))
    return breaks[distance > 1e-6 * period]


def _applied_command(model: Model, time: np.ndarray, command: np.ndarray, period: float) -> PiecewisePolynomial:
    """The command the model's actuator receives: the logged one held over each sample and shifted by the delay,
    or with a jittering delay its expectation, exactly piecewise linear
    (:func:`~furuta_drake.effects.surrogate.expected_command_points`)."""
    if model.delay_spread > 0:
        times, values = expected_command_points(command, period, model)
        return PiecewisePolynomial.FirstOrderHold(time[0] + times, values.reshape(1, -1))
    breaks = np.append(time, time[-1] + period) + model.delay
    return PiecewisePolynomial.ZeroOrderHold(breaks, np.append(command, command[-1]).reshape(1, -1))


def _replay_log(task) -> np.ndarray:
    """(horizon, 2, W) residuals [counts] of one log's windows replayed in Drake (one diagram per task)."""
    model, rig, log, horizon, starts, x0, measured = task
    count = encoder_resolution(rig.counts_per_rev)
    torque = torque_parameters_of(model.unmodelled_terms) if model.unmodelled_terms else None
    replayer = WindowReplayer(model, rig, log.time, log.torque_command, unmodelled_torque=torque)
    period = log.sample_period
    lags = (
        lag_states(model, log.torque_command, starts, period, substeps_for(period))
        if model.lag > 0
        else np.zeros(starts.size)
    )
    r = np.empty_like(measured)
    for w, start in enumerate(starts):
        times = log.time[start : start + horizon]
        _, bristle, twist = split_states(model, x0[:, w])
        predicted = replayer.replay(
            log.time[start],
            x0[:4, w],
            float(lags[w]),
            times,
            None if bristle is None else float(bristle),
            (0.0, 0.0) if twist is None else twist,
        )
        r[:, :, w] = (measured[:, :, w] - predicted) / count
    return r


def replay_gaps(
    models: list[tuple[Model, list[np.ndarray]]],
    rig: RigParameters,
    windows: Windows,
    run: Callable = run_tasks,
) -> list[GapResult | None]:
    """The gap of each (model, initial states per log: 4 x W, and the rows of its hidden states,
    :attr:`~furuta_drake.effects.surrogate.Model.hidden_states`) on
    ``windows`` from Drake replays, one task per model and log, run by ``run`` (:func:`run_tasks` with its
    options); None for a model whose replay failed (raised, or diverged to a non-finite residual)."""
    tasks = [
        (model, rig, log, horizon, starts, x0[i], measured)
        for model, x0 in models
        for i, (log, horizon, starts, measured) in enumerate(
            zip(windows.logs, windows.horizons, windows.starts, windows.measured)
        )
    ]
    residuals = run(_replay_log, tasks)
    n = len(windows.logs)
    out = []
    for k, (_, x0) in enumerate(models):
        parts = residuals[k * n : (k + 1) * n]
        failed = any(isinstance(r, Failure) or not np.all(np.isfinite(r)) for r in parts)
        if failed:
            out.append(None)
            continue
        out.append(gap_from_residuals(parts, windows.floor, x0))
    return out


def replay_gap(
    model: Model, rig: RigParameters, windows: Windows, initial_states: list[np.ndarray], workers: int | None = 1
) -> GapResult | None:
    """:func:`replay_gaps` of one model."""
    return replay_gaps([(model, initial_states)], rig, windows, partial(run_tasks, workers=workers))[0]
