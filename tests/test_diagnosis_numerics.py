"""The diagnosis' hand-written numerics pinned to independent ones: the batched Levenberg-Marquardt refinement of
the windows' initial states against scipy's least_squares, the batched RK4 by step halving, and the surrogate's
dynamics with friction and the DC motor against Drake's MultibodyPlant world."""

import numpy as np
import pytest
from conftest import hanging_log
from pydrake.systems.analysis import SimulatorConfig
from pydrake.systems.framework import DiagramBuilder
from scipy.optimize import least_squares

from benchmarks.diagnosis.suite import run_configs, with_effect
from furuta_drake.diagnosis.gap.metric import make_windows, projected_residuals, substeps_for
from furuta_drake.diagnosis.gap.replay import REPLAY_INTEGRATOR, WindowReplayer
from furuta_drake.diagnosis.selection.fit import _best_start
from furuta_drake.effects.surrogate import REGULARIZATION_VELOCITY, Model, _accelerations, predict_windows
from furuta_drake.effects.surrogate_kernel import bristle_step, pack_friction
from furuta_drake.effects.vocabulary import Effect, apply_effects
from furuta_drake.friction import FrictionParameters, JointFrictionParameters, bristle_friction_torque
from furuta_drake.rig import RIGS
from furuta_drake.world import add_furuta_world

LUND, QUBE = RIGS["lund"](), RIGS["qube_servo2"]()


@pytest.fixture(scope="module")
def all_hanging_windows():
    """Every 217 ms window of a 2 s Lund hanging run with viscous arm friction (the frictionless nominal model does
    not explain it, so each window's residual is well away from zero), and the simulated viscous coefficient."""
    config = with_effect(run_configs(LUND, 3, 2.0)["hanging"], "arm_viscous_friction", 2)
    log = hanging_log(3, "arm_viscous_friction", level=2, duration=2.0)
    return make_windows([log], LUND), config.friction.arm.viscous


@pytest.fixture(scope="module")
def hanging_windows(all_hanging_windows):
    """Four of those windows."""
    return all_hanging_windows[0].subset(4, seed=1)


def test_levenberg_marquardt_reaches_the_least_squares_minimum_of_every_window(hanging_windows):
    """The batched steps (all windows at once) and scipy's least_squares ('lm', one window at a time, run to
    1e-12) find the same minimum of each window's cost, the sum of squared residuals in counts, over its
    initial state: equal to 1e-8 relative, at the same state to 1e-5 rad and rad/s."""
    model = Model.from_rig(LUND)
    residuals, states, _ = projected_residuals(model, hanging_windows, LUND.counts_per_rev)
    batch = hanging_windows.batches()[0]
    count = 2 * np.pi / LUND.counts_per_rev
    for w in range(batch.starts.size):

        def window_residuals(x, w=w):
            predicted = predict_windows(
                model,
                x[:, None],
                batch.command,
                batch.starts[[w]],
                batch.horizon,
                batch.period,
                substeps_for(batch.period),
            )
            return ((batch.measured[:, :, [w]] - predicted) / count).ravel()

        start = batch.initial_states[:, w]
        scipy = least_squares(
            window_residuals, start, method="lm", x_scale=[1e-4, 1e-4, 1e-3, 1e-3], xtol=1e-12, ftol=1e-12
        )
        ours = np.sum(residuals[0][:, :, w] ** 2)
        assert np.sum(window_residuals(start) ** 2) > 1.5 * ours  # the refinement had work to do
        assert ours == pytest.approx(2 * scipy.cost, rel=1e-8)
        np.testing.assert_allclose(states[0][:, w], scipy.x, rtol=0, atol=1e-5)


def test_one_levenberg_marquardt_step_takes_almost_all_the_smoothed_states_error_off(all_hanging_windows):
    """What lets a fit's starts be ranked after a single step of the windows' initial states: on every window of
    a model that misses the arm's viscous friction, one step leaves at most 1 % of the smoothed states' excess
    cost over the converged one (eight steps), and further steps never raise the cost (a step is kept only where
    the re-simulated residual falls)."""
    windows, _ = all_hanging_windows
    model = Model.from_rig(LUND)

    def cost(steps):
        r = projected_residuals(model, windows, LUND.counts_per_rev, sensitivities=False, steps=steps)[0][0]
        return np.sum(r**2, axis=(0, 1))

    smoothed, one, three, converged = (cost(steps) for steps in (0, 1, 3, 8))
    assert np.all(smoothed > 1.5 * converged)  # the smoothed states are far from each window's best
    assert np.all(one - converged <= 0.01 * (smoothed - converged))
    assert np.all(converged <= three) and np.all(three <= one) and np.all(one <= smoothed)


