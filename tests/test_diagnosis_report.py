"""The diagnosis' output directory: the contract's keys and types, byte-identical JSON, atomic writes, plots,
provenance, and report.json as the serialised Diagnosis (old reports read too)."""

import copy
import hashlib
import json
import math

import numpy as np
import pytest
import yaml

import furuta_drake.diagnosis.report.files as report_module
from furuta_drake.diagnosis.gap.localize import localize
from furuta_drake.diagnosis.logs.load import WindowResiduals
from furuta_drake.diagnosis.report.files import (
    check_report,
    effect_curve,
    input_record,
    report_json,
    residual_psd,
    write_report,
)
from furuta_drake.diagnosis.result import Artifacts, Diagnosis
from furuta_drake.errors import ConfigError
from furuta_drake.outputs import atomic_output_dir
from furuta_drake.rig import RigParameters, lund_rig
from furuta_drake.yamlio import loads_yaml_dataclass

DT = 0.001


def windows(amplitude, log="heldout_1.csv", n_windows=12, seed=0):
    rng = np.random.default_rng(seed)
    out = []
    for k in range(n_windows):
        t = (k * 200 + np.arange(200)) * DT
        residual = np.column_stack([amplitude * np.sin(2 * math.pi * 20 * t), amplitude * np.sign(np.sin(t))])
        residual += rng.uniform(-0.5, 0.5, residual.shape)
        state = np.column_stack([0.1 * np.sin(t), 0 * t, 0 * t, np.cos(2 * t)])
        out.append(WindowResiduals(log, t, residual, state, 0.01 * np.ones_like(t), np.zeros(len(t), bool)))
    return out


@pytest.fixture
def inputs(tmp_path):
    before, after = windows(4.0), windows(0.5, seed=1)
    report = {
        "verdict": "arm_coulomb_friction",
        "effects": ["arm_coulomb_friction"],
        "gap": {
            "metric": "rms 0.2 s-ahead prediction error beyond the encoder noise [counts]",
            "nominal": {"train": 3.1, "heldout": np.float64(3.3)},
            "with_effects": {"train": 0.4, "heldout": 0.5},
            "heldout_reduction": 1 - 0.5 / 3.3,
        },
        "ranking": [
            {
                "effect": "arm_coulomb_friction",
                "params": {"coulomb": np.float64(0.0151234567)},
                "heldout_gap": 0.5,
                "heldout_reduction": 0.848,
                "evidence": 12.0,
            },
            {
                "effect": "input_delay",
                "params": {"delay": 0.004},
                "heldout_gap": float("inf"),
                "heldout_reduction": -0.2,
                "evidence": 0.1,
            },
        ],
        "localization": localize(before, after),
    }
    logs = []
    for name in ("train_1.csv", "heldout_1.csv"):
        path = tmp_path / "inputs" / name
        path.parent.mkdir(exist_ok=True)
        path.write_text(f"time,theta,phi,torque\n0,0,0,{len(name)}\n")
        logs.append(path)
    rig_path = tmp_path / "inputs" / "rig.yaml"
    rig_path.write_text("arm_length: 0.25\n")
    record = input_record(
        rig_path=rig_path, train=logs[:1], heldout=logs[1:], seeds={"fit": 7}, options={"horizon_s": 0.2}
    )
    rig = lund_rig()
    artifacts = Artifacts(
        before,
        after,
        1.0 / 12.0,
        [effect_curve("arm_coulomb_friction", {"coulomb": 0.0151, "presliding": 0.002}, rig)],
        fitted_config=rig.replace(arm_coulomb=0.0151),
        fitted_rig=rig.replace(effects={"arm_coulomb_friction": {"coulomb": 0.0151, "presliding": 0.002}}),
        record=record,
    )
    diagnosis = Diagnosis.from_json(
        {
            **report,
            "rule": "lower 95 % bootstrap bound of the held-out reduction above 5 %",
            "holdout": "the --heldout logs",
        }
    )
    diagnosis.artifacts = artifacts
    return dict(report=report, diagnosis=diagnosis), logs + [rig_path]


