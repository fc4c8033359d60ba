"""A rotor rattling in its play, refined window by window (the metric's
:func:`~furuta_drake.diagnosis.gap.metric.projected_residuals`): with the drive's true model every window's twist is
found, and the gap is least at the true play.

The log is the package's Drake world of the shipped geared rig (a rotor of about half the arm side) with a play of
0.02 rad either way, balancing under its LQR at 1 kHz: the rotor crosses the play back and forth between the flanks,
so most windows start with the twist anywhere inside it, at a rate the arm's path does not show."""

import dataclasses

import numpy as np
import pytest

from furuta_drake.config import SimulationConfig
from furuta_drake.diagnosis.gap.metric import evaluate_gap, make_windows
from furuta_drake.diagnosis.logs.load import load_logs
from furuta_drake.diagnosis.logs.writers import write_log
from furuta_drake.effects.vocabulary import rig_model
from furuta_drake.rig import geared_rig
from furuta_drake.rig_file import load_rig
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import dump_yaml_dataclass

PLAY = 0.02  # [rad]


@pytest.fixture(scope="module")
def rattling(tmp_path_factory):
    """(the rig file's nominal model, the balancing log's windows, its counts per revolution)."""
    folder = tmp_path_factory.mktemp("rattling")
    rig = geared_rig().replace(sample_period=0.001)
    (folder / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    truth = rig.replace(drive=dataclasses.replace(rig.drive, backlash=PLAY))
    config = dataclasses.replace(SimulationConfig.from_rig(truth), duration=3.0, initial_state=[0.03, 0.0, 0.0, 0.0])
    result = simulate(config)
    columns = {"time": result.time, "theta": result.measured[:, 0], "phi": result.measured[:, 1]}
    write_log(folder / "balance.csv", {**columns, "torque": result.torque})
    rig = load_rig(folder / "rig.yaml")
    logs = load_logs([folder / "balance.csv"], rig, folder / "rig.yaml")
    return rig_model(rig), make_windows(logs, rig), rig.counts_per_rev


def test_with_the_true_play_no_window_keeps_a_count_of_error(rattling):
    """The true model predicts every window within a count RMS (excess over the encoder's floor under 1 count^2),
    against several counts^2 without the play."""
    nominal, windows, counts = rattling
    exact = evaluate_gap(nominal.replace(drive_backlash=PLAY), windows, counts)
    rigid = evaluate_gap(nominal, windows, counts)
    assert np.max(exact.per_window) < 1.0
    assert np.median(rigid.per_window) > 4.0


@pytest.mark.parametrize("wrong", [0.8 * PLAY, 1.2 * PLAY])
def test_the_gap_is_least_at_the_true_play(rattling, wrong):
    nominal, windows, counts = rattling
    at_truth = evaluate_gap(nominal.replace(drive_backlash=PLAY), windows, counts).gap
    assert at_truth < evaluate_gap(nominal.replace(drive_backlash=wrong), windows, counts).gap
