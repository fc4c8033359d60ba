"""The example data shipped in the repository's ``data/`` folder: six logs of a real QUBE-Servo 2 and its rig file.

``data/qube-servo2-real/README.md`` gives their provenance, licence, columns and segments. The folder sits beside
the package in a clone (or an editable install) of the repository; nothing else reads outside the repository.
"""

from __future__ import annotations

from pathlib import Path

DATA_DIR = Path(__file__).resolve().parent.parent / "data"
QUBE_REAL_DIR = DATA_DIR / "qube-servo2-real"
QUBE_REAL_RIG = QUBE_REAL_DIR / "rig.yaml"


def qube_real_logs() -> list[Path]:
    """The real QUBE-Servo 2 logs (CSV, voltage input), sorted by file name."""
    return sorted(QUBE_REAL_DIR.glob("*.csv"))


__all__ = ["DATA_DIR", "QUBE_REAL_DIR", "QUBE_REAL_RIG", "qube_real_logs"]
