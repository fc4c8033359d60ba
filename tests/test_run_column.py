"""Many runs in one file (``--run-column``): each run is a log with its own time base, named ``file[run=k]``,
checked on its own, held out whole, and diagnosed exactly as the same runs in separate files."""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml
from conftest import QUBE_DATA
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.diagnosis.gap.split import fold_split, split_heldout
from furuta_drake.diagnosis.logs.format import LogFormat
from furuta_drake.diagnosis.logs.load import load_logs, load_runs
from furuta_drake.diagnosis.logs.writers import write_log
from furuta_drake.errors import ConfigError, LogError
from furuta_drake.rig_file import load_rig

QUBE_RIG = QUBE_DATA / "rig.yaml"
RUNS = {  # run value -> a real 250 Hz QUBE log
    7: QUBE_DATA / "swingup_250Hz_5s_0414.csv",
    8: QUBE_DATA / "swingup_250Hz_7s_negdir.csv",
    9: QUBE_DATA / "swingup_250Hz_10s_a.csv",
}
BY_TRIAL = LogFormat(columns={"time": "time"}, run_column="trial")  # an MCAP log's time field, not its log_time


def read_csv(path) -> dict[str, np.ndarray]:
    data = np.genfromtxt(path, delimiter=",", names=True)
    return {name: data[name] for name in data.dtype.names}


