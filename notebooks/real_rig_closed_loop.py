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
# # Real data: the paper's observers on a real QUBE, and the closed loop before and after the correction
# The diagnosis corrects a model and measures the correction as a k-step prediction error. A user asks the next
# question: with the corrected model, do the model-based observer and the controller behave in simulation as they
# do on the rig? This notebook answers it on the real QUBE-Servo 2 runs of `data/qube-servo2-real` (SimuRLacra,
# BSD-3), with the same functions as `furuta-drake reproduce --only real`. `FURUTA_NOTEBOOK_SMALL=1` (set by the
# tests) runs quick diagnoses, fewer observer candidates and three swing-ups.

# %%
import os
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
from IPython.display import Markdown, display

from furuta_drake.controllers.quanser_swingup import QuanserSwingUpParameters, quanser_command
from furuta_drake.observers.filtered_derivative import filtered_derivative
from furuta_drake.plotting import (
    plot_controller_fit,
    plot_limit_cycle_spectra,
    plot_real_closed_loop,
    plot_real_observers,
)
from furuta_drake.real_rig import report as real_rig_report
from furuta_drake.real_rig.closed_loop_study import balancing_spectrum, rest_direction
from furuta_drake.real_rig.runs import CHIRP, HELDOUT_SWINGUPS, TRAIN_SWINGUP, reference_velocity

SMALL = bool(os.environ.get("FURUTA_NOTEBOOK_SMALL"))
folder = Path(tempfile.mkdtemp(prefix="real_rig_"))

# %% [markdown]
# ## Run everything
# In order: the diagnosis that corrects Quanser's nominal model (fitted on one swing-up and the chirp's train
# blocks), the observers replayed on the measured angles, the controller checked against the logged voltage, each
# swing-up simulated on the nominal and the corrected model, and the diagnosis of what the corrected model still
# misses.

# %%
outcome = real_rig_report.run_real_rig(folder, small=SMALL, progress=print)
display(Markdown("\n".join(real_rig_report.correction_section(outcome))))

# %% [markdown]
# ## The controller the rig ran
# `controllers/quanser_swingup.py` is Quanser's energy swing-up and PD balance, as SimuRLacra ran it, rewritten in
# the package's conventions. Fed the logged angles, it should give back the logged voltage. With the paper's
# zero-phase reference velocities it does not quite; with the causal filtered derivative of the rig's server
# (its corner fitted on the train swing-up) it does, to a small fraction of a volt.

# %%
display(Markdown("\n".join(real_rig_report.controller_section(outcome))))
log = outcome.runs.logs[TRAIN_SWINGUP]
params = QuanserSwingUpParameters(rest_direction=rest_direction(log, QuanserSwingUpParameters()))
angles = np.column_stack([log.theta, log.phi])
corner = outcome.closed_loop.corner
replayed = {
    "zero-phase Butterworth velocities": quanser_command(params, np.column_stack([angles, reference_velocity(log)]))[0],
    f"server's filter, {corner:.1f} rad/s": quanser_command(
        params, np.column_stack([angles, filtered_derivative(angles, log.sample_period, corner)])
    )[0],
}
plot_controller_fit(log.time, log.input, replayed, TRAIN_SWINGUP)

# %% [markdown]
# ## The paper's observers on measured data
# HG and VFE (with the Dahl observer) replayed on the balancing part of the swing-ups (linearised at the upright)
# and on the chirp (linearised hanging), each tuned on the train segments, judged on the held-out ones against the
# paper's zero-phase Butterworth reference. Does the VFE's 3.4x of the paper hold here, and does the corrected
# model help the model-based observer?

# %%
display(Markdown("\n".join(real_rig_report.observer_section(outcome))))
shown = {key: value for key, value in outcome.observers.estimates.items() if key[1] in (HELDOUT_SWINGUPS[0], CHIRP)}
plot_real_observers(shown)

# %% [markdown]
# ## The closed loop, real and simulated
# Each real swing-up's experiment in simulation (same start, 250 Hz, 4 V clip, encoder counts, the server's
# velocity filter) on the nominal and on the corrected model, and on the model the balancing diagnosis corrects
# further. The gap table is the headline: how much of the nominal model's closed-loop gap the correction closes.

# %%
display(Markdown("\n".join(real_rig_report.closed_loop_section(outcome))))
runs = outcome.closed_loop.runs
for name in dict.fromkeys(log_name for _, log_name in runs):
    plot_real_closed_loop({source: runs[(source, log_name)] for source, log_name in runs if log_name == name}, name)

# %% [markdown]
# ## Where it does not close
# The corrected model swings up like the rig but balances differently: the rig's balancing limit cycle, and the
# saturated oscillation one run falls into. The diagnosis, run again on the balancing from the corrected model,
# says what it finds there and where its gap sits.

# %%
display(Markdown("\n".join(real_rig_report.open_part_section(outcome))))
spectra = {
    name: {
        source: spectrum
        for source, log_name in runs
        if log_name == name
        if (spectrum := balancing_spectrum(runs[(source, log_name)][0])) is not None
    }
    for name in dict.fromkeys(log_name for _, log_name in runs)
}
plot_limit_cycle_spectra(spectra)
plt.show()
