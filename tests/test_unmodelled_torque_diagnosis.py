"""The torque beyond the vocabulary on the diagnosis side: the term library in the surrogate's kernel, the sparse
regression on known injected torques, the report's expression, and report.json with and without the key."""

import json
import re
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.diagnosis.gap.metric import evaluate_gap, make_windows
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.diagnosis.report.tables import unmodelled_sentence
from furuta_drake.diagnosis.report.torque import torque_record
from furuta_drake.diagnosis.result import Diagnosis
from furuta_drake.diagnosis.selection.missing_torque import find_missing_torque, stand_ins
from furuta_drake.diagnosis.selection.rule import Bootstrap
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.effects.surrogate import HISTORY, REGULARIZATION_VELOCITY, Model, predict_windows
from furuta_drake.effects.torque_library import TERMS, term_value, term_values
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.rig import RIGS
from furuta_drake.unmodelled import FUNCTIONS, TORQUE_VARIABLES, compile_torque

QUBE = RIGS["qube_servo2"]()
NOMINAL = Model.from_rig(QUBE)
PERIOD = 2e-3
SETTINGS = DiagnosisSettings(bootstrap=400, interval_resamples=200)


def surrogate_log(model: Model, seconds: float, seed: int) -> RunLog:
    """A hanging run of ``model`` under random torque steps (0.2 s each), read through the rig's encoder."""
    rng = np.random.default_rng(seed)
    n = int(seconds / PERIOD)
    command = np.repeat(rng.uniform(-0.6, 0.6, n // 100 + 1), 100)[:n] * QUBE.torque_limit
    x0 = np.array([[np.pi], [0.0], [0.0], [0.0]])
    padded = np.concatenate([np.zeros(HISTORY), command])
    angles = predict_windows(model, x0, padded, np.array([HISTORY]), n, PERIOD, 2)[:, :, 0]
    step = 2 * np.pi / QUBE.counts_per_rev
    angles = np.round(angles / step) * step
    return RunLog(f"run{seed}.csv", "", np.arange(n) * PERIOD, angles[:, 0], angles[:, 1], "torque", command, PERIOD)


def missing_torque_of(truth: Model, final: Model):
    """The torque ``final`` misses on logs of ``truth`` (two 4 s train runs, one 3 s held-out run)."""
    train = make_windows([surrogate_log(truth, 4.0, 1), surrogate_log(truth, 4.0, 2)], QUBE)
    heldout = make_windows([surrogate_log(truth, 3.0, 3)], QUBE)
    counts = QUBE.counts_per_rev
    nominal = evaluate_gap(NOMINAL, heldout, counts).per_window
    reference = evaluate_gap(final, heldout, counts).per_window
    bootstrap = Bootstrap(heldout.count, SETTINGS.bootstrap, SETTINGS.seed)
    return find_missing_torque(final, nominal, reference, train, heldout, counts, bootstrap, SETTINGS)


@settings(max_examples=40, deadline=None)
@given(
    st.integers(0, len(TERMS) - 1),
    st.floats(-4, 4),
    st.floats(-4, 4),
    st.floats(-30, 30),
    st.floats(-30, 30),
)
def test_kernel_terms_are_the_expressions(index, theta, phi, theta_dot, phi_dot):
    """The kernel's compiled library gives every term's printed numpy expression at any state."""
    expected = term_values(theta, phi, theta_dot, phi_dot)[index]
    assert term_value(index, theta, phi, theta_dot, phi_dot) == pytest.approx(float(expected), rel=1e-12, abs=1e-12)


def test_a_constant_arm_torque_is_the_same_as_a_command_offset():
    """A constant unmodelled arm torque c acts exactly as c added to the command (both are generalised forces on
    phi); without terms the predictions are the model's own."""
    rng = np.random.default_rng(4)
    command = rng.uniform(-0.05, 0.05, 400)
    x0 = rng.normal(0, 0.3, (4, 5)) + np.array([[np.pi], [0], [0], [0]])
    starts = HISTORY + np.arange(5) * 20
    c = 0.004
    with_term = NOMINAL.replace(unmodelled_terms=((0, TERMS.index("1"), c),))
    shifted = predict_windows(NOMINAL, x0, command + c, starts, 60, PERIOD, 2)
    np.testing.assert_allclose(predict_windows(with_term, x0, command, starts, 60, PERIOD, 2), shifted, atol=1e-12)
    assert np.max(np.abs(predict_windows(NOMINAL, x0, command, starts, 60, PERIOD, 2) - shifted)) > 1e-3


@pytest.fixture(scope="module")
def cogging():
    """A cogging torque of 10 % of m g l varying as sin(7 phi) on the arm, missed by the nominal model."""
    truth = NOMINAL.replace(unmodelled_terms=((0, TERMS.index("sin(7*phi)"), 0.1 * NOMINAL.gravity_torque),))
    return truth, missing_torque_of(truth, NOMINAL)


def test_regression_recovers_an_injected_cogging_torque_with_its_interval(cogging):
    truth, missing = cogging
    assert missing is not None and missing.kept
    (joint, term, coefficient), (low, high) = missing.terms[0], missing.intervals[0]
    assert (joint, TERMS[term]) == (0, "sin(7*phi)")
    assert low <= truth.unmodelled_terms[0][2] <= high
    assert coefficient == pytest.approx(truth.unmodelled_terms[0][2], rel=0.05)
    # what is left is the sensor: the held-out gap falls to below a tenth of the nominal one
    assert missing.over_nominal.reduction > 0.9


def test_report_expression_evaluates_to_the_fitted_torque(cogging):
    _, missing = cogging
    record = torque_record(missing)
    assert set(record) == {"arm"}
    entry = record["arm"]
    scatter = missing.scatter["arm"]
    torque = compile_torque(entry["expression"], "report.unmodelled_torque.arm.expression")
    np.testing.assert_allclose(torque(*scatter["state"]), scatter["fitted"], rtol=1e-5, atol=1e-12)
    assert set(re.findall(r"[a-z_]+", entry["expression"])) <= set(TORQUE_VARIABLES) | set(FUNCTIONS) | {"pi"}
    assert "position-periodic" in unmodelled_sentence("arm", entry)


def test_on_a_coulomb_only_rig_nothing_is_claimed_beyond_the_friction():
    """With the rig's arm Coulomb friction in the final model the torque claims nothing; left out, the torque
    found has the friction's shape and is named after it."""
    level = 0.05 * NOMINAL.gravity_torque
    friction = JointFrictionParameters(
        model="static", coulomb_pos=level, coulomb_neg=level, regularization_velocity=REGULARIZATION_VELOCITY
    )
    truth = NOMINAL.replace(arm_friction=friction)
    beside = missing_torque_of(truth, truth)
    assert beside is None or not beside.kept
    missing = missing_torque_of(truth, NOMINAL)
    assert missing is not None and missing.kept
    assert torque_record(missing)["arm"]["closest_effect"] == "arm_coulomb_friction"


def test_an_inertia_three_times_the_rig_files_is_a_stand_in():
    from furuta_drake.diagnosis.selection.fit import FitResult
    from furuta_drake.effects.vocabulary import Effect

    heavy = FitResult("inertia_mismatch", {"inertia_mismatch": Effect("", (3.0, 1.0, 1.0, 1.0))}, 1.0, None)
    plausible = FitResult("inertia_mismatch", {"inertia_mismatch": Effect("", (1.3, 1.0, 1.0, 1.0))}, 1.0, None)
    bounded = FitResult("arm_spring", {"arm_spring": Effect("", (0.1,))}, 1.0, None, at_bounds=["arm_spring.k (upper)"])
    assert stand_ins(heavy) == ["inertia_mismatch"]
    assert stand_ins(plausible) == []
    assert stand_ins(bounded) == ["arm_spring"]


def test_an_old_report_without_the_key_reads_and_writes_without_it():
    data = json.loads((Path(__file__).parent / "data" / "report_before_v2.json").read_text())
    diagnosis = Diagnosis.from_json(data)
    assert diagnosis.unmodelled_torque == {}
    assert "unmodelled_torque" not in diagnosis.to_json()


def test_a_report_with_the_key_round_trips(cogging):
    data = json.loads((Path(__file__).parent / "data" / "report_before_v2.json").read_text())
    record = torque_record(cogging[1])
    data["unmodelled_torque"] = json.loads(json.dumps(record))
    assert Diagnosis.from_json(data).to_json()["unmodelled_torque"] == data["unmodelled_torque"]


@pytest.mark.slow
def test_a_drake_rig_with_cogging_is_diagnosed_with_it_and_the_fitted_model_carries_it(tmp_path):
    """Logs of a Drake world with a cogging torque -0.1 m g l sin(7 phi) on the arm (the simulate config's
    unmodelled torque): the report gives it back, and fitted_model.yaml and fitted_rig.yaml carry the expression."""
    import dataclasses

    from benchmarks.diagnosis.suite import run_configs
    from furuta_drake.config import SimulationConfig
    from furuta_drake.diagnosis.pipeline import diagnose
    from furuta_drake.diagnosis.report.files import write_report
    from furuta_drake.diagnosis.settings import FAST
    from furuta_drake.results import write_log_csv
    from furuta_drake.rig import lund_rig
    from furuta_drake.simulate import simulate
    from furuta_drake.unmodelled import UnmodelledTorqueParameters
    from furuta_drake.yamlio import dump_yaml_dataclass, load_yaml_dataclass

    rig = lund_rig()
    amplitude = 0.1 * Model.from_rig(rig).gravity_torque
    (tmp_path / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    for name, seed in (("train.csv", 11), ("heldout.csv", 12)):
        config = dataclasses.replace(
            run_configs(rig, seed, 4.0)["hanging"],
            unmodelled_torque=UnmodelledTorqueParameters(arm=f"{-amplitude!r}*sin(7*phi)"),
        )
        write_log_csv(simulate(config), tmp_path / name)
    diagnosis = diagnose(
        rig=tmp_path / "rig.yaml",
        train=[tmp_path / "train.csv"],
        heldout=[tmp_path / "heldout.csv"],
        workers=1,
        settings=dataclasses.replace(FAST, replay=False),
    )
    write_report(tmp_path / "out", diagnosis)
    report = json.loads((tmp_path / "out" / "report.json").read_text())
    arm = report["unmodelled_torque"]["arm"]
    lead = max(arm["terms"], key=lambda t: abs(t["coefficient"]))
    assert lead["term"] == "sin(7*phi)"
    assert lead["coefficient"] == pytest.approx(-amplitude, rel=0.2)
    assert (tmp_path / "out" / arm["plot"]).stat().st_size > 0
    fitted = load_yaml_dataclass(tmp_path / "out" / "fitted_model.yaml", SimulationConfig)
    assert fitted.unmodelled_torque.arm == arm["expression"]
    rig_file = load_yaml_dataclass(tmp_path / "out" / "fitted_rig.yaml", type(rig))
    assert rig_file.unmodelled_torque.arm == arm["expression"]
