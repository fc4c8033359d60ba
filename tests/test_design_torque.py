"""``design`` with a diagnosis that kept an unmodelled torque: the torque in every hypothesis, refit by the
criterion, ``--target unmodelled_torque=SIZE`` (its RMS along the train logs), and bad targets refused."""

from __future__ import annotations

import dataclasses
import hashlib
import json

import numpy as np
import pytest
import yaml

from benchmarks.diagnosis.suite import run_configs
from furuta_drake.cli import main
from furuta_drake.design.criterion import Parametrised, experiment_windows, linearised_noncentrality
from furuta_drake.design.family import BANDS, Family
from furuta_drake.design.hypotheses import parse_target, read_hypotheses
from furuta_drake.design.rollout import surrogate_runs
from furuta_drake.design.torque_hypothesis import TORQUE, apply_hypothesis, report_torque
from furuta_drake.diagnosis.logs.load import load_logs
from furuta_drake.effects.surrogate import sensor_variance
from furuta_drake.effects.torque_library import TERMS
from furuta_drake.effects.vocabulary import Effect, Scales, rig_model
from furuta_drake.errors import ConfigError
from furuta_drake.results import write_log_csv
from furuta_drake.rig import lund_rig
from furuta_drake.simulate import simulate
from furuta_drake.unmodelled import UnmodelledTorqueParameters
from furuta_drake.yamlio import dump_yaml_dataclass

RIG = lund_rig()
NOMINAL = rig_model(RIG)
AMPLITUDE = 0.1 * NOMINAL.gravity_torque  # the cogging torque's [N m]
DELAY = 0.003


def torque_entry(coefficient: float) -> dict:
    return {
        "arm": {
            "expression": f"{coefficient!r}*sin(7*phi)",
            "terms": [{"term": "sin(7*phi)", "coefficient": coefficient, "ci": [1.1 * coefficient, 0.9 * coefficient]}],
            "heldout_reduction": 0.9,
            "closest_effect": None,
            "plot": "unmodelled_torque_arm.png",
        }
    }


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    """A Lund rig file and two 2 s hanging logs of it with a cogging torque -0.1 m g l sin(7 phi) on the arm."""
    root = tmp_path_factory.mktemp("torque_case")
    (root / "rig.yaml").write_text(dump_yaml_dataclass(RIG))
    for name, seed in (("train.csv", 3), ("heldout.csv", 4)):
        config = dataclasses.replace(
            run_configs(RIG, seed, 2.0)["hanging"],
            unmodelled_torque=UnmodelledTorqueParameters(arm=f"{-AMPLITUDE!r}*sin(7*phi)"),
        )
        write_log_csv(simulate(config), root / name)
    return root


def report_of(torque: dict | None, rival: bool) -> dict:
    """A report whose verdict is an input delay (with an actuator lag confusable at step 1 when ``rival``), or
    none, with ``torque`` as its unmodelled torque."""
    entry = {"step": 1, "status": "ok", "heldout_reduction": 0.9, "reduction_over_previous": 0.9}
    ranking = [{"effect": "input_delay", "params": {"delay": DELAY}, **entry}] if rival else []
    ranking += [{"effect": "actuator_lag", "params": {"time_constant": DELAY}, **entry}] if rival else []
    report = {
        "verdict": "input_delay" if rival else "none",
        "effects": ["input_delay"] if rival else [],
        "ranking": ranking,
        "steps": [{"effect": "input_delay"}] if rival else [],
        "detection_limits": [],
        "confusable": [{"effects": ["input_delay", "actuator_lag"], "why": "built to be"}] if rival else [],
    }
    return {**report, TORQUE: torque} if torque else report


