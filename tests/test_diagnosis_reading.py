"""The report a lab reads: the first sentence of report.md and report.html states the verdict of the report.json it
came from, with the fitted sizes as physical quantities (the injected truths of these hand-built diagnoses), the
page stays self-contained, old reports still render and the unmodelled torque shows only when present."""

from __future__ import annotations

import json
import re
from html import unescape
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from furuta_drake.diagnosis.formatting import PREFIXES, quantity
from furuta_drake.diagnosis.gap.per_log import heldout_rms_per_log
from furuta_drake.diagnosis.logs.load import WindowResiduals
from furuta_drake.diagnosis.report.files import report_json, report_markdown
from furuta_drake.diagnosis.report.html import report_html
from furuta_drake.diagnosis.report.narrative import accepted_effects, rig_line
from furuta_drake.diagnosis.result import DetectionLimit, Diagnosis, GapFigures, RankedCandidate, Step

OLD_REPORT = Path(__file__).parent / "bad_inputs" / "design_old_report" / "report.json"
OLD_REPORT_V2 = Path(__file__).parent / "data" / "report_before_v2.json"
LOCALIZATION = {
    "signals": {"theta": 0.2, "phi": 0.8},
    "windows": [{"log": "heldout_1.csv", "start": 1.2, "end": 1.5, "why": "phi error, high arm speed"}],
    "regimes": [{"regime": "high arm speed", "share_of_gap": 0.7, "share_of_samples": 0.2}],
    "frequency_bands": [{"low_hz": 3.0, "high_hz": 10.0, "share_of_gap": 0.6}],
}
INERTIA = {"arm_inertia_scale": 1.3, "pendulum_inertia_scale": 1.0, "coupling_scale": 1.0, "gravity_scale": 1.0}


def diagnosis(verdict, effects, params, nominal, after, lower_bound=None, intervals=None) -> Diagnosis:
    """A finished diagnosis as report.json would hold it: the final model's ranking entry carries ``params``
    (prefixed by effect when there are several) and ``intervals``."""
    reduction = 1 - after / nominal
    ranking = []
    if effects:
        ranking.append(
            RankedCandidate("+".join(effects), params, after, reduction, lower_bound, params_ci=intervals or {})
        )
    steps = [Step(name, {}, after, reduction) for name in effects]
    limits = [DetectionLimit("actuator_deadzone", "deadzone", 0.0008, "N m")]
    return Diagnosis(
        verdict=verdict,
        effects=list(effects),
        gap=GapFigures(
            "k-step output error", {"train": nominal, "heldout": nominal}, {"train": after, "heldout": after}, reduction
        ),
        ranking=ranking,
        localization=LOCALIZATION,
        steps=steps,
        detection_limits=limits,
    )


CASES = {
    "unexplained": diagnosis("unexplained", [], {}, nominal=2.4, after=2.4),  # a cogging torque: best tried 20 %
    "none": diagnosis("none", [], {}, nominal=0.02, after=0.02),
    "single": diagnosis(
        "input_delay", ["input_delay"], {"delay": 0.0081}, 1.6, 0.128, 0.9, {"delay": [0.0078, 0.0084]}
    ),
    "three": diagnosis(
        "inertia_mismatch",
        ["inertia_mismatch", "input_delay", "arm_coulomb_friction"],
        {
            **{f"inertia_mismatch.{k}": v for k, v in INERTIA.items()},
            "input_delay.delay": 0.008,
            "arm_coulomb_friction.coulomb": 0.012,
            "arm_coulomb_friction.presliding": 0.002,
            "arm_coulomb_friction.form": "presliding",
        },
        nominal=2.0,
        after=0.3,
        lower_bound=0.8,
    ),
}
CASES["unexplained"].ranking = [
    RankedCandidate("arm_coulomb_friction", {"coulomb": 0.003, "presliding": 0.001}, 1.92, 0.2, 0.1)
]
# What each first sentence must say, from the injected truth: 8.1 ms is 0.0081 s, 12 mN m is 0.012 N m, 85 %
# is 1 - 0.3 / 2.0, 92 % is 1 - 0.128 / 1.6.
EXPECTED = {
    "unexplained": (
        "no effect of the vocabulary explains",
        "held-out gap 2.4 counts",
        "the best candidate tried (Coulomb friction on the arm) removes only 20 %",
    ),
    "none": ("to within their noise", "held-out gap 0.02 counts", "no unmodelled effect is needed"),
    "single": ("Commands reach the arm about 8.1 ms late", "this removes 92 %", "at least 90 % with 95 % confidence"),
    "three": (
        "The arm is about 1.3 times heavier than the rig file says",
        "commands reach the arm about 8 ms late",
        "the arm's sliding (Coulomb) friction is about 12 mN m",
        "together they remove 85 % of the gap on logs the fit never saw",
        "at least 80 %",
    ),
}


