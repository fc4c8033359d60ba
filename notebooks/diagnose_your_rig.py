# ---
# jupyter:
#   jupytext:
#     text_representation:
#       extension: .py
#       format_name: percent
#   kernelspec:
#     display_name: Python 3
#     language: python
#     name: python3
# ---

# %% [markdown]
# # Diagnose your own rig, start to finish
# A tutorial for someone with their own Furuta pendulum and their own logs. We pretend to be a lab with a
# QUBE-Servo 2 that logs the way Quanser's software does: the arm is called `theta`, the pendulum `alpha`, the
# voltage `vm`, time `t`, and the angles are in degrees. (The data are the project's real QUBE recordings,
# `data/qube-servo2-real/`, renamed and converted.) The steps: write the log, start a rig file from the template,
# check its constants against the bench, diagnose, read the report, and simulate the corrected model.
# Every step has a command-line twin, given in the text. `FURUTA_NOTEBOOK_SMALL=1` (set by the tests) tries four
# candidates with short fits instead of the whole vocabulary.

# %%
import os
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from furuta_drake.data import QUBE_REAL_DIR
from furuta_drake.diagnosis.logs.format import LogFormat
from furuta_drake.diagnosis.logs.writers import write_log
from furuta_drake.diagnosis.pipeline import diagnose
from furuta_drake.diagnosis.report.files import write_report
from furuta_drake.diagnosis.settings import FAST, DiagnosisSettings
from furuta_drake.rig import qube_servo2_rig
from furuta_drake.rig_file import format_rig_check, load_rig, rig_template

SMALL = bool(os.environ.get("FURUTA_NOTEBOOK_SMALL"))
WORK = Path(tempfile.mkdtemp(prefix="your_rig_"))

# %% [markdown]
# ## 1. Your logs, as your lab writes them
# One run per file. Here: two swing-ups to fit on, and a third swing-up plus the hanging chirp to judge on.


# %%
def lab_log(name: str) -> Path:
    """One of the project's QUBE logs, written the way the lab's software writes it: its names, degrees."""
    table = np.genfromtxt(QUBE_REAL_DIR / name, delimiter=",", names=True)
    columns = {
        "t": table["time"],
        "vm": table["voltage"],
        "alpha": np.degrees(table["theta"]),
        "theta": np.degrees(table["phi"]),
    }
    return write_log(WORK / name, columns)


train = [lab_log("swingup_250Hz_10s_a.csv"), lab_log("swingup_250Hz_5s_0414.csv")]
heldout = [lab_log("swingup_250Hz_7s_negdir.csv"), lab_log("chirp_10to0Hz_pos1p5V_250Hz_10s.csv")]
print((WORK / "swingup_250Hz_10s_a.csv").read_text().splitlines()[:3])

# %% [markdown]
# The mapping says which of the lab's columns is which, and the unit of the angles
# (`--columns time=t,theta=alpha,phi=theta,voltage=vm --angle-unit deg` on the command line):

# %%
log_format = LogFormat.parse("time=t,theta=alpha,phi=theta,voltage=vm", "deg")

# %% [markdown]
# ## 2. A rig file
# `furuta-drake rig --template qube_servo2 > my_rig.yaml` writes this, every key explained. Edit the values to
# your rig's. Ours counts the pendulum the other way from furuta-drake's convention (near the upright a positive
# arm torque must give a negative pendulum acceleration), so it says `theta_direction: -1`: without it the
# diagnosis stops and names that key rather than "diagnosing" a flipped sign.

# %%
template = rig_template(qube_servo2_rig(), "my QUBE-Servo 2")
print("\n".join(template.splitlines()[:14]))
rig_text = template.replace("theta_direction: 1", "theta_direction: -1").replace(
    "sample_period: 0.002", "sample_period: 0.004"
)
rig_path = WORK / "my_rig.yaml"
rig_path.write_text(rig_text)

# %% [markdown]
# ## 3. Check the constants on the bench
# `furuta-drake rig --check my_rig.yaml`. Hold the arm and let the pendulum swing a little: its period must match
# the "arm held" line. A few percent off is an inertia error the diagnosis will find; a factor of two is a wrong
# key.

# %%
print(format_rig_check(load_rig(rig_path), str(rig_path)))

# %% [markdown]
# ## 4. Diagnose
# `furuta-drake diagnose --rig my_rig.yaml --train ... --heldout ... --columns ... --angle-unit deg --out report`.
# Candidates are fitted on the train logs only; every held-out figure comes from the held-out logs.