def write_diagnosis(directory, case, report: dict) -> None:
    directory.mkdir()

    def entry(path):
        return {"path": str(path), "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}

    (directory / "report.json").write_text(json.dumps(report))
    record = {"rig": entry(case / "rig.yaml"), "train": [entry(case / "train.csv")]}
    (directory / "config.yaml").write_text(yaml.safe_dump({**record, "heldout": [entry(case / "heldout.csv")]}))


def test_the_kept_torque_is_in_every_hypothesis_and_its_pairs_previous_model(case):
    logs = load_logs([case / "train.csv"], RIG)
    found = read_hypotheses(report_of(torque_entry(-AMPLITUDE), rival=True), RIG, logs)
    assert [h.name for h in found.hypotheses] == [f"input_delay+{TORQUE}", f"actuator_lag+{TORQUE}"]
    for hypothesis in found.hypotheses:
        assert hypothesis.model.unmodelled_terms == ((0, TERMS.index("sin(7*phi)"), -AMPLITUDE),)
    assert TORQUE in found.pairs[0].previous


def test_a_torque_target_is_the_torque_scaled_to_that_rms_along_the_train_logs(case):
    """The target's sin(7 phi) coefficient c gives |c| sqrt(mean sin^2(7 phi)) = SIZE along the train log."""
    logs = load_logs([case / "train.csv"], RIG)
    size = 2e-4
    found = read_hypotheses(
        report_of(torque_entry(-AMPLITUDE), rival=False), RIG, logs, [parse_target(f"{TORQUE}={size}")]
    )
    assert [h.name for h in found.hypotheses] == ["nominal", TORQUE]
    assert found.hypotheses[0].model.unmodelled_terms == ()
    ((joint, term, coefficient),) = found.hypotheses[1].model.unmodelled_terms
    assert (joint, TERMS[term]) == (0, "sin(7*phi)") and coefficient < 0
    assert abs(coefficient) * np.sqrt(np.mean(np.sin(7 * logs[0].phi) ** 2)) == pytest.approx(size, rel=1e-9)
    pair = found.pairs[0]
    assert pair.nested and pair.new == ("", TORQUE)


@pytest.mark.parametrize(
    "torque, target, fragment",
    [
        (True, f"{TORQUE}=-0.001", f"--target '{TORQUE}=-0.001': the size must be a positive number"),
        (True, f"{TORQUE}=big", "'big' is not a number"),
        (False, f"{TORQUE}=0.001", "the diagnosis kept no unmodelled torque to target"),
    ],
)
def test_a_bad_torque_target_exits_2_naming_it(case, tmp_path, capsys, torque, target, fragment):
    write_diagnosis(tmp_path / "d", case, report_of(torque_entry(-AMPLITUDE) if torque else None, rival=False))
    args = ["design", "--diagnosis", str(tmp_path / "d"), "--out", str(tmp_path / "out"), "--target", target]
    assert main(args) == 2
    assert fragment in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_a_report_torque_outside_the_library_is_refused_naming_the_entry():
    bad = torque_entry(1e-3)
    bad["arm"]["terms"][0]["term"] = "sin(7.5*phi)"
    with pytest.raises(ConfigError, match=rf"{TORQUE}\.arm\.terms\[0\]: expected a term of the torque library"):
        report_torque({TORQUE: bad})


def noncentrality(truth: dict, rival: dict, command: np.ndarray) -> float:
    """lambda (docs/design.md) of a hanging experiment with ``command`` on the Lund rig, ``truth`` generating it."""
    truth_model = apply_hypothesis(NOMINAL, truth)
    train, heldout = experiment_windows(
        surrogate_runs(truth_model, command, RIG.sample_period), command, RIG.sample_period, RIG
    )
    scales = Scales(
        torque=NOMINAL.gravity_torque,
        command=RIG.torque_limit,
        arm_inertia=NOMINAL.arm_inertia_total,
        pendulum_inertia=NOMINAL.pendulum_inertia_total,
        period=RIG.sample_period,
    )
    variance = sensor_variance(truth_model, RIG.counts_per_rev)
    return float(
        linearised_noncentrality(Parametrised(NOMINAL, rival, scales), train, heldout, RIG.counts_per_rev, variance)[0]
    )


def cogging(coefficient: float) -> dict:
    return {TORQUE: Effect(f"0:{TERMS.index('sin(7*phi)')}", (coefficient,))}


FLAT = np.full((1, BANDS), 0.05)  # [rad] per band


def test_the_criterion_refits_the_torques_coefficients():
    """A rival torque 1.5 times the truth's is refit to it (what a refit absorbs counts for nothing); a rival
    without the torque has nothing to refit and is far from the truth."""
    command = Family(2.0, RIG.sample_period, NOMINAL.arm_inertia_total, 0.0).feedforward(FLAT)
    truth = cogging(-AMPLITUDE)
    absorbed = noncentrality(truth, cogging(-1.5 * AMPLITUDE), command)
    missing = noncentrality(truth, {}, command)
    assert missing > 100.0
    assert absorbed < 1e-3 * missing


@pytest.mark.slow
def test_the_torque_targets_design_sees_it_better_than_a_flat_experiment(case, tmp_path):
    """--target unmodelled_torque=SIZE at a tenth of the torque found: the designed 2 s experiment's noncentrality
    of the torque (the truth) against the model without it exceeds that of a flat experiment (every band at the
    same amplitude) with the same peak command, and its predicted detection is reported."""
    from furuta_drake.design import pipeline

    torque = torque_entry(-AMPLITUDE)
    write_diagnosis(tmp_path / "d", case, report_of(torque, rival=False))
    size = 0.1 * AMPLITUDE / np.sqrt(2)
    design = pipeline.design_experiment(
        tmp_path / "d", duration=2.0, settings=pipeline.FAST, targets=[f"{TORQUE}={size}"]
    )
    assert design.status == "design"
    target = design.hypotheses.hypotheses[1].effects
    flat = Family(2.0, RIG.sample_period, NOMINAL.arm_inertia_total, 0.0).feedforward(FLAT)
    flat = flat * np.max(np.abs(design.command)) / np.max(np.abs(flat))
    designed = noncentrality(target, {}, design.command[None])
    assert designed > noncentrality(target, {}, flat)
    assert 0.0 <= design.pairs[0]["detection_probability"] <= 1.0
