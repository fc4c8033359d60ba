"""A candidate experiment played on a hypothesis: fast batches on the diagnosis' surrogate, the check in Drake.

:func:`surrogate_runs` integrates many commands at once from rest with the surrogate the diagnosis fits with
(:func:`~furuta_drake.effects.surrogate.predict_windows`, one window as long as the experiment);
:func:`drake_config` plays one command on the Drake diagram of a hypothesis
(:func:`~furuta_drake.effects.corrected.model_config`: MultibodyPlant, the friction system and the actuator
chain), open loop from rest hanging or, for ``balancing``, added to the project's LQR of the rig file's nominal
model balancing the upright.
"""

from __future__ import annotations

import dataclasses

import numpy as np

from furuta_drake.config import ExcitationConfig, MonitorConfig, SimulationConfig
from furuta_drake.diagnosis.gap.metric import COMMAND_PAD, substeps_for
from furuta_drake.effects.surrogate import Model, predict_windows
from furuta_drake.rig import RigParameters, encoder_resolution

HANGING = (np.pi, 0.0, 0.0, 0.0)  # [theta, phi, theta_dot, phi_dot]: at rest, the pendulum down
UPRIGHT = (0.0, 0.0, 0.0, 0.0)


def surrogate_runs(model: Model, commands: np.ndarray, period: float) -> np.ndarray:
    """(N, 2, D) angles [theta, phi] [rad] of ``model`` under each of the D commands (D, N) [N m] (held over
    each sample), open loop from rest hanging; row k is the angle at sample k."""
    commands = np.atleast_2d(commands)
    designs, samples = commands.shape
    padded = np.concatenate([np.zeros((designs, COMMAND_PAD)), commands, np.zeros((designs, 1))], axis=1)
    starts = COMMAND_PAD + np.arange(designs) * padded.shape[1]
    x0 = np.tile(np.asarray(HANGING, dtype=float)[:, None], (1, designs))
    return predict_windows(model, x0, padded.ravel(), starts, samples, period, substeps_for(period))


def drake_config(
    rig: RigParameters,
    model: Model,
    command: np.ndarray,
    duration: float,
    balancing: bool,
    seed: int,
    lqr_gain: np.ndarray | None = None,
) -> SimulationConfig:
    """The simulate config that plays ``command`` [N m] on ``model`` (a hypothesis of ``rig``): open loop from
    rest hanging, or with ``balancing`` added to the LQR of gain ``lqr_gain`` (the rig file's) from rest
    upright."""
    from furuta_drake.effects.corrected import model_config

    config = model_config(rig, model)
    controller = dataclasses.replace(
        config.controller,
        mode="lqr" if balancing else "open_loop",
        gain=None if lqr_gain is None else [float(v) for v in np.ravel(lqr_gain)],
    )
    return dataclasses.replace(
        config,
        controller=controller,
        excitation=ExcitationConfig(command=[float(v) for v in command]),
        initial_state=list(UPRIGHT if balancing else HANGING),
        duration=duration,
        seed=seed,
        monitor=MonitorConfig(theta_bound=None),
    )


def nominal_lqr_gain(rig: RigParameters) -> np.ndarray:
    """The gain (1, 4) of the project's LQR designed on the rig file's nominal model, as the lab would run it."""
    from furuta_drake.diagram import build_furuta_diagram

    return build_furuta_diagram(SimulationConfig.from_rig(rig.replace(effects=None))).lqr_gain


def surrogate_closed_loop(
    model: Model, gain: np.ndarray, dithers: np.ndarray, period: float, limit: float, counts: int
) -> tuple[np.ndarray, np.ndarray]:
    """(angles (N, 2, D) [rad], logged commands (D, N) [N m]) of ``model`` balanced from rest upright by the LQR
    u_k = sat(-K [theta_k, phi_k, theta_dot_k, phi_dot_k] + dither_k) (encoder angles of ``counts`` per
    revolution, true velocities, as the project's LQR reads them; ``limit`` [N m]), one dither per row of
    ``dithers`` (D, N).

    The command depends on the state, so the surrogate's right-hand side and actuator chain (delay, lag, static
    map, Dahl or LuGre bristle) are stepped one sample at a time, with the same RK4 substeps as
    :func:`~furuta_drake.effects.surrogate.predict_windows`.
    """
    from furuta_drake.effects.surrogate import applied_torque, expected_command
    from furuta_drake.effects.surrogate_kernel import integrate, lag_filter, pack_rows

    dithers = np.atleast_2d(dithers)
    designs, samples = dithers.shape
    substeps = substeps_for(period)
    dt = period / substeps
    width = COMMAND_PAD + samples + 1
    history = np.zeros(designs * width)
    starts = COMMAND_PAD + np.arange(designs) * width
    x = np.tile(np.asarray(UPRIGHT, dtype=float)[:, None], (1, designs))
    lag_state, z = np.zeros(designs), np.zeros(designs)
    packed = pack_rows([model])  # the kernel's parameters, once for every substep
    resolution = encoder_resolution(counts)
    K = np.ravel(gain)

    angles, logged = np.empty((samples, 2, designs)), np.empty((designs, samples))
    for k in range(samples):
        angles[k] = x[:2]
        measured = np.vstack([np.round(x[:2] / resolution) * resolution, x[2:]])
        u = np.clip(-(K @ measured) + dithers[:, k], -limit, limit)
        history[starts + k] = u
        logged[:, k] = u
        for i in range(substeps):
            held = expected_command(history, starts, k * period + i * dt, dt, period, model)
            if model.lag > 0:
                filtered, lag_state = lag_filter(held[None, :], lag_state, model.lag, dt)
                held = filtered[0]
            _, x, z = integrate(x, z, np.ascontiguousarray(applied_torque(model, held))[None, :], dt, 1, *packed)
    return angles, logged
