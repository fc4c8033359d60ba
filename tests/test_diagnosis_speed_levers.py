"""The diagnosis' speed levers change no number: perturbed states share one evaluation of the input chain, a
worker pool is shared by threads (the folds' selections) with every task still contained, and the folds run at
once give what each fold's selection gives alone."""

import os
import threading

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.effects.surrogate import Model, integrate_windows, predict_windows, window_torques
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.parallel import Failure, TaskPool, run_tasks
from furuta_drake.rig import RIGS

QUBE = RIGS["qube_servo2"]()


@settings(max_examples=15, deadline=None)
@given(
    delay=st.floats(0.0, 0.01),
    lag=st.floats(0.0, 0.02),
    deadzone=st.floats(0.0, 0.01),
    substeps=st.sampled_from([1, 2, 4]),
    seed=st.integers(0, 2**16),
)
def test_copies_of_the_windows_predict_bitwise_as_tiled_windows(delay, lag, deadzone, substeps, seed):
    """The windows' torques tiled over copies x W states (the finite differences of the state sensitivities)
    predict the same as every window start repeated copies times, to the last bit, whatever the actuator chain."""
    model = Model.from_rig(QUBE).replace(
        delay=delay,
        lag=lag,
        deadzone=deadzone,
        saturation=0.05,
        arm_friction=JointFrictionParameters.dahl(1.5e-3, 1.5e-3, sigma0=1.5),
    )
    rng = np.random.default_rng(seed)
    command = 0.03 * rng.standard_normal(3000)
    starts = rng.integers(300, 2900, 6)
    copies = 3
    x0 = rng.normal(size=(4, copies * starts.size))
    z0 = 1e-4 * rng.normal(size=copies * starts.size)
    period = 1e-3 * substeps
    tiled = predict_windows(model, x0, command, np.tile(starts, copies), 20, period, substeps, z0)
    torque = np.tile(window_torques(model, command, starts, 20, period, substeps), (1, copies))
    shared = integrate_windows([model], x0, torque, period, substeps, z0)
    assert np.array_equal(tiled, shared, equal_nan=True)


@settings(max_examples=15, deadline=None)
@given(
    delay=st.floats(0.0, 0.01),
    lag=st.floats(0.0, 0.02),
    substeps=st.sampled_from([1, 2, 4]),
    dahl=st.booleans(),
    seed=st.integers(0, 2**16),
)
def test_several_models_in_one_call_predict_bitwise_as_each_alone(delay, lag, substeps, dahl, seed):
    """integrate_windows of the parameter steps of a finite-difference Jacobian (dynamics and input chain moved one
    at a time, from copies of the same states) in one call equals each model's own predict_windows to the last
    bit."""
    friction = JointFrictionParameters.dahl(1.5e-3, 1.5e-3, sigma0=1.5) if dahl else Model.from_rig(QUBE).arm_friction
    model = Model.from_rig(QUBE).replace(delay=delay, lag=lag, spring_stiffness=1e-3, arm_friction=friction)
    models = [
        model,
        model.replace(arm_inertia_total=1.001 * model.arm_inertia_total),
        model.replace(delay=delay + 1e-4),
        model.replace(spring_stiffness=2e-3),
        model.replace(lag=lag + 1e-3),
    ]
    rng = np.random.default_rng(seed)
    command = 0.03 * rng.standard_normal(3000)
    starts = rng.integers(300, 2900, 6)
    x0 = rng.normal(size=(4, starts.size))
    z0 = 1e-4 * rng.normal(size=starts.size) if dahl else None
    period = 1e-3 * substeps
    torque = np.concatenate([window_torques(m, command, starts, 20, period, substeps) for m in models], axis=1)
    bristles = None if z0 is None else np.tile(z0, len(models))
    together = integrate_windows(models, np.tile(x0, (1, len(models))), torque, period, substeps, bristles)
    alone = np.concatenate([predict_windows(m, x0, command, starts, 20, period, substeps, z0) for m in models], axis=2)
    assert np.array_equal(together, alone, equal_nan=True)


def _task(x):
    if x == "die":
        os._exit(3)  # a worker killed mid-task
    return x * 2


