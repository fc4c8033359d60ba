"""Parameter sweeps on Dask: points and seeds, results independent of the workers, diverged points, bad input."""

import csv
import dataclasses
import math

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.cli import main
from furuta_drake.config import SimulationConfig
from furuta_drake.errors import ConfigError
from furuta_drake.sweep import SweepConfig, dask_client, load_sweep, resolve_sweep, run_sweep
from furuta_drake.yamlio import dump_yaml_dataclass

LUND = SimulationConfig.from_rig("lund")
# Lund linearization (docs/paper.md): theta_ddot = ALPHA1 theta + BETA4 u at the upright.
ALPHA1, BETA4 = 47.949, -365.07


def short(config: SimulationConfig = LUND, **changes) -> SimulationConfig:
    return dataclasses.replace(config, duration=1.0, **changes)


@pytest.fixture(scope="module")
def scheduler():
    """One two-worker LocalCluster for the module (its start-up costs about a second)."""
    with dask_client(workers=2) as client:
        yield client.scheduler.address


def csv_rows(path):
    with open(path, newline="") as file:
        return list(csv.DictReader(file))


@pytest.mark.slow
def test_grid_gives_one_row_per_point_and_the_same_bytes_on_one_and_two_workers(tmp_path, scheduler, capsys):
    base = short(observers=dataclasses.replace(LUND.observers, run=["hg"]))
    sweep_file = tmp_path / "sweep.yaml"
    sweep_file.write_text(
        dump_yaml_dataclass(
            SweepConfig(
                base=base, parameters={"encoder.counts_per_rev": [256, 16384], "initial_state[0]": [0.05, 0.1]}, seed=3
            )
        )
    )

    assert main(["sweep", "--config", str(sweep_file), "--out", str(tmp_path / "two"), "--scheduler", scheduler]) == 0
    assert "swept 4 points (0 diverged)" in capsys.readouterr().out
    rows = run_sweep(load_sweep(sweep_file), tmp_path / "one", workers=1)

    assert (tmp_path / "one" / "results.csv").read_bytes() == (tmp_path / "two" / "results.csv").read_bytes()
    assert [(r["point"], r["encoder.counts_per_rev"], r["initial_state[0]"]) for r in rows] == [
        (0, 256, 0.05),
        (1, 256, 0.1),
        (2, 16384, 0.05),
        (3, 16384, 0.1),
    ]
    assert len({r["point_seed"] for r in rows}) == 4
    for row in rows:
        assert not row["diverged"] and row["diverged_time"] is None
        # Balanced from rest at theta_0: the pendulum never leans further than it started (plus a few counts).
        assert row["initial_state[0]"] <= row["theta_abs_max_rad"] < row["initial_state[0]"] + 0.01
        assert 0 < row["mean_theta_sq_rad2"] < row["initial_state[0]"] ** 2
    # The HG observer differentiates the quantised angles: counts 64 times coarser give a larger velocity error.
    # On the arm (at rest at phi = 0 like the observer's initial state: no start-up error) the quantisation
    # noise, of variance q^2 / 12, dominates: 64^2 = 4096 times larger, less what the model error adds to both.
    for start in (0, 1):
        coarse, fine = rows[start], rows[start + 2]
        assert coarse["hg_velocity_mse_theta_dot"] > fine["hg_velocity_mse_theta_dot"]
        assert coarse["hg_velocity_mse_phi_dot"] > 100 * fine["hg_velocity_mse_phi_dot"]
    written = {p.name for p in (tmp_path / "two").iterdir()}
    assert written == {
        "results.csv",
        "sweep.yaml",
        "metrics_vs_encoder_counts_per_rev.png",
        "metrics_vs_initial_state_0.png",
    }
    table = csv_rows(tmp_path / "two" / "results.csv")
    assert list(table[0])[:4] == ["point", "point_seed", "encoder.counts_per_rev", "initial_state[0]"]
    assert [r["diverged"] for r in table] == ["false"] * 4
    # The written sweep.yaml is the resolved sweep: loading it gives the same points.
    again = load_sweep(tmp_path / "two" / "sweep.yaml")
    assert [p.config for p in again.points] == [p.config for p in load_sweep(sweep_file).points]


