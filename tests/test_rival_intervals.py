"""The accepted model's intervals inflated about the fitted value by rule.INTERVAL_INFLATION and widened by how
far its parameters move when the strongest candidate not accepted is fitted beside it, so that they hold when an
effect below the detection limits acts."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import REPO
from hypothesis import given
from hypothesis import strategies as st

from furuta_drake.diagnosis.gap.metric import GapResult
from furuta_drake.diagnosis.result import RankedCandidate
from furuta_drake.diagnosis.selection.fit import FitResult
from furuta_drake.diagnosis.selection.rival import inflated, widen
from furuta_drake.diagnosis.selection.rule import INTERVAL_INFLATION, Bootstrap
from furuta_drake.diagnosis.selection.stepwise import Selection
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import Effect
from furuta_drake.rig import RIGS

WINDOWS = 100
INTERVAL = [0.78, 0.82]  # the gain's bootstrap interval given the model holding the gain error alone (fit: 0.8)
INFLATED = [0.8 - INTERVAL_INFLATION * 0.02, 0.8 + INTERVAL_INFLATION * 0.02]


def _gap(excess: float, seed: int) -> GapResult:
    per_window = excess * (1.0 + 0.1 * np.random.default_rng(seed).standard_normal(WINDOWS))
    return GapResult(float(np.sqrt(per_window.mean())), {}, per_window, 0.0, [], [])


def _widened(rivals: list[tuple[float, float]]) -> dict:
    """The gain's interval after a selection that kept a gain error of 0.8 and fitted, beside it, a delay (one
    per entry of ``rivals``: the gain it moved to and the excess squared residual left [counts^2])."""
    nominal = _gap(4.0, 0)
    final = FitResult("torque_gain_error", {"torque_gain_error": Effect("", (0.8,))}, 0.3, _gap(0.09, 1))
    selection = Selection(nominal, [(1, final)], accepted=["torque_gain_error"])
    for i, (gain, excess) in enumerate(rivals):
        effects = {
            "torque_gain_error": Effect("", (gain,)),
            f"{['input_delay', 'actuator_lag'][i]}": Effect(["fixed", ""][i], (1e-3,)),
        }
        selection.tried.append((2, FitResult("+".join(effects), effects, 0.2, _gap(excess, 2 + i))))
    row = RankedCandidate("torque_gain_error", {"gain": 0.8}, 0.3, 0.9, 0.85, params_ci={"gain": INTERVAL})
    model = Model.from_rig(RIGS["lund"]())
    (out,) = widen([row], selection, Bootstrap(WINDOWS, 200, 0), model)
    return out


def test_the_interval_spans_the_gain_the_model_holding_the_rival_fits():
    row = _widened([(0.86, 0.05)])
    assert row.params_ci["gain"] == pytest.approx([INFLATED[0], INFLATED[1] + 0.06])  # and shifted by +0.06
    assert row.params_ci_if_complete["gain"] == INTERVAL


def test_the_rival_is_the_candidate_that_explains_the_held_out_data_best():
    row = _widened([(0.86, 0.08), (0.74, 0.02)])  # the lag leaves less: it is the rival
    assert row.params_ci["gain"] == pytest.approx([INFLATED[0] - 0.06, INFLATED[1]])  # shifted by -0.06


def test_a_rival_fitted_with_the_kept_effects_frozen_moves_nothing():
    row = _widened([(0.8, 0.05)])
    assert row.params_ci["gain"] == pytest.approx(INFLATED)


def test_without_a_rival_the_interval_is_still_inflated():
    row = _widened([])
    assert row.params_ci["gain"] == pytest.approx(INFLATED)
    assert row.params_ci_if_complete["gain"] == INTERVAL


@given(st.floats(0.5, 1.5))
def test_the_widened_interval_holds_both_the_interval_and_its_shift(gain):
    row = _widened([(gain, 0.05)])
    low, high = row.params_ci["gain"]
    assert low <= min(INFLATED[0], INFLATED[0] + gain - 0.8) + 1e-12
    assert high >= max(INFLATED[1], INFLATED[1] + gain - 0.8) - 1e-12


@given(st.floats(0.0, 1.0), st.floats(0.0, 1.0), st.floats(0.0, 1.0))
def test_an_inflated_interval_holds_the_bootstrap_s_and_stays_non_negative(value, below, above):
    low, high = max(value - below, 0.0), value + above
    out_low, out_high = inflated(value, low, high, "arm_viscous_friction.viscous")
    assert out_low <= low and out_high >= high and out_low >= 0.0
    assert out_high - value == pytest.approx(INTERVAL_INFLATION * above)
    signed_low, _ = inflated(value, low, high, "equilibrium")
    assert signed_low == pytest.approx(value - INTERVAL_INFLATION * (value - low))


def test_the_docs_state_the_inflation():
    docs = " ".join((REPO / "docs" / "diagnose.md").read_text().split())
    low, high = f"x - {INTERVAL_INFLATION:g} (x - lo)", f"x + {INTERVAL_INFLATION:g} (hi - x)"
    assert f"[{low}, {high}]" in docs and "`INTERVAL_INFLATION`" in docs


def _form_widened(rival_excess: float) -> RankedCandidate:
    """The Coulomb level's interval after a selection that kept Coulomb friction in its presliding form at 10 mN m
    (bootstrap interval 9.9-10.1 mN m, held-out excess 0.09 counts^2) whose smooth form, fitted in its place,
    reads 9.5 mN m and leaves ``rival_excess``."""
    nominal = _gap(4.0, 0)
    final = FitResult(
        "arm_coulomb_friction", {"arm_coulomb_friction": Effect("presliding", (0.010, 1e-3))}, 0.3, _gap(0.09, 1)
    )
    selection = Selection(nominal, [(1, final)], accepted=["arm_coulomb_friction"])
    smooth = {"arm_coulomb_friction": Effect("smooth", (0.0095, 0.02))}
    selection.form_rivals = [FitResult("arm_coulomb_friction", smooth, 0.3, _gap(rival_excess, 1))]
    interval = {"coulomb": [0.0099, 0.0101], "presliding": [0.9e-3, 1.1e-3]}
    row = RankedCandidate(
        "arm_coulomb_friction", {"coulomb": 0.010, "presliding": 1e-3}, 0.3, 0.9, 0.85, params_ci=interval
    )
    (out,) = widen([row], selection, Bootstrap(WINDOWS, 200, 0), Model.from_rig(RIGS["lund"]()))
    return out


def test_the_level_spans_the_other_friction_form_when_the_data_cannot_rule_it_out():
    """The smooth form fits the held-out windows as well (the same excess, seeded alike): the Coulomb level's
    interval reaches down to its 9.5 mN m; the presliding stiffness, which the smooth form has not, moves nowhere."""
    out = _form_widened(0.09)
    low = 0.010 - INTERVAL_INFLATION * 0.0001
    assert out.params_ci["coulomb"] == pytest.approx([low - 0.0005, 0.010 + INTERVAL_INFLATION * 0.0001])
    assert out.params_ci["presliding"] == pytest.approx(
        [1e-3 - INTERVAL_INFLATION * 1e-4, 1e-3 + INTERVAL_INFLATION * 1e-4]
    )


def test_a_friction_form_the_held_out_data_rule_out_does_not_widen():
    """The smooth form leaves three times the excess squared residual: ruled out, the interval is only inflated."""
    out = _form_widened(0.27)
    assert out.params_ci["coulomb"] == pytest.approx(
        [0.010 - INTERVAL_INFLATION * 0.0001, 0.010 + INTERVAL_INFLATION * 0.0001]
    )