def rendered(case: str, tmp_path) -> tuple[dict, str, str]:
    report = json.loads(report_json(CASES[case].to_json()))
    return report, report_html(report, tmp_path, {}), report_markdown(report, {})


def first_sentence_html(page: str) -> str:
    found = re.search(r'<h1 class="verdict[^"]*" id="verdict">(.*?)</h1>', page, re.S)
    return unescape(found.group(1))


def first_sentence_markdown(text: str) -> str:
    return next(line for line in text.splitlines() if line.startswith("**")).strip("*")


@pytest.mark.parametrize("case", list(CASES))
def test_the_first_sentence_states_the_verdict_of_its_report_json(case, tmp_path):
    report, page, markdown = rendered(case, tmp_path)
    sentence = first_sentence_html(page)
    assert first_sentence_markdown(markdown) == sentence  # both open on the same answer
    for needle in EXPECTED[case]:
        assert needle in sentence, (needle, sentence)
    assert sentence.count(".") >= 1 and sentence.endswith(".")
    assert page.index('id="verdict"') < page.index('id="before-after"') < page.index('id="next"')


def test_the_first_screen_holds_the_before_after_chart_and_the_next_step(tmp_path):
    _, page, markdown = rendered("single", tmp_path)
    first = page[page.index('<div class="first">') : page.index('id="effects"')]
    assert "<svg" in first and "furuta-drake diagnose --rig fitted_rig.yaml" in first
    assert "input_delay: {delay: 0.0081}" in page  # the rig-file line to add
    assert "8.1 ms (95 % interval 7.8 to 8.4 ms)" in page
    assert markdown.index("gap.svg") < markdown.index("## What to do next") < markdown.index("## The evidence")


def test_fold_consistency_is_said_in_words(tmp_path):
    report = json.loads(report_json(CASES["single"].to_json()))
    report["consistency"] = {
        "folds": 3,
        "verdicts": ["input_delay", "input_delay", "none"],
        "effects": [["input_delay"], ["input_delay"], []],
        "judgement": "verdict input_delay on 2/3, none on 1/3 folds",
    }
    page = report_html(report, tmp_path, {})
    trust = page[page.index('id="trust"') : page.index('id="effects"')]
    assert "Repeated on 3 splits of the logs, the same verdict came back 2 times" in trust


def test_a_confusable_pair_asks_for_the_design_command(tmp_path):
    report = json.loads(report_json(CASES["single"].to_json()))
    report["confusable"] = [{"effects": ["input_delay", "actuator_lag"], "why": "their reductions overlap"}]
    page = report_html(report, tmp_path, {})
    assert "cannot tell a delay of the command from a lag of the drive" in page
    assert "furuta-drake design --diagnosis . --out design" in page


@pytest.mark.parametrize("case", list(CASES))
def test_the_page_is_self_contained(case, tmp_path):
    _, page, _ = rendered(case, tmp_path)
    assert not re.search(r"https?://", page)
    assert not re.search(r"<(script|link|iframe|object|embed)\b", page)
    assert all(ref.startswith("#") for ref in re.findall(r'href="([^"]*)"', page))