def test_a_fallen_pendulum_is_a_diverged_row_and_the_other_points_run(tmp_path, scheduler):
    # With |u| <= 0.05 N m the arm cannot hold the pendulum at 0.9 rad: |BETA4| 0.05 cos(0.9) = 11 rad/s^2 of
    # control against ALPHA1 sin(0.9) = 38 rad/s^2 of gravity; from 0.05 rad it needs only ALPHA1 0.05 = 2.4.
    assert abs(BETA4) * 0.05 * math.cos(0.9) < ALPHA1 * math.sin(0.9)
    lqr = dataclasses.replace(LUND.controller.lqr, torque_limit=0.05)
    base = short(controller=dataclasses.replace(LUND.controller, lqr=lqr))
    rows = run_sweep(
        SweepConfig(base=base, parameters={"initial_state[0]": [0.9, 0.05]}), tmp_path / "out", scheduler=scheduler
    )
    fallen, balanced = rows
    assert fallen["diverged"] and "fell" in fallen["cause"]
    # Falling 0.1 rad at a net acceleration of at least 38 - 11 rad/s^2 takes under 0.09 s.
    assert 0 < fallen["diverged_time"] < 0.2
    assert fallen["mean_theta_sq_rad2"] is None
    assert not balanced["diverged"] and balanced["theta_abs_max_rad"] < 0.06
    table = csv_rows(tmp_path / "out" / "results.csv")
    assert table[0]["diverged"] == "true" and table[0]["mean_theta_sq_rad2"] == ""
    assert float(table[0]["diverged_time"]) == pytest.approx(fallen["diverged_time"], rel=1e-11)


def test_a_gain_that_destabilises_the_upright_is_bad_input_and_nothing_is_written(tmp_path, scheduler):
    # u = -K x with K = [1, 0, 0, 0] pushes the pendulum the way it falls: theta_ddot = (ALPHA1 - BETA4) theta.
    sweep = SweepConfig(base=short(), parameters={"controller.gain": [[1.0, 0.0, 0.0, 0.0]]})
    with pytest.raises(
        ConfigError,
        match=r"point 0 \(controller\.gain=\[1\.0, 0\.0, 0\.0, 0\.0\]\): "
        r"controller\.gain .* does not stabilise",
    ):
        run_sweep(sweep, tmp_path / "out", scheduler=scheduler)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(
    "entries, fragment",
    [
        (
            "parameters:\n  friction.arm.coulomb_poss: [0.01]\n",
            r"sweep\.yaml:3: parameters\.friction\.arm\.coulomb_poss: "
            r"unknown key 'coulomb_poss' in JointFrictionParameters",
        ),
        ("parameters:\n  fricton.arm.viscous: [0.01]\n", r"sweep\.yaml:3: .*unknown key 'fricton' in SimulationConfig"),
        ("parameters:\n  duration: [1.0, abc]\n", r"sweep\.yaml:3: parameters\.duration\[1\] expected a number"),
        ("parameters:\n  controller.velocity_source: [hg, kalman]\n", r"must be one of \['true', 'derivative'"),
        ("parameters:\n  duration[0]: [1.0]\n", r"sweep\.yaml:3: .*'duration' is not a list"),
        ("parameters:\n  initial_state[4]: [1.0]\n", r"sweep\.yaml:3: .*initial_state\[4\]: index out of range"),
        ("parameters:\n  friction..arm: [1.0]\n", r"is not a dotted path"),
        ("parameters:\n  duration: [1.0]\n  duration: [2.0]\n", r"sweep\.yaml:4: parameters\.duration: duplicate path"),
        (
            "parameters:\n  duration: [1.0, -2.0]\n",
            r"sweep\.yaml: point 1 \(duration=-2\): duration must be a positive",
        ),
        ("parameters:\n  duration: []\n", r"parameters\.duration: needs at least one value"),
        ("parameters: {}\n", r"a grid sweep needs at least one"),
        (
            "mode: random\nsamples: 3\nranges:\n  controller.velocity_source: [0, 1]\n",
            r"sweep\.yaml:5: ranges\.controller\.velocity_source: random mode draws numbers",
        ),
        ("mode: random\nsamples: 3\nranges:\n  encoder.counts_per_rev: [100.5, 2000]\n", r"give integer bounds"),
        ("mode: random\nsamples: 3\nranges:\n  duration: [2.0, 1.0]\n", r"ranges\.duration must be \[low, high\]"),
        ("mode: random\nranges:\n  duration: [1.0, 2.0]\n", r"samples must be >= 1"),
        ("parameters:\n  duration: [1.0]\nmetrics: [velocity_rmse]\n", r"unknown metric 'velocity_rmse'"),
        ("parameters:\n  duration: [1.0]\nbase_file: missing.yaml\n", r"missing\.yaml: no such file"),
        (
            "parameters:\n  duration: [1.0]\nworkers: 2\n",
            r"sweep\.yaml:4: workers unknown key 'workers' in SweepConfig",
        ),
    ],
)
def test_bad_sweep_files_are_named_by_file_line_and_key(tmp_path, entries, fragment):
    path = tmp_path / "sweep.yaml"
    path.write_text("seed: 1\n" + entries)
    with pytest.raises(ConfigError, match=fragment):
        load_sweep(path)