# %%
settings = FAST if SMALL else DiagnosisSettings()
candidates = ["inertia_mismatch", "input_delay", "actuator_lag", "arm_viscous_friction"] if SMALL else None
diagnosis = diagnose(
    rig=rig_path, train=train, heldout=heldout, log_format=log_format, candidates=candidates, settings=settings
)
write_report(WORK / "report", diagnosis)
print(f"verdict: {diagnosis.verdict}; effects: {diagnosis.effects}")
print(diagnosis.choice)

# %% [markdown]
# ## 5. Read the report
# `report.md` and `report.html` in the output folder hold all of this; here the key parts from Python.
# The gap is the RMS of the k-step prediction error in encoder counts, beyond the encoder's own rounding.

# %%
gap = diagnosis.gap
print(
    f"held-out gap: nominal {gap.nominal['heldout']:.2f} counts -> with the effects "
    f"{gap.with_effects['heldout']:.2f} counts ({gap.heldout_reduction:.0%} less; {gap.evaluated_by})"
)
for step in diagnosis.steps:
    print(
        f"  + {step.effect}: {step.heldout_gap:.2f} counts; without it the others' model is "
        f"{step.reduction_over_others:.0%} worse"
    )

# %% [markdown]
# Each fitted parameter with its 95 % interval: how precisely these logs pin it.

# %%
final = next(entry for entry in diagnosis.ranking if entry.effect.split("+") == [s.effect for s in diagnosis.steps])
for key, value in final.params.items():
    if key in final.params_ci:
        low, high = final.params_ci[key]
        print(f"  {key:45s} {value:.4g}  [{low:.4g}, {high:.4g}]")

# %% [markdown]
# What these logs could not have missed: the smallest size of every other effect the same rule would have
# detected. An effect below its limit may be there; these logs cannot tell.

# %%
for limit in diagnosis.detection_limits:
    print(
        f"  {limit.effect:22s} {limit.param:20s} "
        + ("beyond its range" if limit.value is None else f"{limit.value:.3g} {limit.unit}")
    )

# %% [markdown]
# Where the gap sat, before and after: the regimes and frequency bands that carry it.

# %%
loc = diagnosis.localization
for regime in loc["regimes"]:
    after = next(r for r in loc["after"]["regimes"] if r["regime"] == regime["regime"]) if "after" in loc else None
    print(
        f"  {regime['regime']:24s} {regime['share_of_gap']:6.1%}"
        + (f" -> {after['share_of_gap']:6.1%}" if after else "")
    )

# %% [markdown]
# ## 6. Simulate the corrected model
# `fitted_model.yaml` is a simulate config (`furuta-drake simulate --config fitted_model.yaml`); here its Drake
# model and the nominal one are driven by the same open-loop voltage from the hanging pendulum, and their arm
# responses compared. `fitted_rig.yaml` is the rig file with the accepted effects, to continue from.

# %%
import dataclasses

from furuta_drake.config import ExcitationConfig, MonitorConfig, SimulationConfig
from furuta_drake.simulate import simulate

fitted = diagnosis.artifacts.fitted_config
nominal = SimulationConfig.from_rig(load_rig(rig_path))
runs = {}
for label, config in (("nominal", nominal), ("corrected", fitted)):
    config = dataclasses.replace(
        config,
        duration=2.0 if SMALL else 6.0,
        initial_state=[np.pi, 0.0, 0.0, 0.0],
        controller=dataclasses.replace(config.controller, mode="open_loop"),
        excitation=ExcitationConfig(torque_rms=0.3 * config.rig.gravity_torque, frequency_min=0.3, frequency_max=4.0),
        monitor=MonitorConfig(theta_bound=None),
        seed=3,
    )
    runs[label] = simulate(config)
fig, ax = plt.subplots(figsize=(9, 3))
for label, result in runs.items():
    ax.plot(result.time, result.state[:, 1], label=label)
ax.set_xlabel("time [s]")
ax.set_ylabel("phi [rad]")
ax.legend()
print(sorted(p.name for p in (WORK / "report").iterdir()))

# %% [markdown]
# ## 7. Many trials in one file
# Identification data often comes as one long table of short trials with a trial column. Here the lab's logs,
# written as such a table: every trial keeps its own time from 0 and the `trial` column numbers them.
# `--run-column trial` (here `LogFormat(..., run_column="trial")`) makes each trial a log of its own, named
# `file.csv[run=k]`, and the held-out data whole trials:
# `furuta-drake diagnose --rig my_rig.yaml --train trials.csv --run-column trial --columns ... --out report`.