def test_report_json_round_trips_through_the_diagnosis_and_reads_an_old_report(inputs):
    """report.json is Diagnosis.to_json; from_json gives the same Diagnosis back; a report written before the
    later keys (steps, params_ci, detection_limits, ...) reads with those empty and every old key intact."""
    from pathlib import Path

    kwargs, _ = inputs
    text = report_json(kwargs["diagnosis"].to_json())
    again = report_json(Diagnosis.from_json(json.loads(text)).to_json())
    assert again == text
    old = json.loads((Path(__file__).parent / "data" / "report_before_v2.json").read_text())
    diagnosis = Diagnosis.from_json(old)
    assert diagnosis.verdict == old["verdict"] and diagnosis.effects == old["effects"]
    assert diagnosis.steps == [] and diagnosis.detection_limits == [] and diagnosis.consistency is None
    assert [entry.effect for entry in diagnosis.ranking] == [entry["effect"] for entry in old["ranking"]]
    assert diagnosis.ranking[0].params == old["ranking"][0]["params"]
    new = json.loads(report_json(diagnosis.to_json()))
    for key in ("verdict", "effects", "localization"):
        assert new[key] == old[key]
    assert new["gap"]["nominal"] == old["gap"]["nominal"]


def test_report_json_has_the_spec_keys_and_types(inputs):
    kwargs, _ = inputs
    data = json.loads(report_json(kwargs["report"]))
    assert list(data)[:5] == ["verdict", "effects", "gap", "ranking", "localization"]
    assert set(data) == {"verdict", "effects", "gap", "ranking", "localization"}
    assert set(data["gap"]) == {"metric", "nominal", "with_effects", "heldout_reduction"}
    assert set(data["gap"]["nominal"]) == set(data["gap"]["with_effects"]) == {"train", "heldout"}
    assert all(
        set(entry) == {"effect", "params", "heldout_gap", "heldout_reduction", "evidence"} for entry in data["ranking"]
    )
    loc = data["localization"]
    assert {"signals", "windows", "regimes", "frequency_bands"} <= set(loc)
    assert set(loc["signals"]) == {"theta", "phi"}
    assert all({"log", "start", "end", "why"} <= set(w) for w in loc["windows"]) and loc["windows"]
    assert all({"regime", "share_of_gap"} <= set(r) for r in loc["regimes"])
    assert all({"low_hz", "high_hz", "share_of_gap"} <= set(b) for b in loc["frequency_bands"])
    assert type(data["gap"]["nominal"]["heldout"]) is float  # numpy scalars become plain floats
    assert data["ranking"][0]["params"]["coulomb"] == 0.0151235  # 6 significant digits
    assert data["ranking"][1]["heldout_gap"] is None  # a non-finite figure is null, never NaN/Infinity


@pytest.mark.parametrize(
    "damage, message",
    [
        (lambda r: r.pop("verdict"), "missing 'verdict'"),
        (lambda r: r["gap"].pop("with_effects"), "missing 'with_effects'"),
        (lambda r: r["gap"]["nominal"].update(train="3.1"), "gap.nominal.train must be a number"),
        (lambda r: r["ranking"][0]["params"].update(coulomb="big"), "params.coulomb must be a number"),
        (lambda r: r["localization"]["windows"][0].pop("why"), "missing 'why'"),
        (lambda r: r["localization"].update(regimes={}), "localization.regimes must be a list"),
    ],
)
def test_check_report_names_what_is_wrong(inputs, damage, message):
    report = copy.deepcopy(inputs[0]["report"])
    damage(report)
    with pytest.raises(ValueError, match=message):
        check_report(report)


