"""Logs recorded slowly, as a microcontroller records a lab-built rig: the diagnosis reads 50 Hz logs of step and
square-wave commands, and refuses a log that comes near the upright at a rate whose shortest gap window spans more
than twice the horizon the upright's instability allows, naming the rate that would do."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

import benchmarks.independent.simulator as sim
from furuta_drake.diagnosis.gap.metric import make_windows
from furuta_drake.diagnosis.logs.load import RunLog
from furuta_drake.diagnosis.pipeline import diagnose
from furuta_drake.diagnosis.settings import FAST
from furuta_drake.errors import LogError
from furuta_drake.rig import qube_servo2_rig


def qube_log(theta0: float, period: float, seconds: float = 6.0) -> RunLog:
    """A QUBE log at ``period`` [s] swinging gently about ``theta0`` [rad] (0 upright, pi hanging)."""
    t = np.arange(round(seconds / period)) * period
    return RunLog(
        name="slow.csv",
        path="",
        time=t,
        theta=theta0 + 0.05 * np.sin(2 * math.pi * 0.7 * t),
        phi=0.2 * np.sin(2 * math.pi * 0.3 * t),
        input_kind="torque",
        input=np.zeros_like(t),
        sample_period=period,
    )


def test_a_log_near_the_upright_at_too_low_a_rate_is_refused_naming_the_rate_that_would_do():
    rig = qube_servo2_rig()
    a, b, c, d = rig.arm_inertia_total, rig.pendulum_inertia_total, rig.coupling, rig.gravity_torque
    pole = math.sqrt(d * a / (a * b - c**2))  # the upright's unstable pole (sqrt(alpha1)), 16 1/s
    # Windows of 5 samples may span twice the horizon 1.5 / pole: 5 T <= 3 / pole, so the rate must be 5 pole / 3.
    needed = 5 * pole / 3
    with pytest.raises(LogError, match=rf"slow\.csv: at 25 Hz .* log at {needed:.3g} Hz or faster"):
        make_windows([qube_log(0.0, 1 / 25)], rig)
    make_windows([qube_log(0.0, 1 / 30)], rig)  # above the rate: read
    make_windows([qube_log(math.pi, 1 / 25)], rig)  # hanging, the instability plays no part: read


@pytest.mark.slow
def test_50_hz_logs_of_a_geared_rig_under_steps_and_square_waves_are_diagnosed(tmp_path):
    """The independent simulator's geared rig without any effect, recorded at 50 Hz from rest hanging: a voltage
    step that spins the arm up, square waves that swing the pendulum; nothing is found beyond the rig file."""
    rig = dataclasses.replace(sim.geared_like(), sample_period=0.02)
    world = sim.World(rig)
    sim.write_rig_file(rig, tmp_path / "rig.yaml")
    runs = {
        "train_step": sim.RunSpec("step", 5.0, 1, level=0.08),
        "train_square": sim.RunSpec("square", 6.0, 2, level=0.1, square_period=1.5),
        "heldout_square": sim.RunSpec("square", 6.0, 3, level=0.12, square_period=1.0),
    }
    for name, run in runs.items():
        sim.write_log(sim.simulate(world, run), tmp_path / f"{name}.csv")
    diagnosis = diagnose(
        rig=tmp_path / "rig.yaml",
        train=[tmp_path / "train_step.csv", tmp_path / "train_square.csv"],
        heldout=[tmp_path / "heldout_square.csv"],
        settings=FAST,
        workers=1,
    )
    assert diagnosis.verdict == "none"
