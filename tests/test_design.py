"""``furuta-drake design``: the discrimination criterion's physics, the bounds of a design under every hypothesis
(checked in Drake, apart from the design's own check), equal hypotheses, and the command line."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest
import yaml

from benchmarks.diagnosis.suite import run_configs
from furuta_drake.cli import main
from furuta_drake.design import pipeline
from furuta_drake.design.criterion import Parametrised, experiment_windows, linearised_noncentrality
from furuta_drake.design.family import Family
from furuta_drake.design.rollout import drake_config, surrogate_runs
from furuta_drake.diagnosis.logs.load import load_logs
from furuta_drake.effects.surrogate import sensor_variance
from furuta_drake.effects.vocabulary import Effect, Scales, apply_effects, rig_model
from furuta_drake.results import write_log_csv
from furuta_drake.rig import encoder_resolution, lund_rig
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import dump_yaml_dataclass

DELAY = 0.003  # [s]


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """A Lund rig file and two short hanging logs, as a diagnosis reads them."""
    root = tmp_path_factory.mktemp("case")
    rig = lund_rig()
    (root / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    for name, seed in (("train.csv", 3), ("heldout.csv", 4)):
        write_log_csv(simulate(run_configs(rig, seed, 2.0)["hanging"]), root / name)
    return root


def write_diagnosis(directory, case, rival: dict) -> None:
    """A diagnosis directory whose verdict is an input delay, confusable with ``rival`` (params of an
    actuator lag) at step 1: report.json with the keys the design reads, config.yaml with the inputs."""
    directory.mkdir()

    def entry(path):
        return {"path": str(path), "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}

    ranking = [
        {
            "effect": "input_delay",
            "params": {"delay": DELAY},
            "step": 1,
            "status": "ok",
            "heldout_reduction": 0.9,
            "reduction_over_previous": 0.9,
        },
        {
            "effect": "actuator_lag",
            "params": rival,
            "step": 1,
            "status": "ok",
            "heldout_reduction": 0.9,
            "reduction_over_previous": 0.9,
        },
    ]
    report = {
        "verdict": "input_delay",
        "effects": ["input_delay"],
        "ranking": ranking,
        "steps": [{"effect": "input_delay"}],
        "detection_limits": [],
        "confusable": [{"effects": ["input_delay", "actuator_lag"], "why": "built to be"}],
    }
    (directory / "report.json").write_text(json.dumps(report))
    (directory / "config.yaml").write_text(
        yaml.safe_dump(
            {
                "rig": entry(case / "rig.yaml"),
                "train": [entry(case / "train.csv")],
                "heldout": [entry(case / "heldout.csv")],
            }
        )
    )


def noncentrality(truth_effects: dict, rival_effects: dict, amplitudes) -> float:
    """lambda of a 2 s experiment of the family on the Lund rig, ``truth_effects`` generating it."""
    rig = lund_rig()
    nominal = rig_model(rig)
    truth = apply_effects(nominal, truth_effects)
    family = Family(2.0, rig.sample_period, nominal.arm_inertia_total, 0.0)
    command = family.feedforward(np.array([amplitudes]))
    train, heldout = experiment_windows(
        surrogate_runs(truth, command, rig.sample_period), command, rig.sample_period, rig
    )
    scales = Scales(
        torque=nominal.gravity_torque,
        command=rig.torque_limit,
        arm_inertia=nominal.arm_inertia_total,
        pendulum_inertia=nominal.pendulum_inertia_total,
        period=rig.sample_period,
    )
    return float(
        linearised_noncentrality(
            Parametrised(nominal, rival_effects, scales),
            train,
            heldout,
            rig.counts_per_rev,
            sensor_variance(truth, rig.counts_per_rev),
        )[0]
    )


AMPLITUDES = [0.02, 0.02, 0.01, 0.004, 0.0]  # [rad] per band: arm motion up to 10 Hz


def test_noncentrality_is_zero_for_equal_models_and_grows_as_the_square_of_an_effect():
    lag = {size: noncentrality({"actuator_lag": Effect("", (size,))}, {}, AMPLITUDES) for size in (0.0, 1e-3, 2e-3)}
    assert lag[0.0] < 1e-6 * lag[2e-3]
    assert 0 < lag[1e-3] < lag[2e-3]
    assert 3.0 < lag[2e-3] / lag[1e-3] < 5.0  # a small effect's residual is linear in its size


def test_a_difference_the_refit_absorbs_counts_for_nothing():
    """A lag of 2 ms judged by a lag hypothesis fitted at 3 ms: the refit finds 2 ms, and what is left is a
    small share of what the lag shows against the nominal model."""
    truth = {"actuator_lag": Effect("", (2e-3,))}
    against_nominal = noncentrality(truth, {}, AMPLITUDES)
    against_wrong_size = noncentrality(truth, {"actuator_lag": Effect("", (3e-3,))}, AMPLITUDES)
    assert against_wrong_size < 0.02 * against_nominal


def test_the_design_respects_its_bounds_under_every_hypothesis(case, tmp_path, monkeypatch):
    """Played on each hypothesis' Drake model (a run of its own, not the design's check), the experiment keeps
    the arm within --arm-bound, the pendulum near hanging and the command within the rig's limit."""
    write_diagnosis(tmp_path / "diagnosis", case, {"time_constant": DELAY})
    monkeypatch.setattr(pipeline, "DesignSettings", lambda **_: pipeline.FAST)
    out = tmp_path / "design"
    assert (
        main(
            [
                "design",
                "--diagnosis",
                str(tmp_path / "diagnosis"),
                "--out",
                str(out),
                "--duration",
                "2",
                "--arm-bound",
                "0.3",
            ]
        )
        == 0
    )
    for name in ("experiment.csv", "design.json", "design.md", "design.png", "config.yaml"):
        assert (out / name).stat().st_size > 0
    lines = (out / "experiment.csv").read_text().splitlines()
    assert lines[0].startswith("# open-loop command [N m]") and lines[1] == "time,torque"
    command = np.loadtxt(out / "experiment.csv", delimiter=",", skiprows=2)[:, 1]
    design = json.loads((out / "design.json").read_text())
    assert design["status"] == "design" and design["duration_s"] == 2.0 and command.size == 2000
    assert [h["name"] for h in design["hypotheses"]] == ["input_delay", "actuator_lag"]
    rig = lund_rig()
    assert np.max(np.abs(command)) <= rig.torque_limit + 1e-9
    nominal = rig_model(rig)
    for effects in ({"input_delay": Effect("fixed", (DELAY,))}, {"actuator_lag": Effect("", (DELAY,))}):
        result = simulate(drake_config(rig, apply_effects(nominal, effects), command, 2.0, False, 7))
        assert np.max(np.abs(result.state[:, 1])) <= 0.3
        assert np.max(np.abs(result.state[:, 0] - np.pi)) <= pipeline.PENDULUM_BOUND["hanging"]
    pair = design["pairs"][0]
    assert {d["truth"] for d in pair["directions"]} == {"input_delay", "actuator_lag"}
    assert all(d["noncentrality"] > 0 and 0 <= d["detection_probability"] <= 1 for d in pair["directions"])


