"""``furuta-drake diagnose`` end to end on short Drake-simulated logs with no hidden effect."""

import json

from furuta_drake.cli import main
from furuta_drake.diagnosis.report import SPEC_KEYS
from furuta_drake.diagnosis.suite import run_configs
from furuta_drake.results import write_log_csv
from furuta_drake.rig import lund_rig
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import dump_yaml_dataclass


def test_effect_free_logs_give_none_with_every_output_and_identical_reruns(tmp_path):
    rig = lund_rig()
    (tmp_path / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    for name, seed in (("train.csv", 11), ("heldout.csv", 12)):
        write_log_csv(simulate(run_configs(rig, seed, 2.0)["hanging"]), tmp_path / name)
    args = ["diagnose", "--rig", str(tmp_path / "rig.yaml"), "--train", str(tmp_path / "train.csv"),
            "--heldout", str(tmp_path / "heldout.csv"), "--workers", "2"]
    assert main(args + ["--out", str(tmp_path / "a")]) == 0
    report = json.loads((tmp_path / "a" / "report.json").read_text())
    assert list(report)[:len(SPEC_KEYS)] == list(SPEC_KEYS)
    assert report["verdict"] == "none" and report["effects"] == []
    assert len(report["ranking"]) >= 14
    assert report["gap"]["nominal"]["heldout"] < 0.25  # counts: the exact model sits at the encoder's floor
    for name in ("report.md", "config.yaml", "fitted_model.yaml", "residuals.png", "residual_spectra.png"):
        assert (tmp_path / "a" / name).stat().st_size > 0
    assert main(args + ["--out", str(tmp_path / "b")]) == 0
    assert (tmp_path / "a" / "report.json").read_bytes() == (tmp_path / "b" / "report.json").read_bytes()
