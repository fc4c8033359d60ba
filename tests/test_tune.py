"""``furuta-drake tune``: the design model with a delay and a lag, the output LQ gain, the loop's margins, the limit
cycle's measurement, and the command's refusals of bad input and of a design no gain makes robust.

Every number an assert compares with comes from the physics of a small system (a double integrator, an
integrator, a sine), not from the code under test."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from scipy.linalg import expm, solve_discrete_are

from furuta_drake.cli import main
from furuta_drake.config import SimulationConfig, dump_config, swingup_config
from furuta_drake.controllers.lqr import LqrParameters, design_lqr
from furuta_drake.plant import make_furuta_plant
from furuta_drake.rig import linearized_hanging, lund_rig
from furuta_drake.tune.design import delayed_model, design_model, output_lqr, spectral_radius
from furuta_drake.tune.limit_cycle import limit_cycle
from furuta_drake.tune.margins import margins
from furuta_drake.yamlio import dump_yaml_dataclass

H = 0.01  # [s] the sample period of the small systems
# A double integrator on [p, v] (states 0 and 2) beside two stable decoupled states (1 and 3), so that the design
# model has the four states the rig's controller feeds back.
A_DOUBLE = np.array([[0.0, 0.0, 1.0, 0.0], [0.0, -1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0], [0.0, 0.0, 0.0, -1.0]])
B_DOUBLE = np.array([[0.0], [0.0], [1.0], [0.0]])
Q = np.diag([1.0, 1.0, 0.1, 1.0])


def test_without_delay_the_output_lq_gain_is_the_riccati_gain():
    model = delayed_model(A_DOUBLE, B_DOUBLE, H, 0.0)
    start = np.array([[1.0, 0.0, 1.0, 0.0]])
    K = output_lqr(model, Q, 1.0, [start])
    # The DARE of the exact double integrator sampled with a held input: p+ = p + h v + h^2/2 u, v+ = v + h u.
    Phi = expm(A_DOUBLE * H)
    Gamma = np.array([[0.0], [0.0], [H], [0.0]])
    Gamma[0, 0] = H**2 / 2
    P = solve_discrete_are(Phi, Gamma, Q, np.array([[1.0]]))
    riccati = np.linalg.solve(1.0 + Gamma.T @ P @ Gamma, Gamma.T @ P @ Phi)
    np.testing.assert_allclose(K, riccati, rtol=1e-4, atol=1e-7)


def test_one_sample_delay_loop_has_the_poles_of_its_characteristic_polynomial():
    model = delayed_model(A_DOUBLE, B_DOUBLE, H, H)
    assert model.size == 5  # one command in flight
    K = output_lqr(model, Q, 1.0, [np.array([[1.0, 0.0, 1.0, 0.0]])])
    k1, k3 = K[0, 0], K[0, 2]
    # u_k acts one sample late: z (z - 1)^2 + k1 (h^2/2 (z - 1) + h^2) + k3 h (z - 1) = 0, times the decoupled
    # stable states' z - e^(-h).
    poly = np.polyadd(
        np.polymul([1.0, 0.0], np.polymul([1.0, -1.0], [1.0, -1.0])), [k1 * H**2 / 2 + k3 * H, k1 * H**2 / 2 - k3 * H]
    )
    expected = np.sort_complex(np.concatenate([np.roots(poly), [math.exp(-H)] * 2]))
    poles = np.sort_complex(np.linalg.eigvals(model.feedback(K)))
    np.testing.assert_allclose(poles, expected, atol=1e-7)
    assert np.max(np.abs(poles)) < 1.0


def test_the_corrected_model_holds_the_commands_in_flight_and_the_lag():
    # 3.5 ms at 1 ms: three whole samples and a fraction, four commands in flight; the lag is one more state.
    config = SimulationConfig.from_rig("lund")
    config.actuator.delay, config.actuator.lag_time_constant = 0.0035, 0.004
    model = design_model(config)
    assert model.size == 4 + 1 + 4
    # The lag's state follows the command at 1 / T: its row of A has -1 / T, so one period multiplies it by e^(-h / T).
    assert model.Phi[4, 4] == pytest.approx(math.exp(-0.001 / 0.004), rel=1e-9)


def test_a_fractional_delay_splits_each_held_command_over_two_samples():
    # An integrator of the arm-torque input, delayed by 1.5 samples: over [k h, (k + 1) h) the input is u_k-2 for
    # the first half and u_k-1 for the second, so p_k+1 = p_k + h/2 (u_k-2 + u_k-1).
    A = np.diag([0.0, -1.0, -1.0, -1.0])
    B = np.array([[1.0], [0.0], [0.0], [0.0]])
    model = delayed_model(A, B, H, 1.5 * H)
    commands = np.random.default_rng(3).normal(size=40)
    s = np.zeros(model.size)
    p = [0.0]
    for u in commands:
        s = model.Phi @ s + model.Gamma[:, 0] * u
        p.append(s[0])
    padded = np.concatenate([[0.0, 0.0], commands])
    exact = np.concatenate([[0.0], np.cumsum(H / 2 * (padded[:-2] + padded[1:-1]))])
    np.testing.assert_allclose(p, exact, atol=1e-12)


def test_the_margins_of_a_sampled_integrator_loop_are_the_analytic_ones():
    # p+ = p + h u, u = -k p: the loop gain k h / (z - 1) loses stability at g k h = 2, and crosses |L| = 1 at
    # 2 sin(theta / 2) = k h with the phase margin pi / 2 - theta / 2.
    k = 20.0
    model = delayed_model(np.diag([0.0, -1.0, -1.0, -1.0]), np.array([[1.0], [0.0], [0.0], [0.0]]), H, 0.0)
    found = margins(model, np.array([k, 0.0, 0.0, 0.0]))
    assert found.gain_high == pytest.approx(2.0 / (k * H), rel=1e-6)
    assert found.gain_db == pytest.approx(20.0 * math.log10(2.0 / (k * H)), rel=1e-6)
    crossover = 2.0 * math.asin(k * H / 2.0)
    assert found.delay_s == pytest.approx(H * (math.pi / 2 - crossover / 2) / crossover, rel=1e-6)


def test_the_delay_margin_is_where_a_delay_in_the_model_destabilises_the_furuta_loop():
    config = SimulationConfig.from_rig("lund")
    K = design_lqr(make_furuta_plant(config.rig), LqrParameters(), period=config.control_period)
    found = margins(design_model(config), K)
    assert found.stable and found.delay_s > 0.01
    A, B = (np.asarray(m) for m in _upright(config))
    for factor, stable in ((0.97, True), (1.03, False)):
        delayed = delayed_model(A, B, config.control_period, factor * found.delay_s)
        assert (spectral_radius(delayed.feedback(K)) < 1.0) == stable
    for gain, stable in ((0.98 * found.gain_low, False), (1.02 * found.gain_low, True)):
        assert (spectral_radius(design_model(config).feedback(gain * K)) < 1.0) == stable


def _upright(config):
    from furuta_drake.tune.design import upright_model

    return upright_model(config)


def test_the_limit_cycle_of_a_noisy_sine_is_its_amplitude_and_frequency():
    period, amplitude, frequency = 0.002, 0.008, 3.7
    time = np.arange(0.0, 12.0, period)
    rng = np.random.default_rng(0)
    drift = 0.002 * time / time[-1]  # a slow drift over the run
    signal = amplitude * np.sin(2 * np.pi * frequency * time + 0.4) + drift + 1e-5 * rng.normal(size=time.size)
    found_amplitude, found_frequency = limit_cycle(signal, period)
    assert found_frequency == pytest.approx(frequency, abs=0.02)
    assert found_amplitude == pytest.approx(amplitude, rel=0.03)


# --- the command line -------------------------------------------------------------------------------------------


def diagnosis_folder(path, effects: dict, params_ci: dict, accepted: list[str]):
    """A diagnosis directory as ``tune`` reads it: the Lund rig file with ``effects`` as fitted_rig.yaml, and a
    report.json accepting ``accepted`` whose model's row has ``params_ci``."""
    path.mkdir(parents=True, exist_ok=True)
    (path / "fitted_rig.yaml").write_text(dump_yaml_dataclass(lund_rig().replace(effects=effects)))
    several = len(accepted) > 1
    params = {(f"{name}.{key}" if several else key): value for name in accepted for key, value in effects[name].items()}
    report = {
        "verdict": accepted[0] if len(accepted) == 1 else "+".join(accepted),
        "effects": accepted,
        "ranking": [{"effect": "+".join(accepted), "params": params, "params_ci": params_ci, "step": len(accepted)}],
    }
    (path / "report.json").write_text(json.dumps(report))
    return path


