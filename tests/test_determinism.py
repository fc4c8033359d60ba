"""Determinism of ``furuta-drake simulate``: the same config and seed give byte-identical log.csv
and summary.json, in this process and in a fresh one with another hash seed; another seed gives another run.

The config exercises everything the seed reaches: the multisine excitation (drawn from the seed), encoder
noise, Dahl friction on the arm, and the HG and VFE + Dahl observers side by side on the same measurements.
"""

import json
import os
import subprocess
import sys

import numpy as np
import pytest
from conftest import REPO

from furuta_drake.cli import main

CONFIG = """\
controller: {velocity_source: vfe}
observers: {run: [hg, vfe]}
friction:
  arm: {model: dahl, coulomb_pos: 0.015, coulomb_neg: 0.015, sigma0: 10.0}
encoder: {noise_std: 1.0e-4, seed: 7}
excitation: {torque_rms: 0.02}
duration: 0.4
"""
FILES = ("log.csv", "summary.json")


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Seed 1 in this process, seed 1 in a subprocess (another PYTHONHASHSEED), seed 2 in this process."""
    root = tmp_path_factory.mktemp("determinism")
    config = root / "config.yaml"
    config.write_text(CONFIG)

    def argv(seed, name):
        return ["simulate", "--config", str(config), "--seed", str(seed), "--out", str(root / name)]

    assert main(argv(1, "first")) == 0
    env = dict(
        os.environ,
        PYTHONHASHSEED="12345",
        MPLBACKEND="Agg",
        PYTHONPATH=os.pathsep.join(filter(None, [str(REPO), os.environ.get("PYTHONPATH")])),
    )
    subprocess.run(
        [sys.executable, "-m", "furuta_drake.cli", *argv(1, "again")],
        cwd=root,
        env=env,
        check=True,
        capture_output=True,
        timeout=120,
    )
    assert main(argv(2, "other")) == 0
    return {name: {file: (root / name / file).read_bytes() for file in FILES} for name in ("first", "again", "other")}


@pytest.mark.slow
@pytest.mark.parametrize("file", FILES)
def test_same_config_and_seed_give_byte_identical_files_across_processes(runs, file):
    assert runs["first"][file] == runs["again"][file]


def test_another_seed_gives_another_excitation_and_another_run(runs):
    first, other = (
        np.loadtxt(runs[name]["log.csv"].decode().splitlines(), delimiter=",", skiprows=1)
        for name in ("first", "other")
    )
    assert first.shape == other.shape == (400, 8)
    # Same start (initial state, encoder noise seed) ...
    np.testing.assert_array_equal(first[0, 2:], other[0, 2:])
    # ... but the seed draws another multisine: the torques differ by a good part of its 0.02 N m RMS.
    torque_difference_rms = np.sqrt(np.mean((first[:, 1] - other[:, 1]) ** 2))
    assert torque_difference_rms > 0.005
    assert not np.array_equal(first[:, 4:], other[:, 4:])
    summaries = [json.loads(runs[name]["summary.json"]) for name in ("first", "other")]
    assert [s["seed"] for s in summaries] == [1, 2]
    assert summaries[0]["vfe_velocity_mse"] != summaries[1]["vfe_velocity_mse"]
