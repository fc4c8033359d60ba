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
# # Reproducing Lenain et al.: Tables I-II and Figs. 5-7 on the simulated Lund rig
# The same experiments as `furuta-drake reproduce`, step by step from the package's functions. The simulated
# rig has the paper's arm friction (Dahl, 0.012 N m for phi_dot > 0, 0.018 N m for phi_dot < 0,
# sigma0 = 10 N m/rad), 0.001 N m pendulum friction, 4096-count encoders at 1 kHz and a seeded multisine torque
# (0.2-3 Hz, 12 mN m RMS, known to the observers) that keeps the arm moving. `FURUTA_NOTEBOOK_SMALL=1` (set by
# the tests) shortens every run.

# %%
import os

from furuta_drake.paper import reproduce
from furuta_drake.paper.report import steady_values
from furuta_drake.plotting import plot_fig5, plot_friction_estimates, plot_k_sigma, plot_observer_sweep

SMALL = bool(os.environ.get("FURUTA_NOTEBOOK_SMALL"))
TABLE_DURATION = 4.0 if SMALL else 20.0  # [s] the paper's tests last 20 s
ADAPTATION_DURATION = 12.0 if SMALL else 40.0  # [s] adaptation switches on at 7.8 s
config = reproduce.paper_rig_config(seed=0, duration=TABLE_DURATION)

# %% [markdown]
# ## Tables I-II, with a fair comparison
# A pilot run (LQR on VFE) is replayed offline through the HG observer for eps from 2 to 20 ms and through the
# VFE observer for its poles scaled 0.5-3x; each keeps its lowest arm velocity error. Then the paper's two
# runs: LQR on HG and LQR on VFE, both with friction compensation u = u_LQ - F_hat (Sec. IV-A), both observers
# running side by side.

# %%
runs = reproduce.run_table_experiments(config, progress=print)
plot_observer_sweep(runs.sweep)


# %%
def show(rows, keys):
    for row in rows:
        label = " ".join(str(row[k]) for k in keys)
        print(
            f"{label:32s} HG {row['HG']:.3g} (paper {row['paper_HG']:.3g})   "
            f"VFE {row['VFE']:.3g} (paper {row['paper_VFE']:.3g})"
        )


print("Table I, squared angles [rad^2]")
show(reproduce.table1(runs), ("signal", "statistic"))
print("\nTable II, squared velocity errors [(rad/s)^2]")
show(reproduce.table2(runs), ("reference", "signal", "statistic"))

# %% [markdown]
# ## Fig. 5: two miscalibrated Dahl sets, no compensation
# F_hat follows the calibration; F_hat + eps_hat_F, which adds the VFE's friction-error estimate, lands on the
# true friction for both sets.

# %%
fig5 = reproduce.fig5_experiment(config)
for name, run in fig5.items():
    print(
        name,
        "F_hat",
        steady_values(run["steady"], "F_hat"),
        "F_hat + eps",
        steady_values(run["steady"], "F_hat_plus_eps"),
        "true",
        steady_values(run["steady"], "true"),
    )
plot_fig5({name: run["result"] for name, run in fig5.items()}, (reproduce.ARM_COULOMB_POS, reproduce.ARM_COULOMB_NEG))

# %% [markdown]
# ## Figs. 6-7: K_sigma adaptation from an underestimated set (Fc_hat = 0.009 N m)

# %%
adaptation = reproduce.adaptation_experiment(config, ADAPTATION_DURATION)
print(adaptation["summary"])
plot_k_sigma(adaptation["result"], reproduce.ADAPTATION_ENABLE_TIME, reproduce.PAPER_K_SIGMA_RANGE)

# %%
plot_friction_estimates(
    adaptation["result"],
    title="Fig. 7: adapted friction estimate",
    calibrated=(reproduce.ARM_COULOMB_POS, reproduce.ARM_COULOMB_NEG),
)