def test_the_one_step_screen_ranks_a_fits_starts_as_the_refined_windows_do(all_hanging_windows):
    """Among starts of the arm's viscous coefficient at none, the simulated one and four times it, the screen of
    ``SCREEN_STEPS`` per window picks the simulated coefficient, as a screen of the full refinement
    does."""
    windows, viscous = all_hanging_windows
    nominal = Model.from_rig(LUND)

    def model_at(x):
        return apply_effects(nominal, {"arm_viscous_friction": Effect("", (float(x[0]),))})

    starts, low, high = [[0.0], [viscous], [4.0 * viscous]], np.array([0.0]), np.array([10.0 * viscous])
    assert _best_start(starts, low, high, model_at, windows, LUND.counts_per_rev)[0] == pytest.approx(viscous)
    full = [np.sum(projected_residuals(model_at(x), windows, LUND.counts_per_rev)[0][0] ** 2) for x in starts]
    assert int(np.argmin(full)) == 1


def test_rk4_error_falls_sixteenfold_when_the_step_halves():
    """Fourth order: windows of large swings (4 ms samples, held torque, back-EMF and an arm spring), integrated
    with 1, 2, 4 and 8 substeps; the difference between successive refinements falls by 2^4 each time."""
    model = Model.from_rig(LUND).replace(back_emf_damping=2e-3, spring_stiffness=0.05)
    period, horizon = 4e-3, 60
    command = 0.05 * np.sin(2 * np.pi * 2.0 * period * np.arange(400))
    x0 = np.array([[2.5, 0.3, 1.0], [0.1, -0.2, 0.5], [-3.0, 5.0, 2.0], [2.0, -4.0, 8.0]])
    angles = [
        predict_windows(model, x0, command, np.array([10, 100, 200]), horizon, period, substeps)
        for substeps in (1, 2, 4, 8)
    ]
    differences = [np.max(np.abs(coarse - fine)) for coarse, fine in zip(angles, angles[1:])]
    for coarse, fine in zip(differences, differences[1:]):
        assert 14.0 < coarse / fine < 18.0


def friction_and_motor(rig) -> Model:
    """``rig``'s model with a Dahl arm (presliding 3 mrad), a Coulomb + viscous pendulum and its DC motor's
    back-EMF (the QUBE's kt ke / R)."""
    mgl = rig.gravity_torque
    return Model.from_rig(rig).replace(
        arm_friction=JointFrictionParameters.dahl(0.10 * mgl, 0.15 * mgl, sigma0=0.10 * mgl / 3e-3),
        pendulum_friction=JointFrictionParameters.coulomb(
            0.004 * mgl, viscous=1e-6, regularization_velocity=REGULARIZATION_VELOCITY
        ),
    )


@pytest.mark.parametrize("seed", range(3))
def test_surrogate_dynamics_with_friction_and_motor_equal_the_multibody_plant(seed):
    """At random states, bristle states and torques: the surrogate's accelerations (the Dahl torque of the
    bristle added to the command, the pendulum's static law and the back-EMF inside) equal those of the Drake
    world (MultibodyPlant, JointFriction, back-EMF) to 1e-9, and the bristle's path step over a 1e-9 rad move
    is JointFriction's dz/dt = v - sigma0 |v| z / Fc(v) to 1e-5."""
    model = friction_and_motor(QUBE)
    assert model.back_emf_damping > 0
    rng = np.random.default_rng(seed)
    builder = DiagramBuilder()
    world = add_furuta_world(
        builder,
        rig=QUBE,
        control_period=QUBE.sample_period,
        friction=FrictionParameters(arm=model.arm_friction, pendulum=model.pendulum_friction),
    )
    builder.ExportInput(world.arm_torque_input, "arm_torque_Nm")
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    for _ in range(10):
        x = rng.uniform([-3.0, -3.0, -8.0, -8.0], [3.0, 3.0, 8.0, 8.0])
        z = rng.uniform(-1.0, 1.0) * 0.15 * QUBE.gravity_torque / model.arm_friction.sigma0
        u = rng.uniform(-0.05, 0.05)
        context.get_mutable_continuous_state_vector().SetFromVector(np.append(world.to_paper.T @ x, z))
        diagram.get_input_port().FixValue(context, [u])
        derivatives = diagram.EvalTimeDerivatives(context).CopyToVector()
        drake = world.to_paper @ derivatives[:4]
        tau = np.array(u + bristle_friction_torque(z, x[3], model.arm_friction))
        # The static law acts only where a joint has one (the pendulum's); the arm's bristle torque is in tau.
        surrogate = _accelerations(model, x, tau)
        np.testing.assert_allclose(surrogate, drake, rtol=1e-9, atol=1e-9 * np.max(np.abs(drake)))
        move = 1e-9  # [rad]: the step's own curvature is sigma0 move / (2 Fc) ~ 2e-7 relative
        step = bristle_step(z, np.sign(x[3]) * move, x[3], pack_friction(model.arm_friction))
        assert (step - z) / move * abs(x[3]) == pytest.approx(derivatives[4], rel=1e-5)


