"""The spread of a jittering input delay read from the residuals' variance by likelihood
(:mod:`furuta_drake.diagnosis.selection.jitter_fit`): found where delays are drawn anew every sample, refused where the
delay is fixed or the extra variance has no jitter's structure."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
from test_form_starts import nominal_windows  # noqa: F401  (the fixture)

from furuta_drake.diagnosis.gap.metric import evaluate_gap
from furuta_drake.diagnosis.selection.jitter_fit import spread_by_likelihood
from furuta_drake.diagnosis.selection.rule import FLOOR_COUNTS
from furuta_drake.effects.surrogate import Model, _delayed_command, predict_windows
from furuta_drake.effects.vocabulary import Effect, apply_effects
from furuta_drake.rig import encoder_resolution

PERIOD = 1e-3  # [s]
DELAY, SPREAD = 5e-3, 2e-3  # [s]
BOUNDS = (0.25 * PERIOD, 5.0 * PERIOD)  # the jittering form's spread bounds
COUNTS = 4096  # the Lund rig's encoder


COPIES = 16  # independent draws of the fixture's windows: the variance's structure needs windows to show


def _copies(windows):
    """``windows`` COPIES times over, each copy to be measured under its own draws."""
    fields = ("logs", "horizons", "starts", "initial_states", "measured", "arm_paths")
    return dataclasses.replace(windows, **{name: list(getattr(windows, name)) * COPIES for name in fields})


def _measured(rig, windows, spread: float, noise: float, seed: int, delay: float = DELAY, counts: int = COUNTS):
    """``windows`` (:func:`_copies`) whose angles are the nominal rig's response to the logged command read at a
    delay drawn anew every sample, uniform on ``delay`` +- sqrt(3) ``spread`` (0: fixed), plus white noise of
    ``noise`` counts, read by an encoder of ``counts`` per revolution."""
    rng = np.random.default_rng(seed)
    count = encoder_resolution(counts)
    (batch,) = windows.batches()
    drawn = delay + math.sqrt(3.0) * spread * rng.uniform(-1.0, 1.0, batch.command.size)
    samples = np.arange(batch.command.size)[None, :]
    applied = _delayed_command(batch.command, samples, 0.0, PERIOD, PERIOD, drawn[None, :])[0]
    angles = predict_windows(Model.from_rig(rig), batch.initial_states, applied, batch.starts, batch.horizon, PERIOD, 1)
    angles = np.round((angles + noise * count * rng.standard_normal(angles.shape)) / count) * count
    measured = [angles[:, :, batch.bounds[j] : batch.bounds[j + 1]] for j in range(len(batch.members))]
    return dataclasses.replace(windows, measured=measured)


def _evidence(rig, windows):
    """The likelihood's spread of a jittering delay of the true mean, from a spread of 1.5 samples."""
    model = apply_effects(Model.from_rig(rig), {"input_delay": Effect("jitter", (DELAY, 1.5 * PERIOD))})
    return spread_by_likelihood(model, windows, COUNTS, BOUNDS, 200, 0)


def test_a_delay_drawn_every_sample_is_credited_with_its_spread(nominal_windows):  # noqa: F811
    rig, _, windows = nominal_windows
    windows = _copies(windows)
    evidence = _evidence(rig, _measured(rig, windows, SPREAD, 0.0, 1))
    assert evidence.credited
    low, high = np.percentile(evidence.samples, [2.5, 97.5])
    assert low <= SPREAD <= high


def test_a_fixed_delay_is_not_credited_with_a_spread(nominal_windows):  # noqa: F811
    rig, _, windows = nominal_windows
    windows = _copies(windows)
    assert not _evidence(rig, _measured(rig, windows, 0.0, 0.0, 1)).credited


def test_white_noise_of_the_jitters_size_is_not_credited_as_a_spread(nominal_windows):  # noqa: F811
    """Extra variance without the jitter's structure: white noise on both angles whose variance is the mean
    squared residual the true jitter leaves above the rounding (measured on a draw of it here)."""
    rig, _, windows = nominal_windows
    windows = _copies(windows)
    model = apply_effects(Model.from_rig(rig), {"input_delay": Effect("fixed", (DELAY,))})
    jittered = evaluate_gap(model, _measured(rig, windows, SPREAD, 0.0, 1), COUNTS).gap
    assert jittered > 2 * FLOOR_COUNTS  # the jitter leaves a residual the rule resolves
    assert not _evidence(rig, _measured(rig, windows, 0.0, jittered, 1)).credited