@pytest.mark.parametrize(
    "path, opening",
    [
        (OLD_REPORT, "Commands reach the arm about 3 ms late; this removes 92 %"),  # the spec's keys only
        (OLD_REPORT_V2, "The arm's sliding (Coulomb) friction is about 1.5 mN m and the drive follows"),
    ],
)
def test_an_old_report_still_renders(path, opening, tmp_path):
    report = json.loads(path.read_text())
    page, markdown = report_html(report, tmp_path, {}), report_markdown(report, {})
    sentence = first_sentence_html(page)
    assert sentence.startswith(opening)
    assert "<svg" in page and first_sentence_markdown(markdown) == sentence


def test_the_unmodelled_torque_is_shown_only_when_present(tmp_path):
    report = json.loads(report_json(CASES["unexplained"].to_json()))
    assert "unmodelled-torque" not in report_html(report, tmp_path, {})
    report["unmodelled_torque"] = {
        "arm": {
            "expression": "0.004*sin(6*phi)",
            "terms": [{"term": "sin(6*phi)", "coefficient": 0.004, "ci": [0.0035, 0.0045]}],
            "heldout_reduction": 0.7,
            "closest_effect": None,
            "plot": "unmodelled_arm.png",
        }
    }
    page, markdown = report_html(report, tmp_path, {}), report_markdown(report, {})
    sentence = "An arm torque of about 4 mN m varying as sin(6*phi): a position-periodic torque"
    assert 'id="unmodelled-torque"' in page and sentence in page and "gap by 70 %" in page
    assert "## The unmodelled torque on the arm" in markdown and "| sin(6*phi) | 0.004 |" in markdown


def test_rig_lines_hold_the_form_and_its_own_parameters_only():
    report = json.loads(report_json(CASES["three"].to_json()))
    lines = {effect.name: rig_line(effect) for effect in accepted_effects(report)}
    assert lines["inertia_mismatch"] == (
        "inertia_mismatch: {arm_inertia_scale: 1.3, pendulum_inertia_scale: 1, coupling_scale: 1, gravity_scale: 1}"
    )
    assert lines["arm_coulomb_friction"] == (
        "arm_coulomb_friction: {coulomb: 0.012, presliding: 0.002, form: presliding}"
    )


def test_per_log_errors_are_the_rms_residual_of_each_log_and_signal():
    def window(log, theta, phi):
        t = np.arange(50) * 0.001
        residual = np.column_stack([theta * np.sign(np.sin(40 * t) + 0.5), np.full(50, phi)])
        return WindowResiduals(log, t, residual, np.zeros((50, 4)), np.zeros(50), np.zeros(50, bool))

    before = [window("a.csv", 2.0, -3.0), window("a.csv", 2.0, 3.0), window("b.csv", 1.0, 0.5)]
    after = [window("a.csv", 0.5, 1.0), window("a.csv", 0.5, -1.0), window("b.csv", 0.25, 0.5)]
    rows = heldout_rms_per_log(before, after)
    assert [row["log"] for row in rows] == ["a.csv", "b.csv"]
    assert rows[0]["nominal"] == pytest.approx({"theta": 2.0, "phi": 3.0})
    assert rows[0]["with_effects"] == pytest.approx({"theta": 0.5, "phi": 1.0})
    assert rows[1]["with_effects"] == pytest.approx({"theta": 0.25, "phi": 0.5})
    assert heldout_rms_per_log(before, None)[1]["with_effects"] == rows[1]["nominal"]


@given(st.floats(1e-7, 500.0), st.sampled_from(["N m", "s", "rad", "N m s/rad"]))
def test_a_quantity_reads_back_to_two_significant_digits(value, unit):
    text = quantity(value, unit)
    figure, shown = text.split(" ", 1)
    factor = next(f for f, prefix in PREFIXES if shown == prefix + unit)
    assert float(figure) * factor == pytest.approx(value, rel=0.05)