def test_surrogate_windows_converge_to_the_multibody_plant_with_friction_and_motor():
    """Three 200 ms windows of large QUBE swings with stick-slip (Dahl arm, Coulomb pendulum, back-EMF): the
    surrogate's angles against the Drake world's (RK5 at 1e-10). Every RK4 stage reads the bristle's exact step
    over the stage's displacement, so at the diagnosis' own 1 ms substep they agree to a fiftieth of a count
    (holding the bristle torque over the substep, a first-order scheme, was ten times further off), and the
    error falls a hundredfold over four halvings (not by a clean power: stick-slip switches inside steps)."""
    model = friction_and_motor(QUBE)
    period = QUBE.sample_period
    time = period * np.arange(600)
    command = 0.6 * QUBE.gravity_torque * np.sin(
        2 * np.pi * 1.5 * time
    ) + 0.1 * QUBE.gravity_torque * np.random.default_rng(1).standard_normal(time.size)
    starts, horizon = np.array([50, 200, 350]), 100
    x0 = np.array([[2.8, 3.0, 3.3], [0.0, 0.2, -0.3], [1.0, -2.0, 0.5], [0.5, 0.0, -1.0]])
    z0 = np.array([0.0, 0.5, -0.5]) * 0.10 * QUBE.gravity_torque / model.arm_friction.sigma0
    replayer = WindowReplayer(model, QUBE, time, command)
    replayer.integrator = SimulatorConfig(integration_scheme="runge_kutta5", accuracy=1e-10, max_step_size=1e-4)
    drake = np.stack(
        [replayer.replay(time[s], x0[:, w], command[s], time[s : s + horizon], z0[w]) for w, s in enumerate(starts)],
        axis=-1,
    )
    count = 2 * np.pi / QUBE.counts_per_rev
    errors = [
        np.max(np.abs(predict_windows(model, x0, command, starts, horizon, period, substeps, z0) - drake)) / count
        for substeps in (1, 2, 4, 8, 16)
    ]
    assert substeps_for(period) == 2 and errors[1] < 0.02
    assert errors[-1] < errors[0] / 100 and all(fine <= 1.2 * coarse for coarse, fine in zip(errors, errors[1:]))


def test_a_replay_read_between_the_samples_holds_each_samples_command():
    """Angles asked for between the samples as well (the integrator stops there too) are those of the replay read
    at the samples alone, to a thousandth of a count: each interval still holds its sample's command, whatever
    stops fall inside it (a delayed command jumps between the samples)."""
    model = friction_and_motor(QUBE).replace(delay=0.4 * QUBE.sample_period)
    period = QUBE.sample_period
    time = period * np.arange(300)
    command = 0.6 * QUBE.gravity_torque * np.sign(np.sin(2 * np.pi * 7.0 * time))
    replayer = WindowReplayer(model, QUBE, time, command)
    x0 = np.array([2.9, 0.1, 1.0, -0.5])
    samples = time[20:120]
    finer = np.sort(np.concatenate([samples, samples[:-1] + 0.3 * period]))
    alone = replayer.replay(samples[0], x0, command[20], samples, 0.0)
    between = replayer.replay(samples[0], x0, command[20], finer, 0.0)
    count = 2 * np.pi / QUBE.counts_per_rev
    assert np.ptp(alone[:, 1]) > 20 * count  # the arm moves under the square wave
    np.testing.assert_allclose(between[np.isin(finer, samples)], alone, rtol=0, atol=1e-3 * count)


def test_the_replay_integrator_stays_far_below_a_count_of_a_tight_reference():
    """The held-out replays' own integrator (error-controlled, :data:`REPLAY_INTEGRATOR`) on large QUBE swings
    with stick-slip, a Dahl arm, Coulomb pendulum friction and back-EMF: within a hundredth of a count of the same
    windows at accuracy 1e-10 (a gap near the one-count floor is a square root: an error of a hundredth of a
    count moves it by far less than its bootstrap spread)."""
    model = friction_and_motor(QUBE)
    period = QUBE.sample_period
    time = period * np.arange(600)
    command = 0.6 * QUBE.gravity_torque * np.sin(2 * np.pi * 1.5 * time)
    starts, horizon = np.array([50, 200, 350]), 100
    x0 = np.array([[2.8, 3.0, 3.3], [0.0, 0.2, -0.3], [1.0, -2.0, 0.5], [0.5, 0.0, -1.0]])
    replayer = WindowReplayer(model, QUBE, time, command)

    def replayed(integrator):
        replayer.integrator = integrator
        return np.stack(
            [replayer.replay(time[s], x0[:, w], command[s], time[s : s + horizon], 0.0) for w, s in enumerate(starts)]
        )

    reference = replayed(SimulatorConfig(integration_scheme="runge_kutta5", accuracy=1e-10, max_step_size=1e-4))
    count = 2 * np.pi / QUBE.counts_per_rev
    assert np.ptp(reference[:, :, 0]) > 1.0  # large swings, not a rest
    assert np.max(np.abs(replayed(REPLAY_INTEGRATOR) - reference)) / count < 0.01
