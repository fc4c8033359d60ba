"""The listed effects kept beside a torque beyond the vocabulary, in the report: report.json's ``beside_torque``
(present only with a kept torque and an effect beside it), the headline naming the torque's shape and the friction
fitted beside it with its value, the table in report.md and report.html, and old reports without the key. The
reports are hand-built from injected truths: cogging of 1.5 mN m as sin(12 phi), Coulomb friction of 1.2 mN m
beside it; with the torque they remove 95 % of the held-out gap, alone 24 % (so the verdict stays unexplained)."""

from __future__ import annotations

import json
import re
from html import unescape
from types import SimpleNamespace

import pytest
from hypothesis import given
from hypothesis import strategies as st

from furuta_drake.diagnosis.pipeline import _artifacts
from furuta_drake.diagnosis.report.files import report_json, report_markdown
from furuta_drake.diagnosis.report.html import report_html
from furuta_drake.diagnosis.report.narrative import next_steps, verdict_sentence
from furuta_drake.diagnosis.report.torque import beside_record
from furuta_drake.diagnosis.result import Diagnosis, GapFigures, RankedCandidate
from furuta_drake.diagnosis.selection.fit import FitResult
from furuta_drake.diagnosis.selection.rule import Comparison
from furuta_drake.diagnosis.selection.stepwise import Selection
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.torque_library import TERMS
from furuta_drake.effects.vocabulary import effect_from_params
from furuta_drake.rig import RIGS

QUBE = RIGS["qube_servo2"]()
NOMINAL = Model.from_rig(QUBE)
COULOMB = 0.0012  # N m, the friction beside the cogging
COGGING = -0.0015  # N m, the coefficient of sin(12*phi)
WITH_TORQUE, ALONE = 0.95, 0.24  # held-out reductions of the friction with and without the torque
LOCALIZATION = {
    "signals": {"theta": 0.5, "phi": 0.5},
    "windows": [{"log": "heldout.csv", "start": 1.0, "end": 1.2, "why": "phi error, hanging"}],
    "regimes": [{"regime": "hanging", "share_of_gap": 0.6, "share_of_samples": 0.5}],
    "frequency_bands": [{"low_hz": 10.0, "high_hz": 30.0, "share_of_gap": 0.6}],
}
TORQUE = {
    "arm": {
        "expression": f"{COGGING}*sin(12*phi)",
        "terms": [{"term": "sin(12*phi)", "coefficient": COGGING, "ci": [-0.00152, -0.00148]}],
        "heldout_reduction": WITH_TORQUE,
        "closest_effect": None,
        "plot": "unmodelled_torque_arm.png",
    }
}
FRICTION = RankedCandidate(
    "arm_coulomb_friction",
    {"coulomb": COULOMB, "regularization_velocity": 0.001, "form": "smooth"},
    1.4 * (1 - ALONE),
    ALONE,
    0.13,
    params_ci={"coulomb": [0.0011, 0.0013], "regularization_velocity": [0.0001, 0.008]},
)
TRIPLE = RankedCandidate(  # the best candidate of the first selection, without the torque
    "arm_coulomb_friction+actuator_deadzone+actuator_lag",
    {"arm_coulomb_friction.coulomb": 0.0011, "actuator_deadzone.deadzone": 0.0007, "actuator_lag.time_constant": 0.006},
    0.69,
    0.51,
    0.44,
)


def diagnosis(torque: dict, accepted: list[str]) -> Diagnosis:
    """An unexplained diagnosis of a 1.4-count gap with ``torque`` kept and ``accepted`` fitted beside it."""
    ranking = [TRIPLE, FRICTION]
    return Diagnosis(
        verdict="unexplained",
        effects=[],
        gap=GapFigures("k-step output error", {"train": 1.4, "heldout": 1.4}, {"train": 1.4, "heldout": 1.4}, 0.0),
        ranking=ranking,
        localization=LOCALIZATION,
        unmodelled_torque=torque,
        beside_torque=beside_record(accepted, ranking, torque),
    )


def rendered(report: dict, tmp_path) -> tuple[str, str, str]:
    """The headline of report.html (checked equal to report.md's), the page and report.md."""
    page, markdown = report_html(report, tmp_path, {}), report_markdown(report, {})
    headline = unescape(re.search(r'id="verdict">(.*?)</h1>', page, re.S).group(1))
    assert next(line for line in markdown.splitlines() if line.startswith("**")).strip("*") == headline
    return headline, page, markdown


def test_the_key_holds_the_friction_fitted_beside_the_torque():
    report = json.loads(report_json(diagnosis(TORQUE, ["arm_coulomb_friction"]).to_json()))
    assert report["beside_torque"] == {
        "effects": ["arm_coulomb_friction"],
        "params": {"coulomb": COULOMB, "regularization_velocity": 0.001, "form": "smooth"},
        "params_ci": {"coulomb": [0.0011, 0.0013], "regularization_velocity": [0.0001, 0.008]},
        "heldout_reduction": WITH_TORQUE,
    }
    assert report["effects"] == [] and report["verdict"] == "unexplained"  # the contract's keys keep their meaning
    assert Diagnosis.from_json(report).beside_torque == report["beside_torque"]


@pytest.mark.parametrize("torque, accepted", [({}, ["arm_coulomb_friction"]), (TORQUE, [])])
def test_the_key_is_absent_without_a_torque_or_an_effect_beside_it(torque, accepted):
    assert "beside_torque" not in json.loads(report_json(diagnosis(torque, accepted).to_json()))