FRICTION = {"arm_coulomb_friction": {"coulomb": 0.012, "presliding": 0.002, "form": "presliding"}}
FRICTION_CI = {"coulomb": [0.011, 0.013], "presliding": [0.0015, 0.0025]}


@pytest.mark.parametrize(
    "damage, named",
    [
        (lambda d: (d / "report.json").unlink(), "report.json: missing"),
        (lambda d: (d / "report.json").write_text("{not json"), "report.json: not valid JSON"),
        (lambda d: _edit_report(d, lambda r: r.pop("effects")), "report.json: no 'effects' key"),
        (lambda d: _edit_report(d, lambda r: r["ranking"][0].pop("params_ci")), "params_ci: missing"),
        (
            lambda d: _edit_report(d, lambda r: r["ranking"][0]["params_ci"].pop("presliding")),
            "params_ci.presliding: missing",
        ),
        (
            lambda d: _edit_report(d, lambda r: r["ranking"][0]["params_ci"].update(coulomb=[0.02, 0.01])),
            "params_ci.coulomb must be [low, high]",
        ),
        (lambda d: _edit_rig(d, {"input_delay": {"delay": -0.003, "form": "fixed"}}), "effects.input_delay.delay"),
        (lambda d: _edit_rig(d, {}), "fitted_rig.yaml: effects.arm_coulomb_friction: missing"),
        (lambda d: (d / "fitted_rig.yaml").write_text("arm_inertia: [1,\n"), "fitted_rig.yaml"),
    ],
)
def test_bad_input_is_one_line_naming_the_file_and_key(tmp_path, capsys, damage, named):
    directory = diagnosis_folder(tmp_path / "diagnosis", FRICTION, FRICTION_CI, ["arm_coulomb_friction"])
    damage(directory)
    code = main(["tune", "--diagnosis", str(directory), "--out", str(tmp_path / "out")])
    error = capsys.readouterr().err.strip()
    assert code == 2
    assert len(error.splitlines()) == 1 and named in error
    assert not (tmp_path / "out").exists()


