"""The accepted model's intervals widened by how far its parameters move when the strongest candidate not
accepted is fitted beside it, so that they hold when an effect below the detection limits acts."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from furuta_drake.diagnosis.fit import FitResult
from furuta_drake.diagnosis.gap import GapResult
from furuta_drake.diagnosis.result import RankedCandidate
from furuta_drake.diagnosis.rival import widen
from furuta_drake.diagnosis.rule import Bootstrap
from furuta_drake.diagnosis.stepwise import Selection
from furuta_drake.effects.surrogate import Model
from furuta_drake.effects.vocabulary import Effect
from furuta_drake.rig import RIGS

WINDOWS = 100
INTERVAL = [0.78, 0.82]  # the gain's bootstrap interval given the model holding the gain error alone


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
    assert row.params_ci["gain"] == pytest.approx([0.78, 0.88])  # the interval, and shifted by +0.06
    assert row.params_ci_if_complete["gain"] == INTERVAL


def test_the_rival_is_the_candidate_that_explains_the_held_out_data_best():
    row = _widened([(0.86, 0.08), (0.74, 0.02)])  # the lag leaves less: it is the rival
    assert row.params_ci["gain"] == pytest.approx([0.72, 0.82])  # shifted by -0.06


def test_a_rival_fitted_with_the_kept_effects_frozen_moves_nothing():
    row = _widened([(0.8, 0.05)])
    assert row.params_ci["gain"] == INTERVAL


@given(st.floats(0.5, 1.5))
def test_the_widened_interval_holds_both_the_interval_and_its_shift(gain):
    row = _widened([(gain, 0.05)])
    low, high = row.params_ci["gain"]
    assert low <= min(INTERVAL[0], INTERVAL[0] + gain - 0.8) + 1e-12
    assert high >= max(INTERVAL[1], INTERVAL[1] + gain - 0.8) - 1e-12