@given(st.permutations(["arm_coulomb_friction", "actuator_deadzone", "actuator_lag"]))
def test_the_key_reads_the_ranking_entry_of_exactly_the_effects_kept(order):
    pair = RankedCandidate(
        "actuator_deadzone+arm_coulomb_friction", {"actuator_deadzone.deadzone": 0.0007}, 1, 0.3, 0.2
    )
    ranking = [FRICTION, pair, TRIPLE]
    assert beside_record(order, ranking, TORQUE)["params"] == TRIPLE.params
    assert beside_record(order[:1], ranking, TORQUE).get("params") == (
        FRICTION.params if order[0] == "arm_coulomb_friction" else None
    )


def test_the_headline_names_the_torque_and_the_friction_with_its_value(tmp_path):
    report = json.loads(report_json(diagnosis(TORQUE, ["arm_coulomb_friction"]).to_json()))
    headline, _, markdown = rendered(report, tmp_path)
    for needle in (
        "held-out gap 1.4 counts",
        "an arm torque of about 1.5 mN m varying as sin(12*phi)",
        "a position-periodic torque, as cogging",
        "the arm's sliding (Coulomb) friction is about 1.2 mN m",
        "together they remove 95 % of the gap on logs the fit never saw",
        "the listed effect alone 24 %",
    ):
        assert needle in headline, (needle, headline)
    assert "best candidate" not in headline
    assert "Verdict `unexplained`." in markdown


def test_report_md_and_html_table_the_friction_with_its_rig_file_line(tmp_path):
    report = json.loads(report_json(diagnosis(TORQUE, ["arm_coulomb_friction"]).to_json()))
    _, page, markdown = rendered(report, tmp_path)
    section = markdown[markdown.index("## The listed effects beside the torque") :]
    assert "with it they remove 95 % of the held-out gap, alone 24 %" in section
    row = next(line for line in section.splitlines() if line.startswith("| arm_coulomb_friction |"))
    assert "1.2 mN m (95 % interval 1.1 to 1.3 mN m)" in row
    assert "arm_coulomb_friction: {coulomb: 0.0012, regularization_velocity: 0.001, form: smooth}" in row
    assert 'id="beside-torque"' in page and "arm_coulomb_friction: {coulomb: 0.0012" in page
    continuing = next(what for what, command in next_steps(report) if "fitted_rig.yaml" in command)
    assert "effects fitted beside the torque are in its effects: section" in continuing
    assert "torque beyond the vocabulary is in its unmodelled_torque: section" in continuing


def test_accepted_effects_are_not_tabled_again_beside_the_torque(tmp_path):
    report = json.loads(report_json(diagnosis(TORQUE, ["arm_coulomb_friction"]).to_json()))
    report.update(verdict="arm_coulomb_friction", effects=["arm_coulomb_friction"])
    _, page, markdown = rendered(report, tmp_path)
    assert "## The listed effects beside the torque" not in markdown and 'id="beside-torque"' not in page


def test_a_torque_without_effects_beside_it_is_named_beside_the_best_candidate(tmp_path):
    report = json.loads(report_json(diagnosis(TORQUE, []).to_json()))
    headline, _, markdown = rendered(report, tmp_path)
    assert "an arm torque of about 1.5 mN m varying as sin(12*phi)" in headline
    assert "it removes 95 % of the gap" in headline
    assert "the best candidate tried (Coulomb friction on the arm, a dead zone of the drive and a lag" in headline
    assert "## The listed effects beside the torque" not in markdown


def test_a_report_without_either_key_still_renders_its_old_headline(tmp_path):
    report = json.loads(report_json(diagnosis({}, []).to_json()))
    assert "unmodelled_torque" not in report and "beside_torque" not in report
    headline, _, markdown = rendered(report, tmp_path)
    assert headline == verdict_sentence(report)
    assert (
        "no effect of the vocabulary explains: the best candidate tried" in headline and "removes only 51 %" in headline
    )
    assert "beside the torque" not in markdown


@pytest.mark.parametrize("alone, torque_kept", [(ALONE, True), (ALONE, False), (0.9, True)])
def test_the_fitted_rig_file_holds_the_friction_beside_a_kept_torque(alone, torque_kept):
    """fitted_rig.yaml and fitted_model.yaml hold the injected friction beside a kept torque, also when the friction
    alone leaves the gap unexplained (``alone`` below one half); without a torque they hold only accepted effects."""
    params = {"coulomb": COULOMB, "regularization_velocity": 0.001, "form": "smooth"}
    fit = FitResult(
        "arm_coulomb_friction", {"arm_coulomb_friction": effect_from_params("arm_coulomb_friction", params)}, 1, None
    )
    selection = Selection(
        nominal=None,
        tried=[(1, fit)],
        accepted=["arm_coulomb_friction"],
        over_nominal={fit.name: Comparison(1.4 * (1 - alone), alone, alone - 0.1, 0.0, 0.0)},
    )
    cogging = (0, TERMS.index("sin(12*phi)"), COGGING)
    missing = SimpleNamespace(terms=[cogging], scatter={})
    inputs = SimpleNamespace(nominal=NOMINAL, rig=QUBE)
    artifacts = _artifacts(inputs, selection, TORQUE if torque_kept else {}, missing, [], None, 0.0, {})
    holds = torque_kept or alone >= 0.5  # the friction is in the files
    stated = (artifacts.fitted_rig.effects or {}).get("arm_coulomb_friction")
    assert stated == (params if holds else None)
    assert artifacts.fitted_config.friction.arm.coulomb_pos == pytest.approx(COULOMB if holds else 0.0)
    expression = artifacts.fitted_rig.unmodelled_torque.arm if torque_kept else None
    assert (expression is not None and "sin(12*phi)" in expression) == torque_kept