def test_equal_hypotheses_get_no_experiment_separates_them(case, tmp_path):
    """A delay of 0 and a lag of 0 are the same model: no experiment, and no command file."""
    directory = tmp_path / "diagnosis"
    write_diagnosis(directory, case, {"time_constant": 0.0})
    report = json.loads((directory / "report.json").read_text())
    report["ranking"][0]["params"]["delay"] = 0.0
    (directory / "report.json").write_text(json.dumps(report))
    design = pipeline.design_experiment(directory, duration=2.0, settings=pipeline.FAST)
    assert design.status == "no_separation" and design.reason.startswith("no experiment separates them")
    assert design.command is None


def test_design_refuses_bad_input_with_one_line(case, tmp_path, capsys):
    write_diagnosis(tmp_path / "diagnosis", case, {"time_constant": DELAY})
    base = ["design", "--diagnosis", str(tmp_path / "diagnosis"), "--out", str(tmp_path / "out")]
    for extra, fragment in (
        (["--target", "cogging=0.1"], "unknown effect 'cogging'"),
        (["--target", "measurement_noise=0.001"], "sensor effect"),
        (["--duration", "-1"], "--duration must be a positive"),
        (["--duration", "0.1"], "too short"),
    ):
        assert main(base + extra) == 2
        assert fragment in capsys.readouterr().err
    assert main(["design", "--diagnosis", str(tmp_path / "missing"), "--out", str(tmp_path / "out")]) == 2
    assert "no such diagnosis directory" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_the_closed_loop_surrogate_is_drakes_lqr_loop():
    """--balancing searches on the surrogate stepped under the LQR: with a lag and Dahl arm friction it follows
    the Drake diagram of the same model and gain to within an encoder count."""
    from furuta_drake.design.rollout import nominal_lqr_gain, surrogate_closed_loop

    rig = lund_rig()
    model = apply_effects(
        rig_model(rig),
        {"actuator_lag": Effect("", (0.004,)), "arm_coulomb_friction": Effect("presliding", (0.005, 0.002))},
    )
    gain = nominal_lqr_gain(rig)
    dither = Family(2.0, rig.sample_period, model.arm_inertia_total, 0.0).torque_dither(np.full((1, 5), 0.02))
    angles, _ = surrogate_closed_loop(model, gain, dither, rig.sample_period, rig.torque_limit, rig.counts_per_rev)
    result = simulate(drake_config(rig, model, dither[0], 2.0, True, 0, gain))
    assert np.max(np.abs(result.state[:, 0])) > 0.01  # the dither moves the pendulum
    count = encoder_resolution(rig.counts_per_rev)
    assert np.max(np.abs(angles[: result.time.size, :, 0] - result.state[:, :2])) < count


