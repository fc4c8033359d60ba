"""The diagnosis engine: the surrogate against Drake, the gap metric on logs whose answer is known, the
decision rule on per-window evidence."""

import dataclasses

import numpy as np
import pytest
from conftest import hanging_log, suite_log
from hypothesis import example, given, settings
from hypothesis import strategies as st

from benchmarks.diagnosis.suite import with_effect
from furuta_drake.config import SimulationConfig
from furuta_drake.diagnosis.gap.metric import evaluate_gap, make_windows
from furuta_drake.diagnosis.gap.replay import replay_gap
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.diagnosis.report.record_text import confusable_why
from furuta_drake.diagnosis.selection.fit import FitTask, fit_task
from furuta_drake.diagnosis.selection.rule import FLOOR_COUNTS, MARGIN, Bootstrap, at_floor, choose, confusable, is_kept
from furuta_drake.diagnosis.selection.sensor import read_sensors
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects.corrected import model_rig
from furuta_drake.effects.surrogate import Model, _accelerations
from furuta_drake.effects.vocabulary import CANDIDATES, Effect, apply_effects
from furuta_drake.plant import joint_indices, make_furuta_plant
from furuta_drake.rig import RIGS, encoder_resolution
from furuta_drake.simulate import simulate


@pytest.mark.parametrize("name", sorted(RIGS))
def test_surrogate_dynamics_equal_the_multibody_plant(name):
    rig = RIGS[name]().replace(motor=None)
    plant = make_furuta_plant(rig)
    context = plant.CreateDefaultContext()
    theta, phi = joint_indices(plant)
    model = Model.from_rig(rig)
    rng = np.random.default_rng(0)
    for _ in range(20):
        x = rng.uniform(-3, 3, 4)
        tau = rng.uniform(-0.05, 0.05)
        q, v = np.zeros(2), np.zeros(2)
        q[theta], q[phi], v[theta], v[phi] = x
        plant.SetPositions(context, q)
        plant.SetVelocities(context, v)
        plant.get_actuation_input_port().FixValue(context, [tau])
        plant.get_applied_generalized_force_input_port().FixValue(context, np.zeros(2))
        xdot = plant.EvalTimeDerivatives(context).CopyToVector()
        accel = _accelerations(model, x, np.array(tau))
        np.testing.assert_allclose([accel[2], accel[3]], [xdot[2 + theta], xdot[2 + phi]], rtol=1e-7, atol=1e-9)


def test_model_rig_reproduces_the_lumped_constants():
    rig = RIGS["lund"]()
    model = Model.from_rig(rig).replace(
        arm_inertia_total=0.004, pendulum_inertia_total=0.0035, coupling=0.0026, gravity_torque=0.09
    )
    back = Model.from_rig(model_rig(model, rig))
    np.testing.assert_allclose(
        [back.arm_inertia_total, back.pendulum_inertia_total, back.coupling, back.gravity_torque],
        [0.004, 0.0035, 0.0026, 0.09],
        rtol=1e-12,
    )


@pytest.fixture(scope="module")
def clean_logs():
    return [hanging_log(1), hanging_log(2)]


def test_exact_model_sits_at_the_sensor_floor_and_drake_agrees(clean_logs):
    rig = RIGS["lund"]()
    windows = make_windows(clean_logs, rig)
    surrogate = evaluate_gap(Model.from_rig(rig), windows, rig.counts_per_rev)
    assert surrogate.gap < 0.25  # counts: the residual is the encoder's own rounding
    drake = replay_gap(Model.from_rig(rig), rig, windows, surrogate.initial_states)
    assert abs(drake.gap - surrogate.gap) < 0.02  # Drake's RK5 at 1e-6 adds no integration error to the floor


def test_a_hidden_delay_is_fitted_and_the_gap_closes():
    """A 4.5-period input delay hidden in a Drake simulation: the fit finds it and the gap shrinks."""
    rig = RIGS["lund"]()
    train = [hanging_log(3, "input_delay")]
    windows = make_windows(train, rig)
    nominal = evaluate_gap(Model.from_rig(rig), windows, rig.counts_per_rev)
    fit = fit_task(
        FitTask(
            "input_delay", {}, Model.from_rig(rig), windows, None, tuple(train), rig.counts_per_rev, DiagnosisSettings()
        )
    )
    assert fit.effects["input_delay"].values[0] == pytest.approx(4.5e-3, abs=0.5e-3)
    assert fit.train_gap < 0.5 * nominal.gap
    low, high = np.percentile(fit.samples["input_delay"][:, 0], [2.5, 97.5])
    assert low < 4.5e-3 < high and high - low < 1e-3  # a 95 % interval around the truth, of a fraction of 1 ms


