"""The rule judged beyond a sensor effect's variance (:meth:`Bootstrap.beyond`): a few counts of noise add the same
variance to every held-out window whatever the model, so beside it a dynamic effect that leaves a fraction of a
count removes a small share of the whole gap; beyond the noise it removes all of what is left."""

import numpy as np
import pytest

from furuta_drake.diagnosis.selection.rule import MARGIN, Bootstrap, decide

WINDOWS = 60
NOISE_COUNTS = 1.3  # white noise's standard deviation [counts]
EFFECT_COUNTS = 0.5  # what an inertia error alone leaves [counts RMS]


def _windows(mean: float, seed: int) -> np.ndarray:
    """Per-window excess squared residuals [counts^2] scattered about ``mean`` (a chi-square-like spread)."""
    rng = np.random.default_rng(seed)
    return mean * rng.gamma(50.0, 1.0 / 50.0, WINDOWS)


def test_an_effect_under_noise_fails_the_margin_on_the_whole_gap_and_passes_beyond_the_noise():
    noise = np.full(WINDOWS, NOISE_COUNTS**2)
    without = noise + _windows(EFFECT_COUNTS**2, 1)  # the model missing the effect
    with_it = noise + _windows(1e-4, 2)  # the model holding it: the noise alone is left
    whole = Bootstrap(WINDOWS, 500, 0)
    evidence = whole.evidence(without, with_it)
    # 1 - 1.3 / sqrt(1.3^2 + 0.5^2) = 6.7 %: below the margin, however clear the effect is.
    expected = 1.0 - NOISE_COUNTS / np.hypot(NOISE_COUNTS, EFFECT_COUNTS)
    assert evidence.reduction == pytest.approx(expected, abs=0.01)
    assert evidence.reduction < MARGIN and not decide(evidence)
    beyond = whole.beyond(noise).evidence(without, with_it)
    assert beyond.reduction > 0.95 and decide(beyond)
    assert whole.beyond(noise).at_floor(with_it) and not whole.at_floor(with_it)


def test_the_whole_gap_is_read_without_the_sensor_and_beyond_nothing_is_the_plain_rule():
    noise = np.full(WINDOWS, NOISE_COUNTS**2)
    before, after = noise + _windows(0.4, 3), noise + _windows(0.1, 4)
    plain = Bootstrap(WINDOWS, 300, 5)
    judged = plain.beyond(noise)
    assert judged.whole().evidence(before, after) == plain.evidence(before, after)
    assert plain.beyond(np.zeros(WINDOWS)).evidence(before, after) == plain.evidence(before, after)
    # Beyond the noise the gaps are those of the excess alone.
    assert judged.evidence(before, after).heldout_gap == pytest.approx(np.sqrt(np.mean(after - noise)))
    # A difference of two models' excess does not depend on a variance both carry.
    assert judged.excess_difference_interval(before, after) == plain.excess_difference_interval(before, after)


@pytest.mark.slow
def test_an_inertia_error_under_a_count_and_a_half_of_noise_is_named_beside_the_noise(tmp_path):
    """The Lund rig with a pendulum 10 % heavier and an arm 7.5 % lighter than its rig file, its encoders read with
    white noise of 1.5 counts: on the whole gap the inertia error removes too small a share to pass the margin
    (the noise is most of it); judged beyond the noise, which passes its signature test, it is named, with the
    coupling and gravity constants (m_p L l and m_p g l) 10 % above the rig file's."""
    from benchmarks.diagnosis.suite import run_configs, with_effect
    from furuta_drake.diagnosis.logs.writers import write_log
    from furuta_drake.diagnosis.pipeline import diagnose
    from furuta_drake.rig import lund_rig
    from furuta_drake.simulate import simulate
    from furuta_drake.yamlio import dump_yaml_dataclass

    rig_path = tmp_path / "rig.yaml"
    rig_path.write_text(dump_yaml_dataclass(lund_rig()))
    paths = {}
    for part, seed in (("train", 3), ("heldout", 4)):
        for run, config in run_configs(lund_rig(), seed, 4.0).items():
            result = simulate(with_effect(with_effect(config, "measurement_noise", 1.0), "inertia_mismatch", 0.5))
            path = tmp_path / f"{part}_{run}.csv"
            angles = {"theta": result.measured[:, 0], "phi": result.measured[:, 1]}
            write_log(path, {"time": result.time, "torque": result.torque, **angles})
            paths.setdefault(part, []).append(path)
    diagnosis = diagnose(
        rig=rig_path,
        train=paths["train"],
        heldout=paths["heldout"],
        candidates=["inertia_mismatch", "input_delay", "arm_viscous_friction", "measurement_noise"],
        workers=2,
    )
    assert {"inertia_mismatch", "measurement_noise"} <= set(diagnosis.effects)
    assert "beyond the variance measurement_noise adds" in diagnosis.choice
    inertia = next(step for step in diagnosis.steps if step.effect == "inertia_mismatch").params
    scales = {key.rsplit(".", 1)[-1]: value for key, value in inertia.items()}
    assert scales["coupling_scale"] == pytest.approx(1.1, rel=0.05)
    assert scales["gravity_scale"] == pytest.approx(1.1, rel=0.05)
    # Every reduction over nominal reads the whole gap: the predictions alone leave the noise.
    assert diagnosis.gap.heldout_reduction < 0.5
