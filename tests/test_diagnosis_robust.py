"""``diagnose`` never crashes on valid logs: whatever mix of effects a rig has, a candidate that fails is named
in the ranking and the diagnosis goes on to a verdict and a written report (benchmarks/diagnosis/robustness.py
runs many more, longer cases)."""

import json
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from benchmarks.diagnosis.suite import OUTSIDE_VOCABULARY, SUITE_RIGS, VOCABULARY, run_configs, with_effect
from furuta_drake.diagnosis.pipeline import diagnose
from furuta_drake.diagnosis.report.files import check_report, write_report
from furuta_drake.diagnosis.settings import FAST
from furuta_drake.results import write_log_csv
from furuta_drake.rig import RIGS
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import dump_yaml_dataclass

pytestmark = pytest.mark.slow  # end-to-end runs: `pytest -m "not slow"` leaves them out

DURATION = 1.5  # [s] per log: a train and a held-out hanging run


@settings(max_examples=8, deadline=None, derandomize=True, suppress_health_check=[HealthCheck.too_slow])
@given(
    rig_name=st.sampled_from(SUITE_RIGS),
    effects=st.lists(st.sampled_from(VOCABULARY + (OUTSIDE_VOCABULARY,)), max_size=3, unique=True),
    levels=st.lists(st.floats(0.2, 3.0), min_size=3, max_size=3),
    seed=st.integers(0, 10_000),
)
def test_diagnose_writes_a_report_whatever_the_mix_of_effects(rig_name, effects, levels, seed):
    rig = RIGS[rig_name]()
    with tempfile.TemporaryDirectory() as folder:
        folder = Path(folder)
        (folder / "rig.yaml").write_text(dump_yaml_dataclass(rig))
        for split, run_seed in (("train", seed), ("heldout", seed + 1)):
            config = run_configs(rig, run_seed, DURATION)["hanging"]
            for effect, level in zip(effects, levels):
                config = with_effect(config, effect, level)
            write_log_csv(simulate(config), folder / f"{split}.csv")
        diagnosis = diagnose(
            rig=folder / "rig.yaml",
            train=[folder / "train.csv"],
            heldout=[folder / "heldout.csv"],
            settings=FAST,
            workers=1,
        )
        write_report(folder / "out", diagnosis)
        report = json.loads((folder / "out" / "report.json").read_text())
    check_report(report)
    assert report["verdict"] in (*VOCABULARY, "none", "unexplained")
    assert all(entry["reason"] for entry in report["ranking"] if entry["status"] == "failed")
    assert report["gap"]["nominal"]["heldout"] is not None
