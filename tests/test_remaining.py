"""What the accepted effects leave (``report.json``'s ``remaining``): present exactly when the final model's held-out
gap, less what accepted sensor effects account for, is above the rule's negligible size; its share is that gap over
the nominal one; it lists the effects fitted beside the accepted ones that remove part of it, each with why it was
not accepted; and on a rig whose delay is kept out of the candidates, the report says what the friction leaves."""

from __future__ import annotations

import json
import math

import pytest

from furuta_drake.diagnosis.report.narrative import remaining_sentences
from furuta_drake.diagnosis.result import DetectionLimit, GapFigures, RankedCandidate
from furuta_drake.diagnosis.selection.remaining import candidates, remaining_record
from furuta_drake.diagnosis.selection.rule import NEGLIGIBLE_COUNTS

LOCALIZATION = {
    "signals": {"theta": 0.9, "phi": 0.1},
    "regimes": [{"regime": "upright", "share_of_gap": 0.9, "share_of_samples": 0.9}],
    "frequency_bands": [{"low_hz": 0.0, "high_hz": 1.0, "share_of_gap": 1.0}],
    "after": {
        "signals": {"theta": 0.2, "phi": 0.8},
        "regimes": [
            {"regime": "arm velocity reversal", "share_of_gap": 0.6, "share_of_samples": 0.2},
            {"regime": "high arm speed", "share_of_gap": 0.3, "share_of_samples": 0.5},
        ],
        "frequency_bands": [
            {"low_hz": 0.0, "high_hz": 3.0, "share_of_gap": 0.3},
            {"low_hz": 3.0, "high_hz": 10.0, "share_of_gap": 0.7},
        ],
    },
}


def figures(nominal: float, with_effects: float, sensor_share: float = 0.0) -> GapFigures:
    return GapFigures(
        "", {"heldout": nominal}, {"heldout": with_effects}, 1 - with_effects / nominal, sensor_share=sensor_share
    )


def row(effect: str, over_previous: float, step: int = 2, **fields) -> RankedCandidate:
    return RankedCandidate(
        effect, fields.pop("params", {}), 1.0, 0.5, 0.4, step=step, reduction_over_previous=over_previous, **fields
    )


def test_nothing_remains_below_the_negligible_size():
    assert remaining_record(figures(4.0, 0.9 * NEGLIGIBLE_COUNTS), {}, LOCALIZATION, [], [], [], []) == {}


def test_the_share_is_the_gap_left_over_the_nominal_and_sits_where_the_after_localisation_says():
    record = remaining_record(figures(4.0, 1.0), {"theta": 0.4, "phi": 0.9}, LOCALIZATION, [], ["x"], [], [])
    assert record["share"] == pytest.approx(0.25)
    assert record["rms_counts"] == {"theta": 0.4, "phi": 0.9}
    where = record["where"]
    assert (where["signal"], where["regime"], where["band_hz"]) == ("phi", "arm velocity reversal", [3.0, 10.0])


def test_what_an_accepted_sensor_effect_accounts_for_is_not_left():
    # The predictions remove nothing (a gap of 2 counts either way) and the accepted noise claims 3/4 of its
    # mean squared excess: what remains is sqrt(4 - 3) = 1 count, half of the nominal gap.
    record = remaining_record(figures(2.0, 2.0, sensor_share=0.75), {}, LOCALIZATION, [], [], [], [])
    assert record["share"] == pytest.approx(0.5)
    # Claiming all of it leaves nothing.
    assert remaining_record(figures(2.0, 2.0, sensor_share=1.0), {}, LOCALIZATION, [], [], [], []) == {}


def test_candidates_beside_the_accepted_effects_with_why_each_was_not_accepted():
    accepted = ["arm_coulomb_friction"]
    ranking = [
        row("arm_coulomb_friction+input_delay", 0.10, step=2),
        row("arm_coulomb_friction+input_delay", 0.30, step=3),  # the latest step is the one read
        row("arm_coulomb_friction+actuator_lag", 0.25),
        row("arm_coulomb_friction+arm_spring", 0.2, at_bound={"arm_spring.stiffness": "lower"}),
        row("arm_coulomb_friction+torque_gain_error", 0.15, params={"torque_gain_error.gain": 1.004}),
        row("arm_coulomb_friction+arm_viscous_friction", 0.12, params={"arm_viscous_friction.viscous": 0.002}),
        row("arm_coulomb_friction+pendulum_friction", 0.001),  # removes nothing worth listing
        RankedCandidate("arm_coulomb_friction+actuator_deadzone", {}, None, None, None, step=2, status="failed"),
        row("input_delay", 0.5, step=1),  # not beside the accepted effect
    ]
    confusable = [{"effects": ["actuator_lag", "arm_coulomb_friction"], "why": ""}]
    limits = [
        DetectionLimit("torque_gain_error", "gain", 1.01, ""),
        DetectionLimit("arm_viscous_friction", "viscous", 0.001, ""),
    ]
    listed = candidates(ranking, accepted, confusable, limits)
    assert [(c["effect"], c["why_not"]) for c in listed] == [
        ("input_delay", "evidence"),
        ("actuator_lag", "confused_with:arm_coulomb_friction"),
        ("arm_spring", "at_bound"),
        ("torque_gain_error", "below_detection_limit"),  # 0.4 % off a gain of 1, the logs detect 1 %
        ("arm_viscous_friction", "evidence"),  # twice the viscous level the logs detect
    ]
    assert listed[0]["of_remaining"] == 0.30