def _edit_report(directory, change) -> None:
    report = json.loads((directory / "report.json").read_text())
    change(report)
    (directory / "report.json").write_text(json.dumps(report))


def _edit_rig(directory, effects: dict) -> None:
    rig = yaml.safe_load((directory / "fitted_rig.yaml").read_text())
    rig["effects"] = effects or None
    (directory / "fitted_rig.yaml").write_text(yaml.safe_dump(rig))


def test_a_missing_diagnosis_and_a_full_output_are_refused(tmp_path, capsys):
    assert main(["tune", "--diagnosis", str(tmp_path / "nowhere"), "--out", str(tmp_path / "out")]) == 2
    assert "no such directory" in capsys.readouterr().err
    directory = diagnosis_folder(tmp_path / "diagnosis", FRICTION, FRICTION_CI, ["arm_coulomb_friction"])
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("mine")
    assert main(["tune", "--diagnosis", str(directory), "--out", str(tmp_path / "full")]) == 2
    assert "--force" in capsys.readouterr().err
    assert (tmp_path / "full" / "keep.txt").read_text() == "mine"
    assert main(["tune", "--diagnosis", str(directory), "--out", str(tmp_path / "new"), "--draws", "0"]) == 2
    assert "--draws must be a positive integer" in capsys.readouterr().err
    assert not (tmp_path / "new").exists()


def test_a_design_no_gain_makes_robust_is_refused_with_the_reason(tmp_path, capsys):
    # A 60 ms input delay on the Lund rig: the upright's pole (6.9 rad/s) leaves no state feedback that keeps a
    # delay margin of one sample over the delay's interval.
    effects = {"input_delay": {"delay": 0.06, "form": "fixed"}}
    directory = diagnosis_folder(tmp_path / "diagnosis", effects, {"delay": [0.05, 0.07]}, ["input_delay"])
    code = main(["tune", "--diagnosis", str(directory), "--out", str(tmp_path / "out"), "--workers", "1"])
    error = capsys.readouterr().err
    assert code == 2
    assert "no tuned design is robust over the parameters' 95 % intervals" in error
    assert "input_delay.delay" in error or "stabilises" in error
    assert not (tmp_path / "out").exists()