def test_a_hidden_lag_at_its_true_time_constant_sits_at_the_floor_in_the_surrogate_and_in_drake():
    """The suite's 12 ms first-order actuator lag (Drake's FirstOrderLowPassFilter in the loop): the surrogate,
    which applies each substep the filter's mean over it, and the Drake replay agree at the floor (applying the
    filter's end value instead read 0.05 counts in the surrogate and 0.10 in Drake)."""
    rig = RIGS["lund"]()
    windows = make_windows([hanging_log(8, "actuator_lag")], rig)
    model = apply_effects(Model.from_rig(rig), {"actuator_lag": Effect("", (0.012,))})
    surrogate = evaluate_gap(model, windows, rig.counts_per_rev)
    drake = replay_gap(model, rig, windows, surrogate.initial_states)
    assert evaluate_gap(Model.from_rig(rig), windows, rig.counts_per_rev).gap > 0.5
    assert surrogate.gap < 0.05 and drake.gap < 0.05  # counts


def test_sensor_effects_are_read_from_the_data(clean_logs):
    """On logs of the Drake world: no noise and no coarser encoder on clean logs; the suite's level-1 coarser
    encoder (a quarter of the counts) read from its grid; its level-2 noise of 3 counts (ahead of the rounding, as
    the encoder system adds it) read within its interval."""
    rig = RIGS["lund"]()
    nominal = Model.from_rig(rig)

    def read(train, heldout):
        train, heldout = make_windows(train, rig), make_windows(heldout, rig)
        bootstrap = Bootstrap(heldout.count, 1000, 0)
        return read_sensors(nominal, train, heldout, rig.counts_per_rev, DiagnosisSettings(), bootstrap)

    grid, noise = read(clean_logs[:1], clean_logs[1:])
    assert not grid.accepted and not noise.accepted
    grid, _ = read(
        [hanging_log(4, "encoder_quantization", level=1)], [hanging_log(14, "encoder_quantization", level=1)]
    )
    assert grid.accepted and grid.effect.values == (rig.counts_per_rev / 4,)
    grid, noise = read([hanging_log(5, "measurement_noise", level=2)], [hanging_log(15, "measurement_noise", level=2)])
    sigma = 3.0 * encoder_resolution(rig.counts_per_rev)  # the suite's level-2 noise: 3 counts
    assert noise.accepted and not grid.accepted
    low, high = np.percentile(noise.samples[:, 0], [2.5, 97.5])
    assert low < sigma < high


def _evidence(previous, candidates, seed=0):
    bootstrap = Bootstrap(previous.size, 1000, seed)
    return bootstrap, {name: bootstrap.evidence(previous, per_window) for name, per_window in candidates.items()}


def test_the_rule_none_at_the_floor_an_effect_when_supported_nothing_otherwise():
    rng = np.random.default_rng(0)
    floor = rng.normal(0.0, 0.01, 60)
    assert at_floor(floor) and Bootstrap(60, 1000, 0).within_noise(floor)
    nominal = 4.0 + rng.normal(0.0, 0.5, 60)
    assert not at_floor(nominal) and not Bootstrap(60, 1000, 0).within_noise(nominal)
    # A gap carried by one window in a hundred: well above the floor, yet not significant (a third of the
    # bootstrap's resamples miss that window and read 0): within the noise.
    one = np.where(np.arange(100) == 0, 12.0, 0.0) + rng.normal(0.0, 0.01, 100)
    assert not at_floor(one) and Bootstrap(100, 1000, 0).within_noise(one)
    closed = {"input_delay": 0.05 * nominal, "actuator_lag": 0.2 * nominal, "arm_spring": 0.95 * nominal}
    _, evidence = _evidence(nominal, closed)
    assert choose(evidence, {name: name for name in closed}) == "input_delay"
    _, evidence = _evidence(nominal, {"arm_spring": 0.95 * nominal})  # 2.5 % of the gap: not supported
    assert choose(evidence, {"arm_spring": "arm_spring"}) is None


