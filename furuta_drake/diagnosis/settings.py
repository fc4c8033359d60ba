"""How much work a diagnosis does: the one place its sizes and seeds are set (recorded in ``config.yaml``)."""

from __future__ import annotations

from dataclasses import dataclass

from furuta_drake.errors import ConfigError

MAX_EFFECTS = 5  # the most effects one selection accepts (the vocabulary's largest independent set a rig needs)


@dataclass(frozen=True)
class DiagnosisSettings:
    """Sizes and seeds of a diagnosis; the defaults are the command's. Smaller values trade precision for speed
    (the tests' property checks use them); none changes the rule that accepts an effect.

    Attributes
    ----------
    fit_windows : windows of the train logs a least-squares fit uses (evenly drawn, seeded).
    start_windows : of those, the windows that rank a fit's starts.
    max_nfev : cost evaluations of one least-squares fit (Jacobians not counted).
    bootstrap : paired resamples of the held-out windows behind every reduction's bounds.
    interval_resamples : resamples of the fit windows behind every parameter interval.
    max_effects : effects that change the predictions accepted one after another at the most (a rig far from its
        rig file may need four or five at once; each further step must still bring held-out evidence).
    detection_limits : whether to find the detection limit of every effect not accepted.
    replay : whether the headline held-out figures are replayed in Drake (else: the surrogate's).
    screen : whether each forward step screens its candidates and fits fully only those within reach of the best
        (else every candidate is fitted fully).
    seed : seed of every random draw (windows, resamples).
    """

    fit_windows: int = 40
    start_windows: int = 16
    max_nfev: int = 20
    bootstrap: int = 1000
    interval_resamples: int = 400
    max_effects: int = MAX_EFFECTS
    detection_limits: bool = True
    replay: bool = True
    screen: bool = True
    seed: int = 0

    def validate(self) -> None:
        for name in ("fit_windows", "start_windows", "max_nfev", "bootstrap", "interval_resamples", "max_effects"):
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, int) or value < 1:
                raise ConfigError(f"diagnosis setting {name} must be a positive integer, got {value!r}")
        if self.max_effects > MAX_EFFECTS:
            raise ConfigError(f"diagnosis setting max_effects is at most {MAX_EFFECTS}, got {self.max_effects}")


FAST = DiagnosisSettings(
    fit_windows=10, start_windows=4, max_nfev=4, bootstrap=200, interval_resamples=100, detection_limits=False
)
"""Settings for quick checks (a smoke test of a pipeline change, property tests): every stage runs, briefly."""
