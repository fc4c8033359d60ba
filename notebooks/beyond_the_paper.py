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
# # Beyond the paper: the open problems of its Sections VI-VII
# Each study runs the paper's method and an extension on the same simulated Lund rig and seed, as
# `furuta-drake reproduce --only beyond` does (`beyond.md`). `FURUTA_NOTEBOOK_SMALL=1` (set by the tests) runs
# the short form of each study.

# %%
import os

from furuta_drake.paper.studies import (
    lugre_observer_study,
    parameter_adaptation_study,
    pendulum_observer_study,
    stability_study,
    swingup_study,
)

SMALL = bool(os.environ.get("FURUTA_NOTEBOOK_SMALL"))


def show(study):
    """The study's summary and rows (None: not applicable, e.g. no catch)."""
    print(study.title)
    print(study.summary)
    for row in study.rows:
        paper, extension = ("-" if x is None else f"{x:.4g}" for x in (row["paper"], row["extension"]))
        print(f"  {row['metric']:45s} paper {paper}  extension {extension} [{row['unit']}]")


# %% [markdown]
# ## A friction observer on both joints
# A Dahl observer on the pendulum joint too, feeding F_hat_theta into the VFE observer (Eq. 10's full F_hat).

# %%
study = pendulum_observer_study.study(small=SMALL)
show(study)
study.figures["pendulum_observer_velocities"]

# %% [markdown]
# ## A LuGre observer on a rig with a Stribeck effect

# %%
study = lugre_observer_study.study(small=SMALL)
show(study)
study.figures["lugre_observer_lugre"]

# %% [markdown]
# ## Adapting sigma0 and Fc, not one gain
# The two-parameter law against Eq. 18 from an under- and an over-estimated Dahl set (four 30-40 s runs).

# %%
study = parameter_adaptation_study.study(small=SMALL)
show(study)
study.figures["parameter_adaptation"]

# %% [markdown]
# ## Stability evidence for the nested observers with frozen K_sigma
# The loop linearized at the upright in its presliding regime (where the Dahl friction is a spring), over
# K_sigma, the true sigma0 and the observer gains, and the sampled basin of attraction of the nonlinear loop.

# %%
study = stability_study.study(small=SMALL)
show(study)
list(study.figures.values())[0]

# %% [markdown]
# ## Swing-up and catch
# An energy-based swing-up (Astrom-Furuta) hands over to the LQR near the top: large, periodic motions for
# the observers. The full study also feeds the swing-up log to `furuta-drake diagnose`.

# %%
study = swingup_study.study(small=SMALL)
show(study)
list(study.figures.values())[0]