def test_the_rule_prefers_the_simpler_of_two_equal_explanations():
    nominal = np.full(40, 9.0) + np.random.default_rng(1).normal(0, 0.2, 40)
    _, evidence = _evidence(nominal, {"arm_stribeck": 0.04 * nominal, "arm_coulomb_friction": 0.05 * nominal})
    assert (
        choose(evidence, {"arm_stribeck": "arm_stribeck", "arm_coulomb_friction": "arm_coulomb_friction"})
        == "arm_coulomb_friction"
    )


def test_a_second_effect_is_judged_against_the_model_holding_the_first():
    """A strong first effect leaves 5 % of the excess; a second effect that removes 60 % of what is left is
    accepted at the next step (its reduction over the model holding the first, bounded below by the bootstrap,
    exceeds the margin), although it adds little to the reduction from nominal; one that removes 5 % is not."""
    rng = np.random.default_rng(3)
    after_first = 0.05 * (16.0 + rng.normal(0.0, 1.0, 80))
    second, weak = "arm_coulomb_friction+actuator_lag", "arm_coulomb_friction+arm_spring"
    candidates = {second: 0.4 * after_first * rng.uniform(0.8, 1.2, 80), weak: 0.95 * after_first}
    added = {second: "actuator_lag", weak: "arm_spring"}
    _, evidence = _evidence(after_first, candidates)
    assert evidence[second].lower_bound > MARGIN
    assert choose(evidence, added) == second
    assert choose({weak: evidence[weak]}, added) is None


def test_two_laws_that_explain_the_data_alike_are_confusable_and_a_clear_winner_is_not():
    rng = np.random.default_rng(4)
    nominal = 9.0 + rng.normal(0.0, 1.0, 60)
    noise = rng.normal(0.0, 0.05, (2, 60))
    candidates = {
        "input_delay": 0.1 * nominal + noise[0],
        "actuator_lag": 0.1 * nominal + noise[1],
        "arm_spring": 0.5 * nominal,
    }
    added = {name: name for name in candidates}
    bootstrap, evidence = _evidence(nominal, candidates)
    chosen = choose(evidence, added)
    pairs = confusable(chosen, evidence, added, nominal, candidates, bootstrap)
    assert [sorted(pair["effects"]) for pair in pairs] == [["actuator_lag", "input_delay"]]
    low, high = pairs[0]["difference"]
    assert low <= 0.0 <= high and not pairs[0]["by_excess"]
    assert "holds 0" in confusable_why(pairs[0])


def test_laws_apart_by_less_than_the_floor_resolves_are_confusable_off_the_floor_too():
    """A delay and a lag beside friction and a spring leave a gap of a tenth of a count: the two fits' reductions
    of it differ by several points, beyond their bootstrap interval, yet by an excess squared residual (0.6 x the
    floor's 0.03^2 counts^2) below what the floor resolves; another law 3x the floor's square behind is no rival."""
    rng = np.random.default_rng(5)
    floor = FLOOR_COUNTS**2
    previous = 0.01 + rng.normal(0.0, 0.001, 60)  # a gap of 0.1 counts, above the floor
    noise = rng.normal(0.0, 0.0001, (3, 60))
    candidates = {
        "actuator_lag": 0.003 + noise[0],
        "input_delay": 0.003 + 0.6 * floor + noise[1],
        "torque_gain_error": 0.003 + 3.0 * floor + noise[2],
    }
    added = {name: name for name in candidates}
    bootstrap, evidence = _evidence(previous, candidates)
    assert not at_floor(candidates["actuator_lag"])
    assert all(is_kept(e) for e in evidence.values())
    reductions = bootstrap.difference_interval(previous, candidates["actuator_lag"], candidates["input_delay"])
    assert reductions[0] > 0.0  # the reductions alone would tell them apart
    pairs = confusable("actuator_lag", evidence, added, previous, candidates, bootstrap)
    assert [pair["effects"] for pair in pairs] == [["actuator_lag", "input_delay"]]
    assert pairs[0]["by_excess"] and pairs[0]["difference"][0] < floor
    assert "below the floor's resolution" in confusable_why(pairs[0])