def test_same_inputs_give_byte_identical_files(inputs, tmp_path):
    kwargs, protect = inputs
    first = write_report(tmp_path / "a", kwargs["diagnosis"], protect=protect)
    second = write_report(tmp_path / "b", copy.deepcopy(kwargs["diagnosis"]), protect=protect)
    names = sorted(p.name for p in first.iterdir())
    assert names == sorted(p.name for p in second.iterdir())
    for name in names:
        assert (first / name).read_bytes() == (second / name).read_bytes(), name


def test_directory_contents_plots_and_provenance(inputs, tmp_path):
    kwargs, protect = inputs
    out = write_report(tmp_path / "out", kwargs["diagnosis"], protect=protect)
    assert sorted(p.name for p in out.iterdir()) == [
        "config.yaml",
        "effect_arm_coulomb_friction.png",
        "fitted_model.yaml",
        "fitted_rig.yaml",
        "gap.svg",
        "localization.svg",
        "report.html",
        "report.json",
        "report.md",
        "residual_spectra.png",
        "residuals.png",
        "windows.svg",
    ]
    for chart in out.glob("*.svg"):
        assert chart.read_text().startswith("<svg") and "<text" in chart.read_text()
    for png in out.glob("*.png"):
        data = png.read_bytes()
        assert data[:8] == b"\x89PNG\r\n\x1a\n" and len(data) > 5000
    markdown = (out / "report.md").read_text()
    for needle in (
        "`arm_coulomb_friction`",
        "](residuals.png)",
        "](residual_spectra.png)",
        "](effect_arm_coulomb_friction.png)",
        "lower 95 % bootstrap bound",
        "rms 0.2 s-ahead",
        "| 1 | arm_coulomb_friction | coulomb = 15.1 mN m |",
        "arm velocity reversal",
        "85 %",
    ):
        assert needle in markdown
    record = yaml.safe_load((out / "config.yaml").read_text())
    for entry in record["train"] + record["heldout"] + [record["rig"]]:
        assert entry["sha256"] == hashlib.sha256(open(entry["path"], "rb").read()).hexdigest()
    assert record["versions"]["numpy"] == np.__version__ and record["seeds"] == {"fit": 7}
    fitted = loads_yaml_dataclass((out / "fitted_model.yaml").read_text(), RigParameters)
    assert fitted.arm_coulomb == 0.0151 and fitted == lund_rig().replace(arm_coulomb=0.0151)
    continued = loads_yaml_dataclass((out / "fitted_rig.yaml").read_text(), RigParameters)
    assert continued.effects == {"arm_coulomb_friction": {"coulomb": 0.0151, "presliding": 0.002}}
    html = (out / "report.html").read_text()
    assert "arm_coulomb_friction" in html and "data:image/png;base64," in html


def test_a_writer_failing_midway_leaves_no_directory(inputs, tmp_path, monkeypatch):
    kwargs, protect = inputs

    def broken(*args, **kwargs):
        raise RuntimeError("disk full")

    monkeypatch.setattr(report_module, "plot_spectra", broken)
    before = sorted(p.name for p in tmp_path.iterdir())
    with pytest.raises(RuntimeError, match="disk full"):
        write_report(tmp_path / "out", kwargs["diagnosis"], protect=protect)
    assert sorted(p.name for p in tmp_path.iterdir()) == before  # neither out nor a staging directory


def test_non_empty_output_needs_force_and_force_replaces_only_when_complete(inputs, tmp_path, monkeypatch):
    kwargs, protect = inputs
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("previous run")
    with pytest.raises(ConfigError, match="not empty; pass --force"):
        write_report(out, kwargs["diagnosis"], protect=protect)
    monkeypatch.setattr(report_module, "plot_residuals", lambda *a: (_ for _ in ()).throw(RuntimeError("x")))
    with pytest.raises(RuntimeError):
        write_report(out, kwargs["diagnosis"], force=True, protect=protect)
    assert sorted(p.name for p in out.iterdir()) == ["old.txt"]  # the failed run left the old results
    monkeypatch.undo()
    write_report(out, kwargs["diagnosis"], force=True, protect=protect)
    assert not (out / "old.txt").exists() and (out / "report.json").exists()
    assert sorted(p.name for p in tmp_path.iterdir()) == ["inputs", "out"]


