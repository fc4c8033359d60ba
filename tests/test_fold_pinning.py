"""What the folds pin down: the diagnosis' effects every split of the logs names, and the effects some splits add
or drop (the real QUBE's splits agree on the first effect and the arm inertia but each adds a different set)."""

from furuta_drake.diagnosis.report.record_text import consistency_judgement
from furuta_drake.diagnosis.result import Consistency
from furuta_drake.diagnosis.selection.folds import pinned
from furuta_drake.effects.vocabulary import rig_model
from furuta_drake.rig import RigParameters


def _folds() -> Consistency:
    return Consistency(
        3,
        ["arm_viscous_friction"] * 3,
        [
            ["arm_viscous_friction", "inertia_mismatch", "arm_spring"],
            ["arm_viscous_friction", "inertia_mismatch", "actuator_lag", "input_delay"],
            ["arm_viscous_friction", "inertia_mismatch", "actuator_lag"],
        ],
    )


def test_effects_every_fold_names_are_settled_and_the_others_counted():
    out = pinned(["arm_viscous_friction", "inertia_mismatch", "actuator_lag", "friction_asymmetry"], _folds())
    assert out.settled == ["arm_viscous_friction", "inertia_mismatch"]
    assert out.unsettled == {"actuator_lag": 2, "friction_asymmetry": 0, "arm_spring": 1, "input_delay": 1}


def test_the_judgement_names_what_the_logs_cannot_pin_down():
    out = pinned(["arm_viscous_friction", "inertia_mismatch", "actuator_lag"], _folds())
    text = consistency_judgement(out, rig_model(RigParameters()))
    assert "these logs cannot pin down actuator_lag (named on 2/3), arm_spring (named on 1/3)" in text
    assert "inertia_mismatch" not in text.split("cannot pin down")[1]


def test_folds_that_agree_leave_nothing_unsettled():
    same = Consistency(2, ["input_delay"] * 2, [["input_delay"], ["input_delay"]])
    out = pinned(["input_delay"], same)
    assert out.settled == ["input_delay"] and out.unsettled == {}
    assert "cannot pin down" not in consistency_judgement(out, rig_model(RigParameters()))