def test_the_words_say_the_share_the_place_and_the_reasons():
    record = remaining_record(figures(4.0, 1.0), {"theta": 0.4, "phi": 0.9}, LOCALIZATION, [], ["x"], [], [])
    record["candidates"] = [
        {"effect": "input_delay", "heldout_reduction": 0.8, "of_remaining": 0.3, "why_not": "evidence"}
    ]
    text = " ".join(remaining_sentences({"remaining": record}))
    assert text.startswith("What remains: 25 % of the nominal held-out gap (theta 0.4, phi 0.9 counts), mostly in phi")
    assert "arm velocity reversal" in text and "3-10 Hz" in text
    assert "input_delay (30 % of it; its evidence was too weak)" in text
    assert remaining_sentences({}) == []


@pytest.mark.slow
def test_a_delay_kept_out_of_the_candidates_remains_beside_the_friction(tmp_path):
    """Coulomb friction and a strong input delay on the Lund rig; only the friction laws are candidates, so the
    delay's part of the gap is what remains, and the report says so."""
    from benchmarks.diagnosis.suite import run_configs, with_effect
    from furuta_drake.diagnosis.logs.writers import write_log
    from furuta_drake.diagnosis.pipeline import diagnose
    from furuta_drake.diagnosis.report.files import write_report
    from furuta_drake.rig import lund_rig
    from furuta_drake.simulate import simulate
    from furuta_drake.yamlio import dump_yaml_dataclass

    rig_path = tmp_path / "rig.yaml"
    rig_path.write_text(dump_yaml_dataclass(lund_rig()))
    paths = {}
    for part, seed in (("train", 3), ("heldout", 4)):
        for run, config in run_configs(lund_rig(), seed, 4.0).items():
            config = with_effect(with_effect(config, "arm_coulomb_friction", 2), "input_delay", 2)
            result = simulate(config)
            path = tmp_path / f"{part}_{run}.csv"
            write_log(
                path,
                {
                    "time": result.time,
                    "torque": result.torque,
                    "theta": result.measured[:, 0],
                    "phi": result.measured[:, 1],
                },
            )
            paths.setdefault(part, []).append(path)
    diagnosis = diagnose(
        rig=rig_path,
        train=paths["train"],
        heldout=paths["heldout"],
        candidates=["arm_coulomb_friction", "arm_viscous_friction"],
        workers=2,
    )
    write_report(tmp_path / "report", diagnosis)
    report = json.loads((tmp_path / "report" / "report.json").read_text())
    assert "arm_coulomb_friction" in report["effects"]
    gap = report["gap"]
    left = math.sqrt(
        gap["with_effects"]["heldout"] ** 2 - (gap["sensor_share"] or 0.0) * gap["nominal"]["heldout"] ** 2
    )
    assert left > NEGLIGIBLE_COUNTS
    remaining = report["remaining"]
    assert remaining["share"] == pytest.approx(left / gap["nominal"]["heldout"], rel=1e-4)
    assert remaining["where"]["signal"] in ("theta", "phi")
    assert "What remains:" in (tmp_path / "report" / "report.md").read_text()
    assert 'id="remaining"' in (tmp_path / "report" / "report.html").read_text()


def test_a_sensor_effect_that_passes_its_test_but_leaves_the_gap_open_is_not_said_to_be_accepted():
    """The verdict's words agree with ``effects``: a sensor effect read on its signature is accepted only when the
    selection closes the gap."""
    import numpy as np

    from furuta_drake.diagnosis.report.record_text import sensor_text
    from furuta_drake.diagnosis.selection.sensor import SensorFinding
    from furuta_drake.effects.vocabulary import Effect

    finding = SensorFinding(
        "measurement_noise", Effect("white", (1e-3,)), np.zeros((1, 1)), np.full(4, 50.0), 40.0, True, np.ones(4)
    )

    class Selection:  # the two fields sensor_text reads besides the findings
        sensors = [finding]
        jitter = None

    Selection.closes = True
    assert "measurement_noise is accepted on its signature" in sensor_text(Selection)
    Selection.closes = False
    text = sensor_text(Selection)
    assert "is accepted" not in text and "passes its signature test" in text and "not among the effects" in text