def test_force_never_deletes_the_inputs(inputs, tmp_path):
    kwargs, protect = inputs
    with pytest.raises(ConfigError, match="--force would delete"):
        write_report(tmp_path / "inputs", kwargs["diagnosis"], force=True, protect=protect)
    assert all(p.exists() for p in protect)


def test_empty_existing_directory_is_used(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    with atomic_output_dir(out) as staging:
        (staging / "x.txt").write_text("1")
    assert (out / "x.txt").read_text() == "1"


def test_white_residual_psd_is_twice_the_variance_times_the_period():
    rng = np.random.default_rng(0)
    sigma = 1.5
    ws = []
    for k in range(200):
        t = (k * 250 + np.arange(250)) * DT
        ws.append(
            WindowResiduals(
                "w.csv", t, rng.normal(0, sigma, (250, 2)), np.zeros((250, 4)), np.zeros(250), np.zeros(250, bool)
            )
        )
    centers, density = residual_psd(ws)
    assert centers[0] > 0 and centers[-1] < 500 and np.all(np.diff(centers) > 0)
    np.testing.assert_allclose(density[4:], 2 * sigma**2 * DT, rtol=0.25)  # bins wide enough to average
    assert np.mean(density) == pytest.approx(2 * sigma**2 * DT, rel=0.1)


def test_effect_curves_follow_the_effect_laws():
    rig = lund_rig().replace(arm_viscous=0.001)
    stribeck = {"coulomb": 0.01, "static": 0.02, "stribeck_velocity": 0.1, "presliding": 0.001}
    friction = effect_curve("arm_stribeck", stribeck, rig)
    v = np.asarray(friction.x)
    fitted = friction.curves["fitted"]
    assert fitted[v > 0][0] == pytest.approx(0.02, rel=2e-3)  # the static level as the arm starts to slide
    assert fitted[np.argmin(np.abs(v - 2.0))] == pytest.approx(0.01 + 0.001 * 2.0, rel=1e-6)  # Coulomb + viscous
    assert friction.curves["nominal"][np.argmin(np.abs(v - 2.0))] == pytest.approx(0.002)
    asym = effect_curve("friction_asymmetry", {"coulomb_pos": 0.02, "coulomb_neg": 0.005, "presliding": 0.001}, rig)
    assert asym.curves["fitted"][0] == pytest.approx(-0.005 - 0.002)
    dead = effect_curve("actuator_deadzone", {"deadzone": 0.05}, rig)
    u = np.asarray(dead.x)
    assert np.all(dead.curves["fitted"][np.abs(u) < 0.05] == 0)
    assert dead.curves["fitted"][-1] == pytest.approx(1.2 * rig.torque_limit - 0.05)
    lag = effect_curve("actuator_lag", {"time_constant": 0.02}, rig)
    t = np.asarray(lag.x)
    assert lag.curves["fitted"][np.argmin(np.abs(t - 0.02))] == pytest.approx(1 - math.exp(-1), abs=2e-3)
    spring = effect_curve("arm_spring", {"stiffness": 0.1, "equilibrium": 0.2}, rig)
    phi = np.asarray(spring.x)
    assert spring.curves["fitted"][np.argmin(np.abs(phi - 1.2))] == pytest.approx(-0.1, abs=1e-3)
    scales = {"arm_inertia_scale": 1.3, "pendulum_inertia_scale": 1.0, "coupling_scale": 1.0, "gravity_scale": 0.9}
    bars = effect_curve("inertia_mismatch", scales, rig)
    assert bars.bars and list(bars.x) == list(scales) and list(bars.curves["fitted"]) == list(scales.values())
