"""The rig's ongoing disturbance: its seeded draws, its place in the Drake world and in rig files, its reading from
logs by the equations of motion, and ``tune`` judging its designs under it.

The numbers asserted come from the physics of the runs (the RMS a draw is made at, the band its spectrum holds,
the torque a friction law adds along a run), not from the code under test."""

from __future__ import annotations

import dataclasses
import json
import re

import numpy as np
import pytest
from scipy.signal import welch

from furuta_drake.config import ExcitationConfig, SimulationConfig
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.diagnosis.selection.disturbance import equivalent_disturbance
from furuta_drake.effects.vocabulary import rig_model
from furuta_drake.errors import ConfigError
from furuta_drake.friction import FrictionParameters, JointFrictionParameters
from furuta_drake.rig import RigParameters, lund_rig
from furuta_drake.simulate import simulate
from furuta_drake.torque_disturbance import TorqueDisturbance
from furuta_drake.yamlio import dump_yaml_dataclass, loads_yaml_dataclass

BAND = [[0.5, 1.0], [6.0, 1.0], [8.0, 0.0]]  # flat from 0.5 to 6 Hz, falling to nothing at 8 Hz


@pytest.mark.parametrize("level, low, high", [(0.005, 0.5, 6.0), (0.02, 2.0, 20.0), (1e-4, 10.0, 40.0)])
def test_a_draw_has_its_level_and_its_band(level, low, high):
    disturbance = TorqueDisturbance(level, [[low, 1.0], [high, 1.0]])
    period, count = 0.001, 20000
    draw = disturbance.samples(count, period, seed=3)
    assert np.sqrt(np.mean(draw**2)) == pytest.approx(level, rel=1e-9)
    frequencies, psd = welch(draw, fs=1 / period, nperseg=4000)
    inside = (frequencies >= low - 0.5) & (frequencies <= high + 0.5)
    assert psd[inside].sum() > 0.95 * psd.sum()
    assert np.array_equal(draw, disturbance.samples(count, period, seed=3))
    assert not np.allclose(draw, disturbance.samples(count, period, seed=4))


@pytest.mark.parametrize(
    "change, named",
    [
        (dict(arm_torque_rms=-0.001), "arm_torque_rms must be >= 0"),
        (dict(arm_torque_rms=float("nan")), "arm_torque_rms must be"),
        (dict(spectrum=[]), "spectrum needs at least two"),
        (dict(spectrum=[[2.0, 1.0], [1.0, 1.0]]), "frequencies must increase"),
        (dict(spectrum=[[1.0, -1.0], [2.0, 1.0]]), "non-negative finite"),
        (dict(spectrum=[[1.0, 0.0], [2.0, 0.0]]), "has no power"),
        (dict(ci=[0.002, 0.001]), "ci must be [low, high]"),
    ],
)
def test_a_non_physical_disturbance_is_refused_by_name(change, named):
    bad = dataclasses.replace(TorqueDisturbance(0.005, BAND, 5.0, [0.004, 0.006]), **change)
    text = dump_yaml_dataclass(lund_rig().replace(disturbance=bad))
    with pytest.raises(ConfigError, match=f"disturbance.*{re.escape(named)}"):
        loads_yaml_dataclass(text, RigParameters, source="rig.yaml")


def test_a_rig_files_disturbance_reaches_the_simulated_arm_seeded():
    disturbance = TorqueDisturbance(0.004, BAND, 5.0)
    rig = lund_rig().replace(disturbance=disturbance)
    loaded = loads_yaml_dataclass(dump_yaml_dataclass(rig), RigParameters)
    assert loaded.disturbance == disturbance
    config = SimulationConfig.from_rig(loaded, duration=3.0, seed=5)
    assert config.disturbance.arm_torque == disturbance and config.rig.disturbance is None
    quiet = simulate(SimulationConfig.from_rig("lund", duration=3.0, seed=5))
    pushed, again = simulate(config), simulate(config)
    np.testing.assert_array_equal(pushed.measured, again.measured)  # seeded
    other = simulate(dataclasses.replace(config, seed=6))
    assert not np.array_equal(pushed.measured, other.measured)
    # The pushed pendulum balances with a larger tilt than the quiet one.
    steady = slice(1500, None)
    assert np.std(pushed.state[steady, 0]) > 2.0 * np.std(quiet.state[steady, 0])
    with pytest.raises(ConfigError, match="rig.disturbance"):
        dataclasses.replace(config, rig=rig).validate()


def _logs(rig, friction=None, disturbance=None, seeds=(1, 2)):
    """Balancing runs of ``rig`` under an excitation and an arm reference, as held-out logs."""
    logs = []
    for seed in seeds:
        excitation = ExcitationConfig(torque_rms=0.1 * rig.gravity_torque, arm_reference_amplitude=0.25)
        config = SimulationConfig.from_rig(rig, duration=8.0, seed=seed, excitation=excitation)
        config.disturbance.arm_torque = disturbance
        if friction is not None:
            config.friction = friction
        result = simulate(config)
        theta, phi = result.measured[:, 0], result.measured[:, 1]
        logs.append(RunLog(f"run{seed}", "", result.time, theta, phi, "torque", result.torque, rig.sample_period))
    return logs, result


def test_the_disturbance_a_rig_carries_is_read_back_from_its_logs():
    rig = lund_rig()
    model = rig_model(rig)
    level = 0.005  # [N m], 2.5 % of the Lund rig's torque limit
    logs, _ = _logs(rig, disturbance=TorqueDisturbance(level, BAND))
    read = equivalent_disturbance(model, logs, seed=0)
    assert read.arm_torque_rms == pytest.approx(level, rel=0.15)
    assert read.ci[0] < read.arm_torque_rms < read.ci[1]
    assert 3.0 < read.bandwidth_hz < 8.5  # 90 % of a flat 0.5-6 Hz band (plus its fall to 8 Hz) lies below ~6 Hz
    quiet, _ = _logs(rig)
    assert equivalent_disturbance(model, quiet, seed=0).arm_torque_rms < 0.25 * level