def test_a_pool_shared_by_threads_contains_a_dying_worker_to_its_task():
    """Two threads hand batches to one pool; a task whose worker dies fails alone, every other task of both
    threads comes back in order, and the pool serves the next batch."""
    results = {}
    with TaskPool(2) as pool:

        def batch(name, tasks):
            results[name] = run_tasks(_task, tasks, pool=pool)

        threads = [
            threading.Thread(target=batch, args=("a", [1, 2, "die", 4])),
            threading.Thread(target=batch, args=("b", [10, 20, 30])),
        ]
        for thread in threads:
            thread.start()
        for thread in threads:
            thread.join()
        after = run_tasks(_task, [5, 6], pool=pool)
    assert results["a"][:2] == [2, 4] and results["a"][3] == 8
    assert isinstance(results["a"][2], Failure) and "worker process died" in results["a"][2].reason
    assert results["b"] == [20, 40, 60]
    assert after == [10, 12]


@pytest.mark.slow
def test_folds_run_at_once_give_each_fold_selection(tmp_path):
    """consistency() runs its folds' selections in threads on one pool; each fold's verdict is the one its
    selection gives run alone, in one process."""
    from benchmarks.diagnosis.suite import run_configs, with_effect
    from furuta_drake.diagnosis.gap.metric import make_windows
    from furuta_drake.diagnosis.gap.split import fold_split
    from furuta_drake.diagnosis.logs.load import load_logs
    from furuta_drake.diagnosis.selection.folds import consistency
    from furuta_drake.diagnosis.selection.stepwise import select_effects
    from furuta_drake.diagnosis.settings import FAST
    from furuta_drake.results import write_log_csv
    from furuta_drake.simulate import simulate
    from furuta_drake.yamlio import dump_yaml_dataclass

    (tmp_path / "rig.yaml").write_text(dump_yaml_dataclass(QUBE))
    paths = []
    for seed in (3, 4):
        paths.append(tmp_path / f"run_{seed}.csv")
        write_log_csv(simulate(with_effect(run_configs(QUBE, seed, 3.0)["hanging"], "input_delay", 2)), paths[-1])
    logs = load_logs(paths, QUBE, tmp_path / "rig.yaml")
    nominal, names = Model.from_rig(QUBE), ["input_delay", "actuator_lag", "arm_viscous_friction"]
    with TaskPool(2) as pool:
        together = consistency(logs, QUBE, nominal, names, FAST, lambda f, t: run_tasks(f, t, pool=pool), folds=3)
    alone = []
    for fold in range(3):
        train, heldout = fold_split(logs, 3, fold, QUBE)
        selection = select_effects(
            nominal,
            train,
            make_windows(train, QUBE),
            make_windows(heldout, QUBE),
            QUBE.counts_per_rev,
            names,
            FAST,
            lambda f, t: run_tasks(f, t, workers=1),
        )
        alone.append(selection.verdict)
    assert together.verdicts == alone
    assert "input_delay" in alone  # the injected delay is found on at least one fold


def test_a_zero_static_friction_law_replays_bitwise_without_its_friction_system(monkeypatch):
    """A diagnosis model of a frictionless rig holds a static law of zero levels: the replay leaves its friction
    system out (a constant zero instead) and integrates every window to the same last bit as with it."""
    from furuta_drake.diagnosis.gap import replay

    model = Model.from_rig(QUBE).replace(lag=0.004)
    assert model.arm_friction.model == "static" and model.arm_friction.coulomb_pos == 0.0
    rng = np.random.default_rng(5)
    time = np.arange(600) * 2e-3
    command = 0.02 * rng.standard_normal(time.size)
    window_times = time[100:160]
    x0 = np.array([np.pi - 0.3, 0.2, 1.0, -2.0])
    without = replay.WindowReplayer(model, QUBE, time, command)
    monkeypatch.setattr(replay, "drake_friction", lambda p: p)
    with_system = replay.WindowReplayer(model, QUBE, time, command)
    assert without.friction is None and with_system.friction is not None
    a = without.replay(time[100], x0, 0.01, window_times)
    b = with_system.replay(time[100], x0, 0.01, window_times)
    assert np.abs(a[-1] - a[0]).max() > 1e-3  # the window moves
    assert np.array_equal(a, b)
