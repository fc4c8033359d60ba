"""The paper's experiments on the simulated Lund rig, on runs shorter than the paper's where the targets allow:
the numbers asserted are the paper's (docs/paper.md) and the simulated rig's true friction."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from furuta_drake.paper import reproduce
from furuta_drake.simulate import simulate


@pytest.fixture(scope="module")
def table_runs():
    return reproduce.run_table_experiments(reproduce.paper_rig_config(seed=1, duration=8.0))


def _row(rows, signal, statistic, reference=None):
    return next(
        r
        for r in rows
        if r["signal"] == signal and r["statistic"] == statistic and (reference is None or r["reference"] == reference)
    )


@pytest.mark.slow
@pytest.mark.parametrize("reference", ["butterworth", "true"])
def test_table2_vfe_cuts_the_velocity_errors(table_runs, reference):
    # Paper: 3.4x on the arm, 3.7x on the pendulum; the reproduction asks >= 2.5x and >= 2x against both references.
    rows = reproduce.table2(table_runs)
    arm = _row(rows, "phi_dot", "mean", reference)
    pendulum = _row(rows, "theta_dot", "mean", reference)
    assert arm["HG"] / arm["VFE"] >= 2.5
    assert pendulum["HG"] / pendulum["VFE"] >= 2.0
    assert (arm["paper_HG"], arm["paper_VFE"]) == (31e-3, 9e-3)


def test_table1_similar_control_accuracy(table_runs):
    # The paper's point (Table I): the observer changes the velocity estimate, not the control accuracy.
    rows = reproduce.table1(table_runs)
    for signal in ("phi", "theta"):
        row = _row(rows, signal, "mean")
        assert 0.5 <= row["HG"] / row["VFE"] <= 2.0, row
    # Balancing: the pendulum stays within a few degrees in both runs.
    for run in (table_runs.hg_run, table_runs.vfe_run):
        assert np.max(np.abs(run.state[:, 0])) < 0.1


def test_fairness_sweep_finds_an_interior_optimum(table_runs):
    # A high-gain observer trades encoder-noise amplification (small eps) against lag (large eps), so its
    # best eps lies strictly inside a grid spanning 2-20 ms; likewise for the VFE poles.
    for observer, grid in (("hg", reproduce.SWEEP_HG_EPS), ("vfe", reproduce.SWEEP_VFE_SCALES)):
        rows = [row for row in table_runs.sweep if row["observer"] == observer]
        assert [row["value"] for row in rows] == list(grid)
        best = [row for row in rows if row["best"]]
        assert len(best) == 1 and best[0]["value"] not in (grid[0], grid[-1])
        assert best[0]["phi_dot_mse_true"] == min(row["phi_dot_mse_true"] for row in rows)
    chosen = table_runs.config.observers
    best_eps = next(r["value"] for r in table_runs.sweep if r["observer"] == "hg" and r["best"])
    assert chosen.hg.eps_phi == chosen.hg.eps_theta == best_eps


def test_offline_replay_equals_the_closed_loop_observers(table_runs):
    # The sweep replays observers on logged data; after the start-up transient this must be the in-loop estimate.
    run, config = table_runs.vfe_run, table_runs.config
    replayed = reproduce.replay_observers(
        run, config, hg=config.observers.hg, vfe=(config.observers.vfe, config.observers.dahl)
    )
    keep = run.time >= reproduce.TRANSIENT
    for name in ("hg", "vfe"):
        np.testing.assert_allclose(replayed[name][keep], run.estimates[name][keep], atol=1e-9, rtol=0)


def test_fig5_friction_plus_error_matches_the_true_friction():
    outcome = reproduce.fig5_experiment(reproduce.paper_rig_config(seed=2, duration=10.0))
    low, high = outcome["set1_low"]["steady"], outcome["set2_high"]["steady"]
    for direction, level in (("pos", reproduce.ARM_COULOMB_POS), ("neg", reproduce.ARM_COULOMB_NEG)):
        # F_hat depends on the calibration (0.7x vs 1.3x Fc): the two sets differ by far more than 10 %.
        assert abs(high[direction]["F_hat"] - low[direction]["F_hat"]) > 0.3 * level
        for steady in (low, high):
            assert steady[direction]["samples"] > 500
            assert abs(abs(steady[direction]["true"]) - level) < 0.02 * level  # steady sliding: at Fc
            assert abs(steady[direction]["F_hat_plus_eps"] - steady[direction]["true"]) < 0.1 * level


def test_adaptation_settles_near_the_true_friction_ratios():
    config = reproduce.paper_rig_config(seed=3)
    outcome = reproduce.adaptation_experiment(config, duration=30.0)
    summary, result = outcome["summary"], outcome["result"]
    start = reproduce.UNDERESTIMATED_COULOMB
    assert summary["K_sigma_plus"] == pytest.approx(reproduce.ARM_COULOMB_POS / start, abs=0.15)  # 1.33
    assert summary["K_sigma_minus"] == pytest.approx(reproduce.ARM_COULOMB_NEG / start, abs=0.2)  # 2.0
    assert summary["friction_pos"] == pytest.approx(-reproduce.ARM_COULOMB_POS, rel=0.15)
    assert summary["friction_neg"] == pytest.approx(reproduce.ARM_COULOMB_NEG, rel=0.15)
    assert summary["theta_abs_max"] < 0.1
    # Nothing adapts before t = 7.8 s (Sec. V-D).
    before = result.time < reproduce.ADAPTATION_ENABLE_TIME
    assert np.all(result.signals["K_sigma"][before] == 1.0)


def test_hg_run_compensates_friction_from_its_own_dahl_observer():
    # Sec. IV-A: u = u_LQ - F_hat in both of Table I's runs. Compensating the 12-18 mN m arm friction must
    # shrink the arm's stick-slip excursions when the LQR runs on HG.
    config = reproduce.with_velocity_source(reproduce.paper_rig_config(seed=4, duration=6.0), "hg")
    off = dataclasses.replace(config, controller=dataclasses.replace(config.controller, friction_compensation=False))
    on_run, off_run = simulate(config), simulate(off)
    keep = on_run.time >= reproduce.TRANSIENT
    assert np.mean(on_run.state[keep, 1] ** 2) < 0.8 * np.mean(off_run.state[keep, 1] ** 2)
