"""The LQR margins behind the sizes a design targets when a diagnosis has no rival, against a loop whose margins
are known in closed form: an unstable first-order plant x' = a x + u under u = -k x (k > a > 0), whose loop
L(s) = k / (s - a) crosses over at w = sqrt(k^2 - a^2) with delay margin atan(w / a) / w; a lag 1 / (T s + 1)
leaves s^2 + (1 / T - a) s + (k - a) / T, stable while T < 1 / a; a gain g keeps it stable while g k > a."""

from __future__ import annotations

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.design.closed_loop import (
    CLOSED_LOOP_SHARE,
    delay_margin,
    gain_margin,
    lag_margin,
    limited_targets,
)


def _loop(a: float, k: float):
    return np.array([[a]]), np.array([[1.0]]), np.array([[k]])


@settings(deadline=None, max_examples=25)
@given(st.floats(0.2, 5.0), st.floats(1.3, 6.0))
def test_the_margins_of_an_unstable_first_order_loop_are_its_closed_forms(a, ratio):
    k = ratio * a
    A, B, K = _loop(a, k)
    w = np.sqrt(k**2 - a**2)
    frequencies = np.geomspace(1e-2, 1e2, 40001)
    assert delay_margin(A, B, K, frequencies) == pytest.approx(np.arctan(w / a) / w, rel=1e-3)
    assert lag_margin(A, B, K) == pytest.approx(1.0 / a, rel=1e-6)
    assert gain_margin(A, B, K) == pytest.approx(a / k, rel=1e-6)


def _report(limits: dict, accepted=("arm_coulomb_friction",)) -> dict:
    return {
        "steps": [{"effect": name} for name in accepted],
        "detection_limits": [{"effect": name, "value": value} for name, value in limits.items()],
    }


def test_a_detection_limit_above_the_size_that_changes_the_loop_is_a_target_one_below_is_not():
    sizes = {"input_delay": 3e-3, "actuator_lag": 6e-3, "torque_gain_error": 0.92}
    report = _report({"input_delay": 8e-3, "actuator_lag": 2e-3, "torque_gain_error": None})
    assert limited_targets(report, sizes) == [("input_delay", 3e-3), ("torque_gain_error", 0.92)]


def test_an_accepted_effect_is_never_a_target():
    sizes = {"input_delay": 3e-3}
    assert limited_targets(_report({"input_delay": 8e-3}, accepted=("input_delay",)), sizes) == []


def test_the_share_of_a_margin_is_a_change_short_of_instability():
    assert 0.0 < CLOSED_LOOP_SHARE < 0.5


def test_a_limit_reaches_a_size_by_its_distance_from_no_effect():
    from furuta_drake.design.closed_loop import reaches

    assert reaches("input_delay", 2e-3, 3e-3) and not reaches("input_delay", 4e-3, 3e-3)
    assert reaches("torque_gain_error", 1.05, 0.92) and not reaches("torque_gain_error", 1.1, 0.92)
    assert reaches("inertia_mismatch", 1.02, 1.05) and not reaches("inertia_mismatch", 1.08, 1.05)
    assert reaches("actuator_saturation", 0.03, 0.02) and not reaches("actuator_saturation", 0.03, 0.04)
    assert not reaches("actuator_lag", None, 1.0)