@pytest.mark.parametrize(
    "rig_name, effect, law", [("lund", "arm_stribeck", "arm"), ("qube_servo2", "pendulum_friction", "pendulum")]
)
def test_the_true_model_of_a_balancing_run_with_stiction_predicts_it(rig_name, effect, law):
    """While balancing, joints stick and slip: a window's prediction hinges on its initial velocity (and, for
    LuGre, its bristle state), which the smoother gets wrong at a stick. With its states refined by the damped
    Levenberg-Marquardt steps the true model must predict at least 3x better than the frictionless nominal one
    (with a near-Gauss-Newton second step it predicted worse: 0.45 counts against the nominal 0.15)."""
    rig = RIGS[rig_name]()
    truth = getattr(with_effect(SimulationConfig.from_rig(rig), effect, 2).friction, law)
    windows = make_windows([suite_log("balance", 11, effect, 2, 8.0, rig_name)], rig)
    nominal = Model.from_rig(rig)
    if effect == "arm_stribeck":
        params = Effect(
            "presliding", (truth.coulomb_pos, truth.static_pos, truth.stribeck_velocity, truth.bristle_bound)
        )
    else:
        params = Effect("", (truth.coulomb_pos, truth.viscous))
    true_gap = evaluate_gap(apply_effects(nominal, {effect: params}), windows, rig.counts_per_rev).gap
    assert true_gap < evaluate_gap(nominal, windows, rig.counts_per_rev).gap / 3.0


def test_two_models_at_the_floor_are_told_apart_by_the_residual_below_it():
    """Both reach a gap of 0 (a reduction of 1 after the square root's clip): the one whose residual sits further
    below the sensor variance explains the data better, whatever the names' order."""
    rng = np.random.default_rng(2)
    nominal = 0.25 + rng.normal(0.0, 0.02, 60)
    for better, worse in (("input_delay", "actuator_lag"), ("actuator_lag", "input_delay")):
        _, evidence = _evidence(nominal, {better: rng.normal(-0.02, 0.005, 60), worse: rng.normal(-0.002, 0.005, 60)})
        assert choose(evidence, {better: better, worse: worse}) == better


def test_every_vocabulary_effect_is_a_candidate_and_every_form_changes_the_model():
    from benchmarks.diagnosis.suite import VOCABULARY

    assert {name for name, candidate in CANDIDATES.items() if not candidate.drive} == set(VOCABULARY)
    assert {name for name, candidate in CANDIDATES.items() if candidate.drive} == {"drive_backlash", "drive_compliance"}
    for name, candidate in CANDIDATES.items():
        model = Model.from_rig(RIGS["geared" if candidate.drive else "qube_servo2"]())
        for form in candidate.forms:
            low, high = form.bounds(_scales(model))
            changed = apply_effects(model, {name: Effect(form.name, [0.5 * (lo + hi) for lo, hi in zip(low, high)])})
            assert changed != model, (name, form.name)


def _scales(model):
    from furuta_drake.effects.vocabulary import Scales

    return Scales(
        torque=model.gravity_torque,
        command=0.05,
        arm_inertia=model.arm_inertia_total,
        pendulum_inertia=model.pendulum_inertia_total,
        period=2e-3,
        drive_inertia=model.rotor_share * (1.0 - model.rotor_share) * model.arm_inertia_total,
    )


def test_fitted_model_is_a_simulate_config_that_runs():
    from furuta_drake.effects.corrected import model_config

    rig = RIGS["lund"]()
    model = apply_effects(
        Model.from_rig(rig),
        {"arm_coulomb_friction": Effect("presliding", (0.01, 2e-3)), "input_delay": Effect("fixed", (0.003,))},
    )
    config = model_config(rig, model)
    config.validate()
    config = dataclasses.replace(config, duration=0.5)
    result = simulate(config)
    assert np.max(np.abs(result.state[:, 0])) < 0.2
    assert isinstance(config, SimulationConfig)


COMMANDS = np.array([-0.03, -0.01, 0.0, 0.005, 0.02])


