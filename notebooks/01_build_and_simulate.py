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
# # Build and simulate the Furuta pendulum of the paper
# The Lund rig of Lenain et al. as a Drake diagram: MultibodyPlant, arm Dahl friction, 4096-count encoders at
# 1 kHz, the HG and VFE observers side by side, LQR on the VFE estimate. `FURUTA_NOTEBOOK_SMALL=1` (set by the
# tests) shortens the run.

# %%
import dataclasses
import os

import numpy as np

from furuta_drake.config import SimulationConfig
from furuta_drake.diagram import build_furuta_diagram
from furuta_drake.friction import FrictionParameters, JointFrictionParameters
from furuta_drake.plotting import plot_states, plot_velocity_estimates
from furuta_drake.simulate import simulate

DURATION = 1.0 if os.environ.get("FURUTA_NOTEBOOK_SMALL") else 10.0

# %%
config = SimulationConfig.from_rig("lund")
config = dataclasses.replace(
    config,
    duration=DURATION,
    friction=FrictionParameters(arm=JointFrictionParameters.dahl(0.012, 0.018, sigma0=10.0)),
    controller=dataclasses.replace(config.controller, velocity_source="vfe"),
    observers=dataclasses.replace(config.observers, run=["hg", "vfe"]),
)
built = build_furuta_diagram(config)
print(built.diagram.GetGraphvizString(max_depth=1)[:300], "...")

# %%
result = simulate(config, built=built)
print(f"{DURATION} s simulated in {result.wall_time:.2f} s; max |theta| = {np.abs(result.state[:, 0]).max():.4f} rad")
for name, estimate in result.estimates.items():
    error = estimate[:, 3] - result.state[:, 3]
    print(f"{name.upper()} arm velocity RMS error: {np.sqrt(np.mean(error**2)):.4f} rad/s")

# %%
plot_states(result)

# %%
plot_velocity_estimates(result)

# %% [markdown]
# ## Meshcat
# The same run drawn in Meshcat (open the printed URL while it runs), recorded and saved as a self-contained
# HTML file that plays back in a browser without a server (`furuta-drake simulate --meshcat --html run.html`
# does the same from the shell).

# %%
from pydrake.geometry import StartMeshcat

meshcat = StartMeshcat()
meshcat.StartRecording()
simulate(dataclasses.replace(config, duration=min(DURATION, 2.0)), meshcat=meshcat)
meshcat.StopRecording()
meshcat.PublishRecording()
with open("furuta_run.html", "w") as file:
    file.write(meshcat.StaticHtml())
print(f"Meshcat at {meshcat.web_url()}; recording saved to furuta_run.html")
