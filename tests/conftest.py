"""Shared test constants: where the read-only project material lives (``shared/`` beside the clone)."""

from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
SHARED = REPO.parent / "shared"
QUBE_DATA = SHARED / "data" / "qube-servo2-real"