@pytest.mark.slow
def test_tune_writes_a_controller_that_simulate_runs(tmp_path, monkeypatch, capsys):
    from furuta_drake.config import load_config
    from furuta_drake.tune import pipeline

    monkeypatch.setattr(pipeline, "TuneSettings", lambda: pipeline.FAST)
    directory = diagnosis_folder(tmp_path / "diagnosis", FRICTION, FRICTION_CI, ["arm_coulomb_friction"])
    out = tmp_path / "tuned"
    swingup = tmp_path / "swingup.yaml"
    swingup.write_text(dump_config(swingup_config("lund", duration=6.0)))
    arguments = ["--duration", "1.5", "--workers", "1", "--swingup", str(swingup)]
    assert main(["tune", "--diagnosis", str(directory), "--out", str(out), *arguments]) == 0
    document = json.loads((out / "tune.json").read_text())
    assert document["sample_period"] == 0.001
    assert document["design_model"]["states"] == 4  # no delay, no lag
    assert document["robust_over_intervals"] is True
    for name in ("nominal", "tuned"):
        design = document["designs"][name]
        assert len(design["lqr_gain"]) == 4
        assert set(design["predicted"]) == {
            "theta_rms",
            "phi_rms",
            "limit_cycle_amplitude",
            "limit_cycle_frequency",
            "effort_rms",
        }
        assert design["margins"]["gain_db"] > 0 and design["margins"]["delay_s"] > 0
    tuned = document["designs"]["tuned"]
    if tuned["family_member"] is None:  # the nominal design kept: no member predicted better over the intervals
        assert tuned["lqr_gain"] == document["designs"]["nominal"]["lqr_gain"]
    else:  # with arm friction in the model, every member runs the VFE and the fitted Dahl observer
        assert tuned["observer"]["kind"] == "vfe"
        # The Dahl observer's stiffness is the fitted level over the fitted presliding displacement.
        assert tuned["observer"]["dahl"]["sigma0"] == pytest.approx(0.012 / 0.002)
    assert set(tuned["friction_compensation"]) >= {"arm_coulomb", "gain"}
    # The swing-up configured: each design's gain behind it catches, no sooner than half a hanging swing.
    half_swing = math.pi / np.max(np.abs(np.linalg.eigvals(linearized_hanging(lund_rig())[0])))
    for name in ("nominal", "tuned"):
        catch = document["swingup"]["designs"][name]["at_fit"]["catch_time_s"]
        assert catch is not None and half_swing < catch < 6.0
    assert "Swing-up catch time" in (out / "tune.md").read_text()
    for name in ("controller.yaml", "nominal.yaml", "tune.md", "tune.html", "balancing.png", "config.yaml"):
        assert (out / name).is_file()
    assert "data:image/png;base64," in (out / "tune.html").read_text()
    config = load_config(out / "controller.yaml")
    assert config.controller.gain == pytest.approx(tuned["lqr_gain"])
    assert config.friction.arm.coulomb_pos == pytest.approx(0.012)
    capsys.readouterr()
    run = tmp_path / "run"
    assert main(["simulate", "--config", str(out / "controller.yaml"), "--duration", "0.5", "--out", str(run)]) == 0
    assert (run / "log.csv").is_file()


def test_a_drive_effect_is_read_from_the_drive_section_and_a_bound_parameter_is_held(tmp_path):
    from furuta_drake.rig import DriveParameters
    from furuta_drake.tune.inputs import corner_rig, read_diagnosis

    drive = DriveParameters(gear_ratio=30.0, rotor_inertia=1e-6, stiffness=0.5, damping=0.02)
    directory = tmp_path / "diagnosis"
    directory.mkdir()
    (directory / "fitted_rig.yaml").write_text(dump_yaml_dataclass(lund_rig().replace(drive=drive)))
    row = {
        "effect": "drive_compliance",
        "params": {"stiffness": 0.5, "damping": 0.02},
        "params_ci": {"damping": [0.01, 0.03]},  # the stiffness fitted at its bound has none
        "at_bound": {"stiffness": "upper"},
        "step": 1,
    }
    report = {"verdict": "drive_compliance", "effects": ["drive_compliance"], "ranking": [row]}
    (directory / "report.json").write_text(json.dumps(report))
    inputs = read_diagnosis(directory)
    assert inputs.accepted["drive_compliance"].values == (0.5, 0.02)  # the drive section's keys
    assert inputs.intervals[("drive_compliance", "stiffness")] == (0.5, 0.5)
    assert inputs.intervals[("drive_compliance", "damping")] == (0.01, 0.03)
    assert any("stiffness" in note and "held at its fit" in note for note in inputs.notes)
    corner = corner_rig(inputs, {("drive_compliance", "damping"): 0.03})
    assert corner.drive.damping == 0.03 and corner.drive.stiffness == 0.5
    assert "drive_compliance" not in (corner.effects or {})


def test_an_interval_reaching_a_non_physical_rig_is_refused_naming_the_corner(tmp_path, capsys):
    # b = J_p + m l^2 scaled by 0.2 leaves less than m l^2: a negative pendulum inertia at the low corner
    scales = {"arm_inertia_scale": 1.0, "pendulum_inertia_scale": 1.0, "coupling_scale": 1.0, "gravity_scale": 1.0}
    intervals = {key: [0.95, 1.05] for key in scales} | {"pendulum_inertia_scale": [0.2, 1.1]}
    directory = diagnosis_folder(tmp_path / "d", {"inertia_mismatch": scales}, intervals, ["inertia_mismatch"])
    assert main(["tune", "--diagnosis", str(directory), "--out", str(tmp_path / "out")]) == 2
    message = capsys.readouterr().err
    assert "not physical at the intervals' corner" in message and "pendulum_inertia_scale low" in message
    assert "rig.pendulum_inertia" in message and not (tmp_path / "out").exists()
