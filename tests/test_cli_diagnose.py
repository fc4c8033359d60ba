"""``furuta-drake diagnose`` end to end on short Drake-simulated logs with no hidden effect."""

import json
from types import SimpleNamespace

import pytest

from benchmarks.diagnosis.suite import VOCABULARY, run_configs
from furuta_drake.cli import diagnosis_summary, main
from furuta_drake.diagnosis.result import SPEC_KEYS, Diagnosis, RankedCandidate
from furuta_drake.results import write_log_csv
from furuta_drake.rig import lund_rig
from furuta_drake.rig_file import load_rig
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import dump_yaml_dataclass


@pytest.mark.slow
def test_effect_free_logs_give_none_with_every_output_and_identical_reruns(tmp_path):
    rig = lund_rig()
    (tmp_path / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    for name, seed in (("train.csv", 11), ("heldout.csv", 12)):
        write_log_csv(simulate(run_configs(rig, seed, 2.0)["hanging"]), tmp_path / name)
    args = [
        "diagnose",
        "--rig",
        str(tmp_path / "rig.yaml"),
        "--train",
        str(tmp_path / "train.csv"),
        "--heldout",
        str(tmp_path / "heldout.csv"),
        "--workers",
        "2",
    ]
    assert main(args + ["--out", str(tmp_path / "a")]) == 0
    report = json.loads((tmp_path / "a" / "report.json").read_text())
    assert list(report)[: len(SPEC_KEYS)] == list(SPEC_KEYS)
    assert report["verdict"] == "none" and report["effects"] == []
    assert len(report["ranking"]) >= 14
    assert report["gap"]["nominal"]["heldout"] < 0.25  # counts: the exact model sits at the encoder's floor
    # A none verdict states what these logs could not have missed: a detection limit for every effect.
    assert report["steps"] == [] and [limit["effect"] for limit in report["detection_limits"]] == list(VOCABULARY)
    # Nothing pushes the simulated rig: the disturbance read is the encoder's share, a fraction of a per cent of the
    # torque limit, and the fitted rig file carries it.
    disturbance = report["disturbance"]
    assert 0.0 <= disturbance["ci"][0] < disturbance["arm_torque_rms"] < disturbance["ci"][1] < 0.01 * rig.torque_limit
    fitted = load_rig(tmp_path / "a" / "fitted_rig.yaml").disturbance
    assert fitted.arm_torque_rms == pytest.approx(disturbance["arm_torque_rms"], rel=1e-5)
    assert "Read as a torque on the arm" in (tmp_path / "a" / "report.md").read_text()
    for name in (
        "report.md",
        "report.html",
        "config.yaml",
        "fitted_model.yaml",
        "fitted_rig.yaml",
        "residuals.png",
        "residual_spectra.png",
    ):
        assert (tmp_path / "a" / name).stat().st_size > 0
    assert main(args + ["--out", str(tmp_path / "b")]) == 0
    assert (tmp_path / "a" / "report.json").read_bytes() == (tmp_path / "b" / "report.json").read_bytes()


@pytest.mark.slow
def test_ctrl_c_leaves_no_output_and_says_so(tmp_path):
    """Ctrl-C in the middle of the fits (SIGINT to the process group, as a terminal sends it): exit 130, one
    line saying nothing was written, no traceback from the main process or its workers, and neither the output
    directory nor a hidden staging directory beside it."""
    import os
    import signal
    import subprocess
    import sys
    import time

    rig = lund_rig()
    (tmp_path / "rig.yaml").write_text(dump_yaml_dataclass(rig))
    # 16 s of log: the diagnosis takes about three times the 6 s before the interrupt (a 4 s log's can end sooner)
    write_log_csv(simulate(run_configs(rig, 21, 16.0)["hanging"]), tmp_path / "train.csv")
    process = subprocess.Popen(
        [
            sys.executable,
            "-m",
            "furuta_drake.cli",
            "diagnose",
            "--rig",
            str(tmp_path / "rig.yaml"),
            "--train",
            str(tmp_path / "train.csv"),
            "--out",
            str(tmp_path / "out"),
            "--workers",
            "2",
        ],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        start_new_session=True,
        # a Ctrl-C's default action, whatever the test runner's: a shell's background job starts with SIGINT
        # ignored, and the child would inherit that
        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL),
    )
    time.sleep(6.0)  # imports, loading and the first fits
    assert process.poll() is None, process.communicate()
    os.killpg(process.pid, signal.SIGINT)
    _, stderr = process.communicate(timeout=60)
    assert process.returncode == 130
    assert "interrupted; no result was written" in stderr and "Traceback" not in stderr
    assert sorted(p.name for p in tmp_path.iterdir()) == ["rig.yaml", "train.csv"]


def test_the_closing_line_counts_failed_candidates_and_not_screened_ones():
    """A candidate its step's screen left behind was not fitted further; it did not fail."""

    def row(effect, status):
        return RankedCandidate(effect, {}, 2.0, 0.1, 0.0, status=status, reason="why")

    gap = SimpleNamespace(nominal={"heldout": 3.43}, with_effects={"heldout": 1.13}, heldout_reduction=0.67)
    ranking = [row("inertia_mismatch", "ok"), row("arm_spring", "screened"), row("actuator_lag", "screened")]
    diagnosis = Diagnosis("inertia_mismatch", ["inertia_mismatch"], gap, ranking, localization={})
    line = diagnosis_summary(diagnosis, "out")
    assert line == (
        "verdict: inertia_mismatch (effects: inertia_mismatch); held-out gap 3.43 -> 1.13 counts (67% reduction); "
        "report in out"
    )
    diagnosis.ranking = [*ranking, row("input_delay", "failed")]
    assert "; 1 candidate(s) failed, listed in the report;" in diagnosis_summary(diagnosis, "out")
