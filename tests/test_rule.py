"""The held-out rule written once: docs/diagnose.md states the rule's own constants, the report's rule text is
generated from them, and the one judgement (``decide``) is the keep rule plus, for a first effect, closing the gap."""

from __future__ import annotations

import re

import pytest
from conftest import REPO

from furuta_drake.diagnosis.report.record_text import rule_text
from furuta_drake.diagnosis.selection import rule


def pct(value: float) -> str:
    return f"{100 * value:g} %"


def section(number: int) -> str:
    """Section ``number`` of docs/diagnose.md up to its first subsection, whitespace collapsed."""
    text = (REPO / "docs" / "diagnose.md").read_text()
    body = re.split(r"^## ", text, flags=re.M)
    found = next(part for part in body if part.startswith(f"{number}. "))
    return " ".join(re.split(r"^### ", found, flags=re.M)[0].split())


def test_the_docs_state_the_rules_constants():
    docs = section(5)
    for phrase in (
        f"below {rule.FLOOR_COUNTS} counts: nothing more enters",
        f"{pct(rule.LOWER_BOUND_QUANTILE)} lower bound of its reduction exceeds {pct(rule.ENTRY)}",
        f"fewer parameters within {pct(rule.PARSIMONY)} of it",
        f"beyond the {pct(rule.CONFUSABLE_LEVEL)} interval of their difference",
        f"is at least {pct(rule.MARGIN)}, its {pct(rule.LOWER_BOUND_QUANTILE)} lower bound exceeds {pct(rule.ENTRY)}",
        f"the floor's square ({rule.FLOOR_COUNTS}^2 counts^2)",
        f"1 - sqrt(1 - P - S) is at least {pct(rule.CLOSES)}",
        f"{'twice' if rule.NOISE_STANDARD_ERRORS == 2 else rule.NOISE_STANDARD_ERRORS} its bootstrap standard error",
    ):
        assert phrase in docs, phrase
    constants = {round(100 * t.value, 6) for t in rule.THRESHOLDS if t.unit == ""} | {100.0}
    stated = {float(n) for n in re.findall(r"(\d+(?:\.\d+)?) %", docs)}
    assert stated <= constants, f"percentages in the docs that are no constant of the rule: {stated - constants}"


def test_the_reports_rule_text_carries_the_constants():
    text = rule_text(bootstrap=1000, seed=0, max_effects=3)
    for value in (rule.ENTRY, rule.MARGIN, rule.PARSIMONY, rule.CLOSES, rule.CONFUSABLE_LEVEL):
        assert f"{value:.0%}" in text
    assert f"below {rule.FLOOR_COUNTS} counts" in text and "at most three" in text
    assert "at most two" in rule_text(bootstrap=1000, seed=0, max_effects=2)


def test_every_threshold_has_a_unit_and_a_meaning():
    names = [t.name for t in rule.THRESHOLDS]
    assert len(names) == len(set(names))
    for t in rule.THRESHOLDS:
        assert getattr(rule, t.name) == t.value and t.meaning and t.unit in ("", "counts", "factor")


@pytest.mark.parametrize("reduction", [0.1, 0.3, 0.6, 0.95])
@pytest.mark.parametrize("first", [False, True])
def test_decide_is_the_keep_rule_and_a_first_effect_must_close_the_gap(reduction, first):
    """Excess removed well above the floor's square, a lower bound well above ENTRY: what decides is the margin
    (20 % of the gap of the model without it) and, for a first effect, closing half of the nominal gap."""
    evidence = rule.Comparison(
        heldout_gap=1.0, reduction=reduction, lower_bound=reduction - 0.05, excess=0.5, excess_drop=1.0
    )
    expected = reduction >= rule.MARGIN and (not first or reduction >= rule.CLOSES)
    assert rule.decide(evidence, first=first) is expected


def test_verdict_names_the_first_effect_only_when_they_close_the_gap():
    """Shares of the nominal mean squared excess: predictions removing 96 % leave a gap of 20 % (an 80 % reduction);
    removing 51 % leaves 70 % of it (a 30 % reduction): not closed."""
    assert rule.combined_reduction(0.96, 0.0) == pytest.approx(0.8)
    assert rule.verdict(["input_delay", "arm_spring"], [], (0.96, 0.0), quiet=False) == "input_delay"
    assert rule.verdict(["input_delay"], [], (0.51, 0.0), quiet=False) == "unexplained"
    assert rule.verdict([], [], (0.0, 0.0), quiet=True) == "none"
    assert rule.verdict([], [], (0.0, 0.0), quiet=False) == "unexplained"


def test_a_sensor_effect_is_the_verdict_when_it_accounts_for_more_than_the_predictions_remove():
    """The sensor's share counts towards closing the gap (it passed its own test) and names the verdict when it is
    the larger part; it never makes the predictions' reduction itself larger."""
    assert rule.verdict([], ["measurement_noise"], (0.0, 0.97), quiet=False) == "measurement_noise"
    assert rule.verdict(["arm_viscous_friction"], ["measurement_noise"], (0.3, 0.6), quiet=False) == (
        "measurement_noise"
    )
    assert rule.verdict(["arm_viscous_friction"], ["measurement_noise"], (0.6, 0.3), quiet=False) == (
        "arm_viscous_friction"
    )
    assert rule.verdict([], ["measurement_noise"], (0.0, 0.5), quiet=False) == "unexplained"  # 29 %: not closed