@pytest.mark.parametrize(
    "effect, form, actuator, values",
    [
        ("actuator_deadzone", "subtract", dict(deadzone=0.01), [-0.02, 0.0, 0.0, 0.0, 0.01]),
        (
            "actuator_deadzone",
            "threshold",
            dict(deadzone=0.01, deadzone_form="threshold"),
            [-0.03, 0.0, 0.0, 0.0, 0.02],
        ),
        ("actuator_saturation", "hard", dict(saturation=0.01), [-0.01, -0.01, 0.0, 0.005, 0.01]),
        (
            "actuator_saturation",
            "smooth",
            dict(saturation=0.01, saturation_form="smooth"),
            0.01 * np.tanh(COMMANDS / 0.01),
        ),
    ],
)
def test_the_forms_of_an_actuator_effect_map_commands_as_their_names_say(effect, form, actuator, values):
    """Dead zone, subtract: the width is taken off larger commands; threshold: smaller commands are dropped,
    larger ones pass whole. Saturation, hard: a clip; smooth: L tanh(u / L). In the surrogate and in Drake's
    actuator chain alike."""
    from pydrake.systems.framework import DiagramBuilder

    from furuta_drake.actuator import ActuatorParameters, add_actuator
    from furuta_drake.effects.surrogate import applied_torque

    commands = COMMANDS
    model = apply_effects(Model.from_rig(RIGS["lund"]()), {effect: Effect(form, (0.01,))})
    np.testing.assert_allclose(applied_torque(model, commands), values, atol=1e-15)
    builder = DiagramBuilder()
    entry, out = add_actuator(builder, ActuatorParameters(**actuator), 1e-3)
    builder.ExportInput(entry)
    builder.ExportOutput(out)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    for command, value in zip(commands, values):
        diagram.get_input_port().FixValue(context, [command])
        assert diagram.get_output_port().Eval(context)[0] == pytest.approx(value, abs=1e-15)


@settings(max_examples=25, deadline=None)
@given(
    level=st.floats(1e-3, 0.1),
    presliding=st.floats(1e-4, 1e-2),
    travel=st.floats(1e-4, 0.05),
    pieces=st.integers(1, 50),
)
def test_dahl_bristle_follows_the_path_alone(level, presliding, travel, pieces):
    """Dahl (Eq. 7) from z = 0 over a monotone travel D: z = z_max (1 - exp(-D / z_max)), z_max = Fc / sigma0,
    however the travel is cut into samples (the law is rate independent)."""
    from furuta_drake.effects.surrogate import bristle_path
    from furuta_drake.friction import JointFrictionParameters

    p = JointFrictionParameters.dahl(level, level, level / presliding)
    path = np.concatenate([[0.0], np.sort(np.random.default_rng(pieces).uniform(0, travel, pieces)), [travel]])
    assert bristle_path(path, p, 1e-3)[-1] == pytest.approx(presliding * (1 - np.exp(-travel / presliding)), rel=1e-9)


@settings(max_examples=25, deadline=None)
@given(speed=st.floats(1e-3, 2.0), ratio=st.floats(1.0, 4.0), travel=st.floats(1e-4, 0.05))
def test_lugre_bristle_saturates_at_the_stribeck_level_of_its_speed(speed, ratio, travel):
    """LuGre at a constant speed v is Dahl with the level g(v) = Fc + (Fs - Fc) exp(-(v / vs)^2): from z = 0
    over a travel D, z = z_max (1 - exp(-D / z_max)) with z_max = g(v) / sigma0."""
    from furuta_drake.effects.surrogate import bristle_path
    from furuta_drake.friction import JointFrictionParameters

    coulomb, sigma0, vs, period = 0.01, 4.0, 0.1, 1e-3
    p = JointFrictionParameters(
        model="lugre",
        coulomb_pos=coulomb,
        coulomb_neg=coulomb,
        static_pos=ratio * coulomb,
        static_neg=ratio * coulomb,
        stribeck_velocity=vs,
        sigma0=sigma0,
    )
    path = np.arange(0.0, travel + speed * period, speed * period)
    z_max = (coulomb + (ratio - 1.0) * coulomb * np.exp(-((speed / vs) ** 2))) / sigma0
    assert bristle_path(path, p, period)[-1] == pytest.approx(z_max * (1 - np.exp(-path[-1] / z_max)), rel=1e-6)


