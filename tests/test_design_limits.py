"""The detection limits a design predicts for the effects it targets when a diagnosis has no rival: a delay the
rig's own logs cannot see at the size that changes its LQR loop (a slow, gentle hanging run through the
surrogate) is seen with the designed experiment, not with the same time of the rig at rest; a rig with nothing
to target gets no design."""

from __future__ import annotations

import hashlib
import json

import numpy as np
import pytest
import yaml

from furuta_drake.cli import main
from furuta_drake.design import pipeline
from furuta_drake.design.closed_loop import closed_loop_sizes
from furuta_drake.design.criterion import experiment_windows
from furuta_drake.design.inputs import read_diagnosis
from furuta_drake.design.limits import diagnosis_heldout_windows, joined, predicted_limits
from furuta_drake.design.output import design_json
from furuta_drake.design.rollout import HANGING, nominal_lqr_gain, surrogate_runs
from furuta_drake.diagnosis.selection.detection import injected_limits
from furuta_drake.diagnosis.selection.fit import scales_of
from furuta_drake.diagnosis.selection.rule import Bootstrap
from furuta_drake.effects.vocabulary import rig_model
from furuta_drake.rig import encoder_resolution, lund_rig
from furuta_drake.yamlio import dump_yaml_dataclass

RESAMPLES = 200


def _write_slow_log(path, rig, seed: int, seconds: float = 2.0) -> None:
    """A hanging run of the nominal surrogate under a slow, gentle command (0.3-0.6 Hz, a few mN m), read through
    the rig's encoder: a delay of a few ms hardly changes it."""
    time = np.arange(round(seconds / rig.sample_period)) * rig.sample_period
    phase = np.random.default_rng(seed).uniform(0, 2 * np.pi, 2)
    command = 0.004 * (np.sin(2 * np.pi * 0.3 * time + phase[0]) + np.sin(2 * np.pi * 0.6 * time + phase[1]))
    angles = surrogate_runs(rig_model(rig), command[None], rig.sample_period)[:, :, 0]
    count = encoder_resolution(rig.counts_per_rev)
    measured = np.round(angles / count) * count
    table = np.column_stack([time, command, measured])
    np.savetxt(path, table, delimiter=",", header="time,torque,theta,phi", comments="", fmt="%.12g")


def _write_diagnosis(directory, case, delay_limit) -> None:
    """A diagnosis with no effect accepted and no rival, whose report states ``delay_limit`` for the delay."""
    directory.mkdir()

    def entry(path):
        return {"path": str(path), "sha256": hashlib.sha256(path.read_bytes()).hexdigest()}

    report = {
        "verdict": "none",
        "effects": [],
        "ranking": [],
        "steps": [],
        "confusable": [],
        "detection_limits": [{"effect": "input_delay", "param": "delay", "value": delay_limit}],
    }
    (directory / "report.json").write_text(json.dumps(report))
    config = {"rig": entry(case / "rig.yaml"), "train": [entry(case / "train.csv")]}
    config["heldout"] = [entry(case / "heldout.csv")]
    (directory / "config.yaml").write_text(yaml.safe_dump(config))


@pytest.fixture(scope="module")
def case(tmp_path_factory):
    root = tmp_path_factory.mktemp("slow_logs")
    rig = lund_rig()
    (root / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    _write_slow_log(root / "train.csv", rig, 1)
    _write_slow_log(root / "heldout.csv", rig, 2)
    return root


def _today_delay_limit(record) -> float | None:
    """The delay's detection limit on the diagnosis' own held-out windows, as the diagnosis finds it."""
    windows = diagnosis_heldout_windows(record)
    model = rig_model(record.rig)
    (limit,) = injected_limits(
        model,
        [],
        windows,
        scales_of(record.train, model),
        record.rig.counts_per_rev,
        Bootstrap(windows.count, RESAMPLES, 0),
        ["input_delay"],
    )
    return limit.value


def test_the_designed_experiment_brings_the_delay_limit_below_the_size_that_matters(case, tmp_path):
    rig = lund_rig()
    size = closed_loop_sizes(rig, nominal_lqr_gain(rig))["input_delay"]
    directory = tmp_path / "probe"
    _write_diagnosis(directory, case, None)
    today = _today_delay_limit(read_diagnosis(directory))
    assert today is None or today > size  # these logs cannot see a delay that changes the loop

    diagnosis = tmp_path / "diagnosis"
    _write_diagnosis(diagnosis, case, today)
    design = pipeline.design_experiment(diagnosis, duration=2.0, balancing=False, settings=pipeline.FAST)
    assert design.status == "design"
    (limit,) = design.limits
    assert limit["effect"] == "input_delay" and limit["size"] == pytest.approx(size)
    assert limit["today"] == today
    assert limit["predicted"] is not None and limit["predicted"] < size and limit["predicted_below_size"]

    # the same 2 s of the rig at rest, hanging: the default of doing nothing sees no delay
    record = read_diagnosis(diagnosis)
    rest = np.tile(np.asarray(HANGING[:2], dtype=float), (2000, 1))
    scales = scales_of(record.train, rig_model(record.rig))
    targets = [("input_delay", size)]
    (idle,) = predicted_limits(record, design.hypotheses, targets, (rest, np.zeros(2000)), scales, RESAMPLES, 0)
    assert idle["predicted"] is None or idle["predicted"] > size
    assert idle["predicted_below_size"] is False
    assert design_json(design)["detection_limits"] == design.limits


def test_a_rig_with_nothing_to_target_gets_no_design(case, tmp_path, capsys):
    """No rival and a delay limit below the size that changes the loop: nothing to separate, exit status 2 and
    nothing written."""
    rig = lund_rig()
    size = closed_loop_sizes(rig, nominal_lqr_gain(rig))["input_delay"]
    _write_diagnosis(tmp_path / "diagnosis", case, 0.5 * size)
    out = tmp_path / "design"
    assert main(["design", "--diagnosis", str(tmp_path / "diagnosis"), "--out", str(out)]) == 2
    assert "nothing to separate" in capsys.readouterr().err
    assert not out.exists()


def test_the_experiment_windows_join_the_diagnosis_ones(case, tmp_path):
    """The predicted limits judge the diagnosis' held-out windows and the experiment's held-out half together."""
    _write_diagnosis(tmp_path / "diagnosis", case, None)
    record = read_diagnosis(tmp_path / "diagnosis")
    old = diagnosis_heldout_windows(record)
    rig = record.rig
    angles = np.tile(np.asarray(HANGING[:2], dtype=float), (2000, 1))
    new = experiment_windows(angles[:, :, None], np.zeros((1, 2000)), rig.sample_period, rig)[1]
    both = joined(old, new)
    assert both.count == old.count + new.count and len(both.logs) == len(old.logs) + 1
