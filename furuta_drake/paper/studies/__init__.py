"""Studies of the paper's open problems (its Sections VI-VII), each comparing the paper's own method with an
extension on the same simulated rig and seed (``furuta-drake reproduce --only beyond``).

Every study of the open problems is a module ``*_study`` of this package with a function ``study(seed: int = 0,
small: bool = False) -> Study``; ``small`` shortens it for the tests and notebooks.

The real-rig studies (``furuta-drake reproduce --only real``) work on the real QUBE-Servo 2 runs instead and live
in :mod:`furuta_drake.real_rig`.
"""

from __future__ import annotations

from dataclasses import dataclass, field


@dataclass
class Study:
    """One study's outcome: ``rows`` of beyond.md (keys: ``metric``, ``paper``, ``extension``, ``unit``,
    ``note``; ``paper`` is the paper's method's figure, ``extension`` ours, None when not applicable),
    ``figures`` ({file stem: matplotlib Figure}), ``logs`` ({name: SimulationResult} worth keeping) and the
    ``summary`` text of what it shows."""

    title: str
    rows: list[dict]
    summary: str
    figures: dict = field(default_factory=dict)
    logs: dict = field(default_factory=dict)
