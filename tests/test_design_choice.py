"""The design's choice among candidate experiments by their predicted detection limits, and the duration a target
would need: on synthetic candidates whose limits are known, and end to end on a diagnosis whose delay the logs
cannot see."""

from __future__ import annotations

import json
import math

import pytest
from test_design_limits import _write_diagnosis, _write_slow_log

from furuta_drake.design import pipeline
from furuta_drake.design.choice import choice_record, chosen, duration_reaching, shortfall
from furuta_drake.design.closed_loop import closed_loop_sizes
from furuta_drake.design.output import design_markdown, write_design
from furuta_drake.design.rollout import nominal_lqr_gain
from furuta_drake.rig import lund_rig
from furuta_drake.yamlio import dump_yaml_dataclass

DELAY = 0.49e-3  # [s] a delay target's size


def candidate(mode: str, duration: float, limit: float | None, effect="input_delay", size=DELAY, status="design"):
    target = {"effect": effect, "param": "delay", "unit": "s", "size": size, "predicted": limit}
    return {"mode": mode, "duration_s": duration, "status": status, "reason": "", "limits": [target]}


def test_the_candidate_whose_limit_falls_furthest_towards_the_size_is_chosen():
    open_loop, balancing = candidate("hanging", 8.0, 2.66e-3), candidate("balancing", 8.0, 0.82e-3)
    assert chosen([open_loop, balancing]) == 1
    assert chosen([balancing, open_loop]) == 0
    # a limit not reached is worse than any reached; a refused candidate is never chosen
    assert chosen([candidate("balancing", 8.0, None), open_loop]) == 1
    assert chosen([candidate("balancing", 8.0, 0.1e-3, status="refused"), open_loop]) == 1
    assert chosen([candidate("hanging", 8.0, 1e-3, status="refused")]) is None


def test_ties_go_to_the_shorter_then_to_the_open_loop():
    assert chosen([candidate("hanging", 16.0, 1e-3), candidate("hanging", 8.0, 1e-3)]) == 1
    assert chosen([candidate("balancing", 8.0, 1e-3), candidate("hanging", 8.0, 1e-3)]) == 1
    assert chosen([candidate("balancing", 8.0, None), candidate("hanging", 8.0, None)]) == 1


def test_the_shortest_candidate_reaching_every_size_is_chosen():
    """Once a limit falls to its size the verdict can see the effect: a longer experiment bringing it further
    down costs the lab time and buys nothing, so the shorter one reaching the size wins."""
    reaching = [candidate("balancing", 32.0, 0.31e-3), candidate("balancing", 16.0, 0.45e-3)]
    assert chosen(reaching + [candidate("balancing", 8.0, 0.74e-3)]) == 1
    assert "brings every target to its size" in choice_record(reaching, chosen(reaching))["why"]
    # reaching both targets beats bringing one further down and leaving the other above its size
    assert chosen([candidate("hanging", 8.0, 0.6e-3), candidate("balancing", 32.0, 0.45e-3)]) == 1


def test_the_worst_target_decides_across_effects():
    """Two targets of different units compare by their limit over their size: a candidate that brings one far
    below its size but leaves the other twice above loses to one leaving both just above."""
    lag = {"effect": "actuator_lag", "param": "time_constant", "unit": "s", "size": 3.7e-3}
    first = candidate("hanging", 8.0, 0.1e-3)
    first["limits"].append({**lag, "predicted": 7.4e-3})
    second = candidate("balancing", 8.0, 0.6e-3)
    second["limits"].append({**lag, "predicted": 4.0e-3})
    assert chosen([first, second]) == 1


def test_shortfalls_measure_from_the_neutral_value():
    assert shortfall("input_delay", 1e-3, 0.5e-3) == pytest.approx(2.0)
    assert shortfall("torque_gain_error", 0.9, 0.95) == pytest.approx(2.0)  # a 10 % error against 5 %
    assert shortfall("inertia_mismatch", 1.02, 1.1) == pytest.approx(0.2)
    assert shortfall("actuator_saturation", 0.1, 0.05) == pytest.approx(0.5)  # a larger limit detects more
    assert shortfall("input_delay", None, 1e-3) == math.inf