def test_hidden_lugre_stribeck_friction_is_the_stribeck_candidate_at_its_true_levels():
    """The suite's Stribeck friction is LuGre (presliding, breakaway at 3x the Coulomb level, vs = 0.1 rad/s).
    The candidate at the true levels and presliding puts the surrogate at the sensor floor, and the Drake replay
    of the same model agrees."""
    rig = RIGS["lund"]()
    truth = with_effect(SimulationConfig.from_rig(rig), "arm_stribeck", 2).friction.arm
    logs = [hanging_log(6, "arm_stribeck")]
    windows = make_windows(logs, rig)
    params = Effect("presliding", (truth.coulomb_pos, truth.static_pos, truth.stribeck_velocity, truth.bristle_bound))
    model = apply_effects(
        Model.from_rig(rig).replace(
            arm_friction=dataclasses.replace(Model.from_rig(rig).arm_friction, viscous=truth.viscous)
        ),
        {"arm_stribeck": params},
    )
    nominal = evaluate_gap(Model.from_rig(rig), windows, rig.counts_per_rev).gap
    surrogate = evaluate_gap(model, windows, rig.counts_per_rev)
    assert nominal > 1.0 and surrogate.gap < 0.3  # counts
    drake = replay_gap(model, rig, windows, surrogate.initial_states)
    assert abs(drake.gap - surrogate.gap) < 0.1


def test_a_cubic_spring_pulls_back_as_k_x_plus_k3_x_cubed_in_the_surrogate_and_in_drake():
    """The cable form of the arm spring, -(k x + k3 x^3) with x = phi - phi_0: the surrogate's arm acceleration
    and the Drake world's (MultibodyPlant with the spring) agree at random states."""
    from pydrake.systems.framework import DiagramBuilder

    from furuta_drake.effects.corrected import model_disturbance, model_rig
    from furuta_drake.world import add_furuta_world

    rig = RIGS["qube_servo2"]().replace(motor=None)
    model = apply_effects(Model.from_rig(rig), {"arm_spring": Effect("cubic", (0.004, 0.02, 0.1))})
    builder = DiagramBuilder()
    world = add_furuta_world(
        builder, rig=model_rig(model, rig), control_period=rig.sample_period, disturbance=model_disturbance(model)
    )
    builder.ExportInput(world.arm_torque_input, "arm_torque_Nm")
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    rng = np.random.default_rng(5)
    for _ in range(10):
        x = rng.uniform([-3.0, -1.5, -5.0, -5.0], [3.0, 1.5, 5.0, 5.0])
        context.get_mutable_continuous_state_vector().SetFromVector(world.to_paper.T @ x)
        diagram.get_input_port().FixValue(context, [0.0])
        drake = world.to_paper @ diagram.EvalTimeDerivatives(context).CopyToVector()[:4]
        stretch = x[1] - 0.1
        assert model.spring_stiffness * stretch + model.spring_cubic * stretch**3 == pytest.approx(
            0.004 * stretch + 0.02 * stretch**3
        )
        np.testing.assert_allclose(_accelerations(model, x, np.array(0.0)), drake, rtol=1e-9, atol=1e-12)


def test_a_stribeck_fit_without_static_excess_or_an_asymmetry_with_equal_levels_is_named_coulomb_friction():
    from furuta_drake.diagnosis.selection.stepwise import _vocabulary_name

    assert _vocabulary_name("arm_stribeck", Effect("presliding", (0.01, 0.0105, 0.1, 1e-3))) == "arm_coulomb_friction"
    assert _vocabulary_name("arm_stribeck", Effect("presliding", (0.01, 0.02, 0.1, 1e-3))) == "arm_stribeck"
    # an asymmetry whose levels differ by 0.03 % is none; one of 28 % is
    assert _vocabulary_name("friction_asymmetry", Effect("presliding", (0.00975, 0.009753, 2e-3))) == (
        "arm_coulomb_friction"
    )
    assert _vocabulary_name("friction_asymmetry", Effect("smooth", (0.00138, 0.00177, 0.02))) == "friction_asymmetry"