# %%
from furuta_drake.diagnosis.gap.split import split_heldout
from furuta_drake.diagnosis.logs.load import load_logs

pieces = [np.genfromtxt(path, delimiter=",", names=True) for path in train + heldout]
table = {name: np.concatenate([piece[name] for piece in pieces]) for name in ("t", "vm", "alpha", "theta")}
table["trial"] = np.concatenate([np.full(piece.size, k + 1.0) for k, piece in enumerate(pieces)])
trials_path = write_log(WORK / "trials.csv", table)
by_trial = LogFormat.parse("time=t,theta=alpha,phi=theta,voltage=vm", "deg", run_column="trial")
trials = load_logs([trials_path], load_rig(rig_path), rig_path, by_trial)
fit_trials, heldout_trials, _ = split_heldout(trials)
print([f"{log.name}: {log.time.size} samples" for log in trials])
print("held out whole:", [log.name for log in heldout_trials])

# %% [markdown]
# ## 8. A rig you built: a geared drive
# A lab-built Furuta pendulum often has a DC gearmotor on the arm, an encoder on the arm's shaft and a
# microcontroller logging at 50 Hz. Its largest unmodelled effect is then in the drive: the gear's backlash (the arm
# is free within a play of a few mrad, then the teeth engage) or a belt's compliance. Neither is a torque of the
# arm's state, so the rig file must say that the rig has a drive: `furuta-drake rig --template geared` writes one
# with the gear ratio and the motor's rotor inertia (the datasheet's, times the ratio squared, gives what the arm
# feels), both explained with how to measure them; `rig --check` reads it back. With a `drive:` section the
# diagnosis also offers `drive_backlash` and `drive_compliance`.
#
# Here the "rig" is the package's Drake world with a play of +-0.03 rad in the gear, logged at 50 Hz under a
# +-1 V step command that reverses the arm every few tenths of a second; the rig file states the drive rigid,
# as a lab's first rig file would.

# %%
import dataclasses

from furuta_drake.config import SimulationConfig, open_loop_config
from furuta_drake.results import write_log_csv
from furuta_drake.rig import geared_rig
from furuta_drake.simulate import simulate

built_rig = geared_rig().replace(sample_period=0.02)  # 50 Hz
geared_path = WORK / "geared_rig.yaml"
geared_path.write_text(rig_template(built_rig, "my geared pendulum"))
print(format_rig_check(load_rig(geared_path), str(geared_path)))


def step_run(seed: int, duration: float) -> SimulationConfig:
    """The built rig with a 0.03 rad backlash, open loop from hanging under a +-1 V step command."""
    truth = built_rig.replace(drive=dataclasses.replace(built_rig.drive, backlash=0.03))
    rng = np.random.default_rng(seed)
    switches = np.cumsum(rng.uniform(0.25, 0.6, size=int(duration / 0.25) + 2))
    times = np.arange(int(round(duration / built_rig.sample_period))) * built_rig.sample_period
    volts_to_torque = built_rig.motor.torque_constant / built_rig.motor.resistance
    command = volts_to_torque * (-1.0) ** np.searchsorted(switches, times, side="right")
    return open_loop_config(truth, command, duration=duration, seed=seed)


duration = 3.0 if SMALL else 8.0
geared_logs = {}
for name, seed in (("train_0", 1), ("train_1", 2), ("heldout_0", 3), ("heldout_1", 4)):
    geared_logs[name] = WORK / f"geared_{name}.csv"
    write_log_csv(simulate(step_run(seed, duration)), geared_logs[name])

# %% [markdown]
# `furuta-drake diagnose --rig geared_rig.yaml --train geared_train_*.csv --heldout geared_heldout_*.csv --out
# geared_report`. (Small runs try the backlash and its look-alike on the arm, Coulomb friction, only.) The report
# names the play with its interval, states the look-alikes it was told apart from, and `fitted_rig.yaml` writes it
# as the drive's `backlash`.

# %%
geared = diagnose(
    rig=geared_path,
    train=[geared_logs["train_0"], geared_logs["train_1"]],
    heldout=[geared_logs["heldout_0"], geared_logs["heldout_1"]],
    candidates=["drive_backlash", "arm_coulomb_friction"] if SMALL else None,
    settings=DiagnosisSettings(detection_limits=False, replay=False) if SMALL else DiagnosisSettings(),
)
write_report(WORK / "geared_report", geared)
print(f"verdict: {geared.verdict}; effects: {geared.effects}")
print(geared.choice)
print("drive:", load_rig(WORK / "geared_report" / "fitted_rig.yaml").drive)