def test_the_duration_reaching_a_size_follows_the_limit_as_a_power_of_the_duration():
    """A limit averaged down by independent noise falls as T^-1/2: twice above the size at 8 s, it reaches it
    at 32 s; one that grows with the duration reaches it at none."""
    exponent, reaching = duration_reaching([8.0, 16.0, 32.0], [2.0, 2.0 / math.sqrt(2.0), 1.0])
    assert exponent == pytest.approx(-0.5) and reaching == pytest.approx(32.0)
    exponent, reaching = duration_reaching([8.0, 16.0], [4.0, 2.0])  # T^-1: 1 at 32 s
    assert reaching == pytest.approx(32.0)
    exponent, reaching = duration_reaching([8.0, 16.0, 32.0], [5.4, 8.3, 15.9])
    assert exponent > 0 and reaching is None
    assert duration_reaching([8.0, 16.0], [3.0, math.inf]) == (None, None)


def test_the_record_names_every_candidate_and_what_a_longer_experiment_reaches():
    candidates = [candidate("hanging", 8.0, 2.7e-3), candidate("hanging", 16.0, 4.1e-3)]
    candidates += [candidate("balancing", 8.0, 0.98e-3), candidate("balancing", 16.0, 0.98e-3 / math.sqrt(2.0))]
    record = choice_record(candidates, chosen(candidates))
    assert [c["chosen"] for c in record["candidates"]] == [False, False, False, True]
    (longer,) = record["longer"]
    assert longer["mode"] == "balancing" and longer["durations_s"] == [8.0, 16.0]
    # 0.98 ms at 8 s falling as T^-1/2 reaches 0.49 ms at 8 * (0.98 / 0.49)^2 = 32 s
    assert longer["exponent"] == pytest.approx(-0.5) and longer["duration_reaching_size_s"] == pytest.approx(32.0)
    assert "balancing, 16 s" in record["why"]


def _diagnosis(tmp_path):
    """A diagnosis of slow logs of the Lund rig in ``tmp_path / "diagnosis"``; returns the rig."""
    rig = lund_rig()
    case = tmp_path / "case"
    case.mkdir()
    (case / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    _write_slow_log(case / "train.csv", rig, 1)
    _write_slow_log(case / "heldout.csv", rig, 2)
    _write_diagnosis(tmp_path / "diagnosis", case, None)
    return rig


@pytest.mark.slow
def test_a_design_left_to_choose_compares_both_modes_by_their_predicted_limits(tmp_path):
    """Without a mode, a design targeting the delay plays both modes and keeps the one whose predicted limit is
    lowest; design.json and design.md list both."""
    rig = _diagnosis(tmp_path)
    design = pipeline.design_experiment(tmp_path / "diagnosis", duration=2.0, settings=pipeline.FAST)
    size = closed_loop_sizes(rig, nominal_lqr_gain(rig))["input_delay"]
    candidates = design.choice["candidates"]
    assert [(c["mode"], c["duration_s"]) for c in candidates] == [("hanging", 2.0), ("balancing", 2.0)]
    (picked,) = [c for c in candidates if c["chosen"]]
    assert picked["mode"] == design.mode and design.limits[0]["size"] == pytest.approx(size)
    assert picked["detection_limits"][0]["predicted"] == design.limits[0]["predicted"]
    assert all(picked["detection_limits"][0]["shortfall"] <= c["detection_limits"][0]["shortfall"] for c in candidates)
    write_design(tmp_path / "design", design)
    document = json.loads((tmp_path / "design" / "design.json").read_text())
    assert [c["mode"] for c in document["choice"]["candidates"]] == ["hanging", "balancing"]
    assert "## Which experiment" in design_markdown(document)


def test_a_design_runs_its_blas_on_one_thread_and_leaves_the_callers_as_it_was(tmp_path, monkeypatch):
    """A design's linear algebra is small: its stages run with one BLAS thread (a second would only spin), and the
    caller's thread count is restored afterwards."""
    from threadpoolctl import threadpool_info

    def threads() -> list[int]:
        return [pool["num_threads"] for pool in threadpool_info() if pool["user_api"] == "blas"]

    _diagnosis(tmp_path)
    seen = []
    monkeypatch.setattr(pipeline, "_chosen_design", lambda *args: seen.append(threads()))
    monkeypatch.setattr(pipeline, "_design_in_mode", lambda *args: seen.append(threads()))
    before = threads()
    pipeline.design_experiment(tmp_path / "diagnosis", duration=2.0, settings=pipeline.FAST)
    assert seen and set(seen[0]) == {1}
    assert threads() == before
