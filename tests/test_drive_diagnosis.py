"""End to end: logs of the geared rig whose gear has a play of +-0.03 rad (the truth: the package's Drake world with the
drive's backlash), recorded at 50 Hz under a step command of the motor's voltage that reverses the arm, diagnosed
against the rig file that states the same drive rigid. The diagnosis names ``drive_backlash``, its 95 % interval
holds the true half-width, and ``fitted_rig.yaml`` states it as the drive's ``backlash``. The candidates are the
backlash and its look-alike on the arm (Coulomb friction), the detection limits left out, to keep the run short."""

from __future__ import annotations

import json

import pytest

from benchmarks.diagnosis.drives import CASES, RATES, record_case
from furuta_drake.diagnosis.pipeline import diagnose
from furuta_drake.diagnosis.report.files import write_report
from furuta_drake.diagnosis.settings import DiagnosisSettings
from furuta_drake.rig_file import load_rig

pytestmark = pytest.mark.slow

BACKLASH = CASES["backlash_large"].drive["backlash"]  # [rad] the truth's half-width


def test_backlash_of_a_known_half_width_is_found_within_its_interval(tmp_path):
    assert BACKLASH == 0.03
    folder = tmp_path / "case"
    record_case(CASES["backlash_large"], folder, RATES["50Hz"], duration=3.0)
    assert load_rig(folder / "rig.yaml").drive.backlash == 0.0  # the rig file the diagnosis reads: a rigid drive
    diagnosis = diagnose(
        rig=folder / "rig.yaml",
        train=sorted(folder.glob("train_*.csv")),
        heldout=sorted(folder.glob("heldout_*.csv")),
        candidates=["drive_backlash", "arm_coulomb_friction"],
        settings=DiagnosisSettings(detection_limits=False, replay=False),
        workers=1,
    )
    write_report(tmp_path / "report", diagnosis)
    report = json.loads((tmp_path / "report" / "report.json").read_text())
    assert report["effects"] == ["drive_backlash"]
    entry = next(e for e in report["ranking"] if e["effect"] == "drive_backlash")
    low, high = entry["params_ci"]["backlash"]
    assert low <= BACKLASH <= high
    assert high - low < 0.5 * BACKLASH  # an interval that says something
    assert report["gap"]["heldout_reduction"] >= 0.5
    fitted = load_rig(tmp_path / "report" / "fitted_rig.yaml")
    assert fitted.drive.backlash == pytest.approx(entry["params"]["backlash"], rel=1e-5)  # report.json: 6 digits
    assert "drive_backlash" not in (fitted.effects or {})