def test_a_target_below_the_detection_limit_is_a_hypothesis_and_one_above_it_is_settled(case):
    """--target actuator_lag=VALUE: below the lag's detection limit it is the accepted model plus that lag (a
    nested pair); above it the logs would have shown it, so nothing is left to separate."""
    from furuta_drake.design.hypotheses import parse_target, read_hypotheses
    from furuta_drake.errors import ConfigError

    rig = lund_rig()
    logs = load_logs([case / "train.csv"], rig)
    report = {
        "ranking": [
            {
                "effect": "input_delay",
                "params": {"delay": DELAY},
                "step": 1,
                "status": "ok",
                "heldout_reduction": 0.9,
                "reduction_over_previous": 0.9,
            }
        ],
        "steps": [{"effect": "input_delay"}],
        "detection_limits": [{"effect": "actuator_lag", "param": "time_constant", "value": 0.002}],
    }
    found = read_hypotheses(report, rig, logs, [parse_target("actuator_lag=0.001")])
    assert [h.name for h in found.hypotheses] == ["input_delay", "input_delay+actuator_lag"]
    assert found.hypotheses[1].effects["actuator_lag"].values == (0.001,)
    assert found.pairs[0].nested and found.pairs[0].new == ("", "actuator_lag")
    with pytest.raises(ConfigError, match="already detected"):
        read_hypotheses(report, rig, logs, [parse_target("actuator_lag=0.005")])
    with pytest.raises(ConfigError, match="already accepted input_delay"):
        read_hypotheses(report, rig, logs, [parse_target("input_delay=0.001")])


def test_a_late_step_rival_must_do_that_steps_work_not_ride_on_the_earlier_effects():
    """Three steps (a spring, Coulomb friction, then a lag of 2 ms confusable with a delay of 2 ms): the earlier
    two close most of the nominal gap, so a third candidate that adds nothing (the encoder's grid) still reduces
    the nominal gap within a few points of the lag. It is no rival: only the delay, which removes as much of the
    gap the two leave as the lag does, is paired with the accepted model."""
    from furuta_drake.design.hypotheses import read_hypotheses

    spring = {"arm_spring.stiffness": 0.024, "arm_spring.equilibrium": 0.05, "arm_spring.form": "linear"}
    friction = {
        "arm_coulomb_friction.coulomb": 0.005,
        "arm_coulomb_friction.regularization_velocity": 0.02,
        "arm_coulomb_friction.form": "smooth",
    }

    def entry(third: str, params: dict, over_nominal: float, over_previous: float) -> dict:
        return {
            "effect": f"arm_spring+arm_coulomb_friction+{third}",
            "params": {**spring, **friction, **{f"{third}.{k}": v for k, v in params.items()}},
            "step": 3,
            "status": "ok",
            "heldout_reduction": over_nominal,
            "reduction_over_previous": over_previous,
        }

    ranking = [
        entry("actuator_lag", {"time_constant": 0.002}, 0.99, 0.6),
        entry("input_delay", {"delay": 0.002, "form": "fixed"}, 0.99, 0.59),
        entry("encoder_quantization", {"counts_per_rev": 4096.0}, 0.97, 0.0),
    ]
    report = {
        "ranking": ranking,
        "steps": [{"effect": "arm_spring"}, {"effect": "arm_coulomb_friction"}, {"effect": "actuator_lag"}],
        "detection_limits": [],
    }
    found = read_hypotheses(report, lund_rig(), [])
    assert [h.name for h in found.hypotheses] == [
        "arm_spring+arm_coulomb_friction+actuator_lag",
        "arm_spring+arm_coulomb_friction+input_delay",
    ]
    assert [pair.new for pair in found.pairs] == [("actuator_lag", "input_delay")]