def test_an_effect_the_model_misses_is_read_as_the_torque_it_applies():
    rig = lund_rig()
    viscous = 0.012  # [N m s/rad] on the arm, absent from the rig file
    arm = JointFrictionParameters(model="static", viscous=viscous)
    logs, result = _logs(rig, friction=FrictionParameters(arm=arm), seeds=(1,))
    missed = equivalent_disturbance(rig_model(rig), logs, seed=0).arm_torque_rms
    frequencies, psd = welch(viscous * result.state[:, 3], fs=1 / rig.sample_period, nperseg=2000)
    band = (frequencies > 0) & (frequencies < 10.0)
    applied = np.sqrt(psd[band].sum() * (frequencies[1] - frequencies[0]))  # the friction torque in the band
    assert missed == pytest.approx(applied, rel=0.25)
    corrected = rig_model(rig).replace(arm_friction=arm)
    assert equivalent_disturbance(corrected, logs, seed=0).arm_torque_rms < 0.4 * applied


def test_tune_judges_both_designs_under_the_rigs_disturbance(tmp_path, monkeypatch):
    from furuta_drake.cli import main
    from furuta_drake.tune import pipeline

    monkeypatch.setattr(pipeline, "TuneSettings", lambda: pipeline.FAST)
    directory = tmp_path / "diagnosis"
    directory.mkdir()
    disturbance = TorqueDisturbance(0.004, BAND, 5.0, [0.003, 0.005])
    (directory / "fitted_rig.yaml").write_text(dump_yaml_dataclass(lund_rig().replace(disturbance=disturbance)))
    (directory / "report.json").write_text(json.dumps({"verdict": "none", "effects": [], "ranking": []}))
    out = tmp_path / "tuned"
    assert main(["tune", "--diagnosis", str(directory), "--out", str(out), "--workers", "1", "--draws", "2"]) == 0
    document = json.loads((out / "tune.json").read_text())
    assert document["disturbance"]["arm_torque_rms"] == pytest.approx(0.004)
    assert document["search"]["disturbance_draws"] == 2
    for design in document["designs"].values():
        levels = design["predicted_under_disturbance"]
        assert set(levels) == {"0.5", "1", "2"}
        assert levels["1"] == design["predicted"]
        # A harder push tilts the pendulum more.
        assert levels["0.5"]["theta_rms"] < levels["1"]["theta_rms"] < levels["2"]["theta_rms"]
    text = (out / "tune.md").read_text()
    assert "Under the rig's disturbance" in text and "4 mN m RMS on the arm; at twice that" in text


def test_the_report_says_when_the_nominal_design_stays_because_of_the_disturbance():
    from types import SimpleNamespace

    from furuta_drake.tune.disturbance import at_scale, quiet_winner_note
    from furuta_drake.tune.family import Member
    from furuta_drake.tune.predict import Prediction

    world = SimulationConfig.from_rig(lund_rig().replace(disturbance=TorqueDisturbance(0.004, BAND)))
    assert at_scale(world, 0.0).disturbance.arm_torque is None
    assert at_scale(world, 2.0).disturbance.arm_torque.arm_torque_rms == pytest.approx(0.008)

    def outcome(name):
        return SimpleNamespace(controller=name, member=Member((1.0, 1.0, 4.0)))

    def problem(quiet_figures):
        def predictions(tasks):
            assert all(config.disturbance.arm_torque is None for config, _ in tasks)  # run on the quiet rig
            return [Prediction(quiet_figures[controller], "", None) for _, controller in tasks]

        return SimpleNamespace(world=world, count=2 * np.pi / 4096, predictions=predictions)

    nominal, finalist = outcome("nominal"), outcome("finalist")
    loud = {"theta_rms": 2e-3, "limit_cycle_amplitude": 4e-3}
    better = {"theta_rms": 1e-3, "limit_cycle_amplitude": 2e-3}  # half of the nominal's in both figures
    note = quiet_winner_note(problem({"nominal": loud, "finalist": better}), nominal, nominal, [finalist])
    assert "stays because of the rig's disturbance" in note and "x 0.50" in note
    # Not better on the quiet rig either, or a tuned design chosen: nothing to say.
    assert quiet_winner_note(problem({"nominal": loud, "finalist": loud}), nominal, nominal, [finalist]) == ""
    assert quiet_winner_note(problem({"nominal": loud, "finalist": better}), nominal, finalist, [finalist]) == ""


def test_the_independent_simulators_push_has_its_level_and_corner():
    from benchmarks.independent import simulator as sim

    world = sim.World(sim.lund_like(), disturbance_rms=0.004, disturbance_corner=3.0)
    period = world.rig.sample_period
    push = sim.ArmDisturbance(world, period, np.random.default_rng(1))
    values = np.array([push.next() for _ in range(200000)])
    assert np.std(values) == pytest.approx(0.004, rel=0.05)
    # first-order low-passed white noise: its lag-one correlation is exp(-2 pi f_c T)
    correlation = np.corrcoef(values[:-1], values[1:])[0, 1]
    assert correlation == pytest.approx(np.exp(-2 * np.pi * 3.0 * period), abs=1e-3)
    quiet = sim.ArmDisturbance(sim.World(sim.lund_like()), period, np.random.default_rng(1))
    assert all(quiet.next() == 0.0 for _ in range(10))