def test_the_cli_refuses_bad_input_in_one_line_before_running_anything(tmp_path, capsys):
    sweep_file = tmp_path / "sweep.yaml"
    sweep_file.write_text("parameters:\n  friction.arm.coulomb_poss: [0.01]\n")
    assert main(["sweep", "--config", str(sweep_file), "--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "coulomb_poss" in err and str(sweep_file) in err
    sweep_file.write_text("parameters:\n  duration: [0.5]\n")
    (tmp_path / "full").mkdir()
    (tmp_path / "full" / "keep.txt").write_text("mine")
    assert main(["sweep", "--config", str(sweep_file), "--out", str(tmp_path / "full")]) == 2
    assert "not empty" in capsys.readouterr().err
    assert main(["sweep", "--config", str(sweep_file), "--out", str(tmp_path / "out"), "--workers", "0"]) == 2
    assert "workers (--workers) must be >= 1, got 0" in capsys.readouterr().err
    assert (
        main(
            [
                "sweep",
                "--config",
                str(sweep_file),
                "--out",
                str(tmp_path / "out"),
                "--scheduler",
                "tcp://127.0.0.1:9",
                "--workers",
                "2",
            ]
        )
        == 2
    )
    assert "--scheduler" in capsys.readouterr().err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["full", "sweep.yaml"]
    assert (tmp_path / "full" / "keep.txt").read_text() == "mine"


@settings(max_examples=25, deadline=None)
@given(
    durations=st.lists(st.floats(0.1, 5.0), min_size=1, max_size=3),
    torques=st.lists(st.floats(0.0, 0.1), min_size=1, max_size=3),
    seed=st.integers(0, 2**32),
)
def test_grid_points_are_the_product_in_order_and_seeds_depend_on_the_index_only(durations, torques, seed):
    sweep = resolve_sweep(
        SweepConfig(base=LUND, seed=seed, parameters={"duration": durations, "excitation.torque_rms": torques})
    )
    assert [(p.config.duration, p.config.excitation.torque_rms) for p in sweep.points] == [
        (d, t) for d in durations for t in torques
    ]
    assert [p.index for p in sweep.points] == list(range(len(durations) * len(torques)))
    assert all(p.config.seed == p.seed == p.config.encoder.seed for p in sweep.points)
    assert len({p.seed for p in sweep.points}) == len(sweep.points)
    other = resolve_sweep(
        SweepConfig(
            base=LUND, seed=seed, parameters={"duration": [1.0] * len(durations), "actuator.gain": [1.0] * len(torques)}
        )
    )
    assert [p.seed for p in other.points] == [p.seed for p in sweep.points]


@settings(max_examples=25, deadline=None)
@given(
    low=st.floats(0.0, 0.05),
    width=st.floats(0.0, 0.05),
    counts=st.integers(4, 1 << 16),
    samples=st.integers(1, 12),
    seed=st.integers(0, 2**32),
)
@pytest.mark.slow
def test_random_points_lie_in_their_ranges_and_do_not_depend_on_the_sample_count(low, width, counts, samples, seed):
    ranges = {"friction.arm.viscous": [low, low + width], "encoder.counts_per_rev": [4, counts]}
    sweep = resolve_sweep(SweepConfig(base=LUND, mode="random", ranges=ranges, samples=samples, seed=seed))
    assert len(sweep.points) == samples
    for point in sweep.points:
        assert low <= point.config.friction.arm.viscous <= low + width
        assert isinstance(point.config.encoder.counts_per_rev, int)
        assert 4 <= point.config.encoder.counts_per_rev <= counts
    more = resolve_sweep(SweepConfig(base=LUND, mode="random", ranges=ranges, samples=samples + 3, seed=seed))
    assert [p.config for p in more.points[:samples]] == [p.config for p in sweep.points]


def test_a_swept_seed_path_overrides_the_point_seed_of_that_path_only():
    sweep = resolve_sweep(SweepConfig(base=LUND, parameters={"seed": [7], "encoder.noise_std": [1e-4, 2e-4]}))
    assert [p.config.seed for p in sweep.points] == [7, 7]
    assert [p.config.encoder.seed for p in sweep.points] == [p.seed for p in sweep.points]
