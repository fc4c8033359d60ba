"""The report's words for a drive: backlash and compliance as physical statements, their look-alikes named beside
them with what the other removes alone, a drive's fitted keys as drive: lines, and an unexplained gap that
concentrates at the arm's velocity reversals said so."""

from __future__ import annotations

from furuta_drake.diagnosis.report import narrative
from furuta_drake.diagnosis.report.narrative import Accepted


def report(effects, ranking, verdict="drive_backlash", regimes=(), **more):
    return {
        "verdict": verdict,
        "effects": effects,
        "ranking": ranking,
        "gap": {"nominal": {"heldout": 3.0}, "heldout_reduction": 0.8},
        "localization": {"regimes": list(regimes)},
        **more,
    }


BACKLASH = {"effect": "drive_backlash", "params": {"backlash": 0.03}, "heldout_reduction": 0.9}
FRICTION = {"effect": "arm_coulomb_friction", "params": {"coulomb": 0.01}, "heldout_reduction": 0.4}


def test_backlash_is_stated_with_its_look_alikes_and_what_they_remove():
    sentences = narrative.trust_sentences(report(["drive_backlash"], [BACKLASH, FRICTION]))
    friction = next(s for s in sentences if "Coulomb friction on the arm" in s)
    assert friction.startswith("Backlash in the drive can look like Coulomb friction on the arm")
    assert "40 %" in friction and "90 %" in friction
    assert any("a dead zone of the drive" in s for s in sentences)
    statement = narrative.effect_statement(Accepted("drive_backlash", {"backlash": 0.03}))
    assert "30 mrad" in statement and "twice" in statement


def test_a_pair_already_confusable_is_not_repeated():
    confusable = [{"effects": ["drive_backlash", "arm_coulomb_friction"], "why": "their reductions overlap"}]
    sentences = narrative.trust_sentences(report(["drive_backlash"], [BACKLASH, FRICTION], confusable=confusable))
    assert sum("Coulomb friction on the arm" in s for s in sentences) == 1


def test_compliance_looks_like_a_lag():
    compliance = {"effect": "drive_compliance", "params": {"stiffness": 3.0, "damping": 0.01}, "heldout_reduction": 0.9}
    sentences = narrative.trust_sentences(report(["drive_compliance"], [compliance], verdict="drive_compliance"))
    assert any(s.startswith("An elastic drive can look like a lag of the drive") for s in sentences)


def test_a_drive_effect_adds_drive_keys_to_the_rig():
    assert narrative.rig_line(Accepted("drive_backlash", {"backlash": 0.03})) == "drive: {backlash: 0.03}"
    line = narrative.rig_line(Accepted("drive_compliance", {"stiffness": 3.0, "damping": 0.01}))
    assert line == "drive: {stiffness: 3, damping: 0.01}"


def test_an_unexplained_gap_at_velocity_reversals_is_said_so():
    at_reversals = [{"regime": "arm velocity reversal", "share_of_gap": 0.6, "share_of_samples": 0.2}]
    text = " ".join(w for w, _ in narrative.next_steps(report([], [FRICTION], "unexplained", at_reversals)))
    assert "concentrates at the arm's velocity reversals (60 % of it in 20 % of the samples)" in text
    assert "drive: section" in text  # backlash was not tried: the rig file states no drive
    spread = [{"regime": "arm velocity reversal", "share_of_gap": 0.25, "share_of_samples": 0.2}]
    assert "reversals" not in " ".join(w for w, _ in narrative.next_steps(report([], [], "unexplained", spread)))
    kept = report([], [], "unexplained", at_reversals, unmodelled_torque={"arm": {}})
    assert narrative.reversal_sentence(kept) == ""  # a torque of the state explains it


def test_a_compliance_limit_reads_as_the_stiffest_hidden_drive():
    limit = {"effect": "drive_compliance", "param": "stiffness", "value": 20.0, "unit": "N m/rad"}
    assert narrative.limit_sentence(limit).startswith("An elastic drive stiffer than 20 N m/rad")