def trial_table(runs: dict[float, dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    """The runs stacked into one long table with a 'trial' column, each run keeping its own time base."""
    names = list(next(iter(runs.values())))
    table = {name: np.concatenate([run[name] for run in runs.values()]) for name in names}
    table["trial"] = np.concatenate([np.full(run["time"].size, value, float) for value, run in runs.items()])
    return table


@pytest.fixture(scope="module")
def rig():
    return load_rig(QUBE_RIG)


@pytest.fixture(scope="module")
def raw():
    return {value: read_csv(path) for value, path in RUNS.items()}


@pytest.mark.parametrize("suffix", [".csv", ".parquet", ".mcap"])
def test_a_trial_table_reads_as_the_runs_in_separate_files(tmp_path, rig, raw, suffix):
    table = write_log(tmp_path / f"trials{suffix}", trial_table(raw))
    runs = load_runs(table, rig, QUBE_RIG, BY_TRIAL)
    assert [log.name for log in runs] == [f"trials{suffix}[run={value}]" for value in RUNS]
    for log, path in zip(runs, RUNS.values()):
        (alone,) = load_runs(path, rig, QUBE_RIG)
        for a, b in ((log.time, alone.time), (log.theta, alone.theta), (log.phi, alone.phi), (log.input, alone.input)):
            np.testing.assert_array_equal(a, b)
        assert log.sample_period == alone.sample_period and log.ignored_columns == ()
    # The runs are views of one array per signal: no copy of the table per run.
    assert all(np.shares_memory(runs[0].theta.base, log.theta) for log in runs)


def test_interleaved_rows_are_grouped_by_run_keeping_their_order(tmp_path, rig, raw):
    table = trial_table(raw)
    order = np.argsort(np.concatenate([np.arange(run["time"].size) for run in raw.values()]), kind="stable")
    interleaved = write_log(tmp_path / "mixed.csv", {name: values[order] for name, values in table.items()})
    contiguous = write_log(tmp_path / "trials.csv", table)
    for a, b in zip(load_runs(interleaved, rig, QUBE_RIG, BY_TRIAL), load_runs(contiguous, rig, QUBE_RIG, BY_TRIAL)):
        np.testing.assert_array_equal(a.theta, b.theta)
        assert a.name.replace("mixed", "trials") == b.name


@settings(max_examples=25, deadline=None)
@given(st.lists(st.sampled_from([-2.0, 0.0, 3.0, 1e6, 0.5]), min_size=3, max_size=40))
def test_every_row_lands_in_its_run_in_file_order(values):
    from furuta_drake.diagnosis.logs.run_column import split_runs

    run_values = np.array(values)
    data = np.column_stack([np.arange(run_values.size), run_values])
    grouped, runs, where = split_runs(run_values, data, lambda row: str(row))
    assert sum(b - a for _, a, b in runs) == run_values.size
    assert [label for label, _, _ in runs] == list(dict.fromkeys(repr(v) if v % 1 else str(int(v)) for v in values))
    for _, a, b in runs:
        rows = grouped[a:b, 0].astype(int)
        assert np.all(np.diff(rows) > 0) and np.all(run_values[rows] == grouped[a, 1])
        assert [where(k) for k in range(a, b)] == [str(r) for r in rows]


def test_bad_runs_name_the_file_and_the_run(tmp_path, rig, raw):
    table = trial_table(raw)
    with pytest.raises(LogError, match=r"trials\.csv:1: no run column 'trial' \(--run-column; the file has: time"):
        load_runs(
            write_log(tmp_path / "trials.csv", {k: v for k, v in table.items() if k != "trial"}),
            rig,
            QUBE_RIG,
            BY_TRIAL,
        )
    backwards = {k: v.copy() for k, v in table.items()}
    row = raw[7]["time"].size + 100  # inside run 8
    backwards["time"][row] = backwards["time"][row - 2]
    with pytest.raises(LogError, match=rf"back\.csv:{row + 2} \(run=8\): column 'time': .* goes back from"):
        load_runs(write_log(tmp_path / "back.csv", backwards), rig, QUBE_RIG, BY_TRIAL)
    short = trial_table({**raw, 10: {k: v[:2] for k, v in raw[7].items()}})
    with pytest.raises(LogError, match=r"short\.csv:\d+ \(run=10\): run 10 has only 2 samples"):
        load_runs(write_log(tmp_path / "short.csv", short), rig, QUBE_RIG, BY_TRIAL)
    with pytest.raises(ConfigError, match="--run-column: 'theta' is read as a signal column"):
        LogFormat.parse(run_column="theta")


def test_held_out_data_are_whole_runs(tmp_path, rig, raw):
    table = trial_table({value + 10 * k: run for k in range(2) for value, run in raw.items()})  # six runs
    logs = load_logs([write_log(tmp_path / "trials.csv", table)], rig, QUBE_RIG, BY_TRIAL)
    train, heldout, note = split_heldout(logs)
    # 30 % of six runs is two, one from the middle of each half: runs 2 and 5 of the file (values 8 and 18).
    assert [log.name for log in heldout] == ["trials.csv[run=8]", "trials.csv[run=18]"]
    assert {log.name for log in train} | {log.name for log in heldout} == {log.name for log in logs}
    assert all(log.time.size == next(r for r in logs if r.name == log.name).time.size for log in train + heldout)
    folds = [fold_split(logs, 3, fold, rig)[1] for fold in range(3)]
    assert sorted(log.name for fold in folds for log in fold) == sorted(log.name for log in logs)


@pytest.mark.slow
def test_a_trial_table_gives_the_report_of_the_runs_in_separate_files(tmp_path, raw, fast_cli_diagnoses):
    """Both diagnoses run with the same brief sizes: a run read into the wrong log, shifted or cut would change
    every fitted and bootstrapped figure of the report, whatever the sizes."""
    from furuta_drake.cli import main

    (tmp_path / "apart").mkdir()
    table = write_log(tmp_path / "trials.csv", trial_table(raw))
    apart = {value: write_log(tmp_path / "apart" / f"run{value}.csv", run) for value, run in raw.items()}
    common = ["diagnose", "--rig", str(QUBE_RIG), "--workers", "1"]
    assert main(common + ["--train", str(table), "--run-column", "trial", "--out", str(tmp_path / "a")]) == 0
    # The table's held-out run (the middle one of three) given as a held-out file:
    separate = ["--train", str(apart[7]), str(apart[9]), "--heldout", str(apart[8])]
    assert main(common + separate + ["--out", str(tmp_path / "b")]) == 0
    text = (tmp_path / "a" / "report.json").read_text()
    for value in RUNS:
        text = text.replace(f"trials.csv[run={value}]", f"run{value}.csv")
    a, b = json.loads(text), json.loads((tmp_path / "b" / "report.json").read_text())
    assert "run8.csv" in a.pop("holdout") and b.pop("holdout") == "held-out logs: run8.csv"
    assert a == b
    record = yaml.safe_load((tmp_path / "a" / "config.yaml").read_text())["options"]["log_format"]
    assert record["run_column"] == "trial"


def test_a_run_too_short_for_a_gap_window_exits_2_naming_it(tmp_path, raw, capsys):
    from furuta_drake.cli import main

    table = trial_table({**raw, 10: {k: v[:20] for k, v in raw[7].items()}})
    path = write_log(tmp_path / "trials.csv", table)
    args = ["diagnose", "--rig", str(QUBE_RIG), "--train", str(path), "--run-column", "trial"]
    assert main(args + ["--out", str(tmp_path / "out")]) == 2
    assert "trials.csv[run=10]: 20 samples" in capsys.readouterr().err
