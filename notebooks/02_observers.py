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
# # HG and VFE observers on the same run
# The high-gain observer (paper Eq. 4-6) and the velocity-and-friction-error observer with the Dahl friction
# observer (Eq. 7-13) run side by side in one diagram, fed the same 4096-count encoder samples of the Lund rig
# with the paper's asymmetric Dahl friction on the arm. The LQR uses the true velocities here (diagram (iv) of
# the paper), so neither observer changes the run they both watch. Then the linear picture: observability from
# the encoders, the observers' error eigenvalues, and the separation principle on Drake's `Linearize` of the
# closed loop. `FURUTA_NOTEBOOK_SMALL=1` (set by the tests) shortens the run.

# %%
import dataclasses
import os

import numpy as np

from furuta_drake.analysis import observability, observer_for_analysis, observer_loop_eigenvalues, separation_error
from furuta_drake.config import ExcitationConfig, SimulationConfig
from furuta_drake.controllers.lqr import state_feedback_eigenvalues
from furuta_drake.diagram import build_furuta_diagram
from furuta_drake.friction import FrictionParameters, JointFrictionParameters
from furuta_drake.observers.linear import ANGLES
from furuta_drake.plotting import plot_friction_estimates, plot_velocity_estimates
from furuta_drake.rig import linearized_upright, lund_rig
from furuta_drake.simulate import simulate

DURATION = 1.0 if os.environ.get("FURUTA_NOTEBOOK_SMALL") else 10.0

# %% [markdown]
# ## One run, two observers
# A multisine torque and a square-wave arm reference keep the arm moving through its friction reversals, where
# the observers differ most. `observers.run` lists the observers that run next to the controller's source.

# %%
rig = lund_rig()
config = SimulationConfig.from_rig(rig)
config = dataclasses.replace(
    config,
    duration=DURATION,
    seed=1,
    friction=FrictionParameters(arm=JointFrictionParameters.dahl(0.012, 0.018, sigma0=10.0)),
    excitation=ExcitationConfig(torque_rms=0.01, arm_reference_amplitude=0.2, arm_reference_period=2.0),
    controller=dataclasses.replace(config.controller, velocity_source="true"),
    observers=dataclasses.replace(config.observers, run=["hg", "vfe"]),
)
built = build_furuta_diagram(config)
print(
    "observer blocks:",
    sorted(s.get_name() for s in built.diagram.GetSystems() if any(k in s.get_name() for k in ("hg", "vfe", "dahl"))),
)
result = simulate(config, built=built)
print(f"{DURATION} s simulated in {result.wall_time:.2f} s")

# %% [markdown]
# Velocity error of each observer against the true velocities (mean square, as in the paper's Table II), on
# identical measurements, after the first 0.2 s (the observers start from a zero estimate, the pendulum at
# theta = 0.1 rad).

# %%
settled = result.time >= 0.2
print(f"{'observer':8} {'theta_dot MSE [(rad/s)^2]':>26} {'phi_dot MSE [(rad/s)^2]':>24}")
for name, estimate in result.estimates.items():
    error = estimate[settled, 2:] - result.state[settled, 2:]
    print(f"{name.upper():8} {np.mean(error[:, 0] ** 2):26.3e} {np.mean(error[:, 1] ** 2):24.3e}")

# %%
plot_velocity_estimates(result)

# %% [markdown]
# The Dahl observer's friction estimate F_hat, the VFE correction F_hat + eps_hat_F and the friction the
# simulation applied (paper Fig. 5).

# %%
plot_friction_estimates(result, title="arm friction: estimates and truth")

# %% [markdown]
# ## Observability from the encoders
# y = C x with C measuring theta and phi (Eq. 2). Both angles observe the linearized pendulum; the arm angle
# alone still does (the pendulum moves the arm through the coupling), the pendulum angle alone does not (an arm
# rotating at constant speed leaves theta unchanged).

# %%
A, B_F = linearized_upright(rig)
for label, C in (("theta and phi", ANGLES), ("phi only", ANGLES[1:]), ("theta only", ANGLES[:1])):
    print(f"{label:14}", observability(A, C))

# %% [markdown]
# ## Error eigenvalues and the separation principle
# HG: eig(A - H C), set by eps (poles near -a1 / (2 eps)); VFE: eig(G) of Eq. 12, placed where the config
# says. The continuous closed loop plant + observer + LQR, linearized by Drake, has exactly the LQR's
# eigenvalues together with the observer's.

# %%
K = np.asarray(result.lqr_gain).reshape(1, 4)
controller = state_feedback_eigenvalues(A, B_F[:, 1:], K, discrete=False, period=config.control_period)
print("LQR eig(A - B K):", np.round(np.sort_complex(controller), 2))
for kind in ("hg", "vfe"):
    observer, error_eigenvalues = observer_for_analysis(kind, A, B_F, getattr(config.observers, kind))
    loop = observer_loop_eigenvalues(rig, K, observer)
    print(f"{kind.upper()} error eigenvalues:", np.round(np.sort_complex(error_eigenvalues), 2))
    print(f"    closed loop matches LQR + observer to {separation_error(loop, controller, error_eigenvalues):.1e}")
