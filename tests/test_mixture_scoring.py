"""The mixture benchmark's scoring (benchmarks/diagnosis/mixtures.py): the share of the held-out gap the accepted
effects close with an accepted sensor effect's share counted, and which named effect names a true one."""

import pytest

from benchmarks.diagnosis.mixtures import closed_share, named_as


def test_a_gap_of_noise_alone_is_closed_by_the_noise_not_by_the_predictions():
    # The predictions remove nothing; the accepted noise accounts for 96 % of the nominal mean squared excess:
    # 1 - sqrt(1 - 0.96) = 80 % of the gap is closed.
    assert closed_share({"heldout_reduction": 0.0, "sensor_share": 0.96}) == pytest.approx(0.8)


def test_without_a_sensor_effect_the_closed_share_is_the_predictions_reduction():
    assert closed_share({"heldout_reduction": 0.62, "sensor_share": None}) == pytest.approx(0.62)
    # Predictions removing 62 % of the gap (85.6 % of its mean square) beside noise claiming the rest: all closed.
    assert closed_share({"heldout_reduction": 0.62, "sensor_share": 1 - 0.38**2}) == pytest.approx(1.0)


def test_a_gain_names_a_true_inertia_error_only_when_its_scales_are_uniform():
    uniform = {"name": "inertia_mismatch", "params": {"a": 1.1, "b": 1.1, "c": 1.1, "d": 1.1}}
    spread = {"name": "inertia_mismatch", "params": {"a": 1.126, "b": 1.075, "c": 1.1, "d": 1.1}}
    assert named_as(uniform, ["torque_gain_error"]) == "torque_gain_error"
    assert named_as(spread, ["torque_gain_error"]) is None
    gain = {"name": "torque_gain_error", "params": {"gain": 0.9}}
    assert named_as(gain, ["inertia_mismatch"]) == "inertia_mismatch"
