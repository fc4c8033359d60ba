"""The verdict fits the size of the gap: a nominal held-out gap that nothing closes reads ``unexplained`` only
when it matters; below a small fraction of a count (after the sensor's own variance) it reads ``none``, and the
choice names the nearest candidate with its fit."""

from __future__ import annotations

import numpy as np
from hypothesis import given
from hypothesis import strategies as st

from furuta_drake.diagnosis.gap.metric import GapResult
from furuta_drake.diagnosis.report.record_text import choice_text
from furuta_drake.diagnosis.selection.fit import FitResult
from furuta_drake.diagnosis.selection.rule import NEGLIGIBLE_COUNTS, Bootstrap
from furuta_drake.diagnosis.selection.stepwise import Selection
from furuta_drake.effects.vocabulary import CANDIDATES, Effect

WINDOWS = 100
ROUNDING_VARIANCE = 1.0 / 12.0  # [counts^2] an ideal rounding encoder's own variance


def _gap(per_window: np.ndarray) -> GapResult:
    return GapResult(float(np.sqrt(max(per_window.mean(), 0.0))), {}, per_window, 0.0, [], [])


def _selection(gap: float) -> Selection:
    """Nothing kept after a forward pass that tried a 1 ms input delay removing 36 % of a nominal gap of
    ``gap`` counts and an actuator lag removing 10 %; the nominal model is not within the noise."""
    rng = np.random.default_rng(1)
    nominal = gap**2 * (1.0 + 0.2 * rng.standard_normal(WINDOWS))
    bootstrap = Bootstrap(WINDOWS, 300, 0)
    selection = Selection(_gap(nominal), [], quiet=False)
    for name, reduction, value in (("input_delay", 0.36, 1.02e-3), ("actuator_lag", 0.10, 4e-4)):
        form = CANDIDATES[name].forms[0].name
        result = FitResult(name, {name: Effect(form, (value,))}, gap, _gap(nominal * (1.0 - reduction) ** 2))
        selection.tried.append((1, result))
        selection.over_nominal[name] = bootstrap.evidence(nominal, result.heldout.per_window)
    return selection


def test_a_one_sample_delays_gap_that_nothing_closes_reads_none_with_the_nearest_candidate():
    selection = _selection(0.08)  # counts: the nominal held-out gap of a one-sample computation delay
    assert selection.verdict == "none" and selection.effects == []
    text = choice_text(selection)
    assert "input_delay" in text and "0.00102 s" in text and "36.0%" in text


def test_a_gap_of_counts_that_nothing_closes_stays_unexplained():
    selection = _selection(3.0)
    assert selection.verdict == "unexplained"
    assert "No candidate" in choice_text(selection) and "nearest" not in choice_text(selection)


def test_the_negligible_gap_is_a_small_fraction_of_the_rounding_encoders_own_error():
    assert NEGLIGIBLE_COUNTS**2 < 0.5 * ROUNDING_VARIANCE


@given(st.floats(0.01, 2.0))
def test_the_verdict_is_none_exactly_below_the_negligible_gap(gap):
    selection = _selection(gap)
    assert (selection.verdict == "none") == (selection.nominal.gap < NEGLIGIBLE_COUNTS)