@settings(max_examples=30, deadline=None)
@given(duration=st.floats(0.5, 60.0), period=st.sampled_from([1e-3, 2e-3, 4e-3]))
@example(duration=5.21875, period=1e-3)  # five blocks: two held out (40 %) is as near 30 % as one
def test_the_automatic_holdout_partitions_every_log_and_spreads_over_it(duration, period):
    """Without --heldout no sample is lost or used twice, about 30 % is held out, and on a log of three or more
    1 s blocks the held-out part is not just its tail (a swing-up log's tail is only balancing)."""
    from furuta_drake.diagnosis.gap.split import MIN_BLOCK_S, split_heldout

    n = int(duration / period)
    time = np.arange(n) * period
    log = RunLog(
        name="run.csv",
        path="",
        time=time,
        theta=0 * time,
        phi=0 * time,
        input_kind="torque",
        input=0 * time,
        sample_period=period,
    )
    train, heldout, note = split_heldout([log])
    parts = sorted(train + heldout, key=lambda part: part.time[0])
    np.testing.assert_array_equal(np.concatenate([part.time for part in parts]), time)
    share = sum(part.time.size for part in heldout) / n
    if duration >= 3 * MIN_BLOCK_S:
        blocks = min(10, int(n * period / MIN_BLOCK_S))
        assert abs(share - 0.3) <= 0.5 / blocks + 2.0 / n  # the nearest whole number of blocks to 30 %
        assert any(part.time[-1] < time[-1] for part in heldout)  # a held-out block inside the run
        assert all(part.time.size * period >= MIN_BLOCK_S - period for part in parts)
    else:
        assert heldout[0].time[-1] == time[-1] and share == pytest.approx(0.3, abs=2.0 / n)
    assert "held out" in note


def test_parameters_fitted_at_a_bound_of_their_range_are_named():
    from furuta_drake.diagnosis.selection.fit import at_bounds

    low, high = np.array([0.0, 0.0, 0.01, 1e-4]), np.array([0.05, 1.0, 1.0, 0.05])
    x = np.array([0.0, 0.5, 1.0 - 1e-6, 0.01])
    assert at_bounds(("arm_stribeck",), ["presliding"], x, low, high) == [
        "arm_stribeck.coulomb (lower)",
        "arm_stribeck.stribeck_velocity (upper)",
    ]
    assert at_bounds(("arm_stribeck",), ["presliding"], np.array([0.01, 0.5, 0.1, 0.01]), low, high) == []


def test_a_second_effect_of_clear_size_on_a_small_uneven_remainder_is_kept_a_small_one_is_not():
    """Beside a strong first effect the remaining gap is small and carried unevenly by the windows (stick-slip
    episodes), so the bootstrap bound of a second effect's reduction is wide. An effect that removes a quarter of
    the remaining gap, unevenly over the windows, earns its place; one that removes a tenth does not, however
    significant, nor does one whose reduction lies in the two worst windows only."""
    rng = np.random.default_rng(3)
    remainder = rng.exponential(0.2, 60) ** 2  # per-window excess [counts^2] left by the first effect
    quarter = remainder * rng.uniform(0.0, 1.125, 60)  # on average 0.5625 = 0.75^2: the RMS gap falls by 1/4
    tenth = remainder * 0.9**2
    worst_two = remainder.copy()
    worst_two[np.argsort(remainder)[-2:]] *= 0.1
    _, evidence = _evidence(remainder, {"quarter": quarter, "tenth": tenth, "worst_two": worst_two})
    assert 0.2 < evidence["quarter"].reduction < 0.3
    assert evidence["quarter"].lower_bound < MARGIN  # a 20 % lower bound would turn it away
    assert is_kept(evidence["quarter"])
    assert evidence["tenth"].lower_bound > 0.05 and not is_kept(evidence["tenth"])
    assert not is_kept(evidence["worst_two"])


def test_a_delay_just_past_a_sample_replays_in_drake_as_in_the_surrogate():
    """A fit can land a delay a fraction of a microsecond past a whole number of samples: the applied command then
    jumps just after each sample. Drake's error-controlled steps stop at every jump, so the replay agrees with the
    surrogate (which integrates each substep's mean command) as closely as for a delay of whole samples; a step
    that straddles such a jump leaves an error its step control does not see."""
    rig = RIGS["lund"]()
    windows = make_windows([hanging_log(3, "input_delay")], rig)
    model = apply_effects(Model.from_rig(rig), {"input_delay": Effect("fixed", (4.0005e-3,))})
    surrogate = evaluate_gap(model, windows, rig.counts_per_rev)
    drake = replay_gap(model, rig, windows, surrogate.initial_states)
    assert abs(drake.gap - surrogate.gap) < 0.002  # counts
