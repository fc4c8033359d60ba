"""Sim-to-real gap diagnosis (``docs/diagnose.md``), one module a stage: logs (load) -> gap (windows and the
metric, on the surrogate) -> fit (candidates) -> select (the held-out rule) -> detection (limits) -> replay (Drake)
-> localize -> report; ``pipeline.diagnose`` runs them and returns a ``result.Diagnosis``."""
