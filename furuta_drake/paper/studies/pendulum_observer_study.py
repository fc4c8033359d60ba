"""Study: a friction observer on both joints (Sec. VII). A Dahl observer on the pendulum joint too, feeding
F_hat_theta into the VFE observer (Eq. 10's full F_hat), against the paper's arm-only observer, on a rig whose
pendulum has Dahl friction. Both observers calibrated (matched levels), and a pendulum observer 30 % low to show
the VFE's eps_hat_F absorbing a calibration error."""

from __future__ import annotations

import dataclasses

from furuta_drake.friction import JointFrictionParameters
from furuta_drake.observers.dahl import DahlObserverParameters
from furuta_drake.paper import reproduce
from furuta_drake.paper.metrics import observer_figures
from furuta_drake.paper.studies import Study
from furuta_drake.plotting import plot_velocity_estimates
from furuta_drake.simulate import simulate

WORN_PENDULUM_COULOMB = 0.003  # [N m]: three times the paper rig's, a worn pendulum bearing
WORN_PENDULUM_SIGMA0 = 2.0  # [N m/rad]
MISCALIBRATION = 0.7  # the second pendulum observer's levels, times the true ones


def study(seed: int = 0, small: bool = False) -> Study:
    """Pendulum velocity error and control error with and without the pendulum friction observer."""
    base = reproduce.paper_rig_config(seed=seed, duration=6.0 if small else 20.0)
    rig = dataclasses.replace(
        base,
        friction=dataclasses.replace(
            base.friction,
            pendulum=JointFrictionParameters.dahl(WORN_PENDULUM_COULOMB, WORN_PENDULUM_COULOMB, WORN_PENDULUM_SIGMA0),
        ),
        observers=dataclasses.replace(base.observers, run=["vfe"]),
    )
    runs = {"paper (arm observer only)": rig}
    for label, factor in (("both joints", 1.0), (f"both joints, pendulum Fc x {MISCALIBRATION:g}", MISCALIBRATION)):
        level = factor * WORN_PENDULUM_COULOMB
        observer = DahlObserverParameters(coulomb_pos=level, coulomb_neg=level, sigma0=WORN_PENDULUM_SIGMA0, rho=None)
        runs[label] = dataclasses.replace(rig, observers=dataclasses.replace(rig.observers, pendulum_friction=observer))
    results = {label: simulate(config) for label, config in runs.items()}
    figures = {label: observer_figures(result, reproduce.TRANSIENT) for label, result in results.items()}
    paper = figures["paper (arm observer only)"]
    rows = []
    for metric, unit in (
        ("theta_dot_mse", "(rad/s)^2"),
        ("phi_dot_mse", "(rad/s)^2"),
        ("theta_sq", "rad^2"),
        ("phi_sq", "rad^2"),
    ):
        for label in list(runs)[1:]:
            rows.append(
                {
                    "metric": f"{metric} ({label})",
                    "paper": paper[metric],
                    "extension": figures[label][metric],
                    "unit": unit,
                    "note": "",
                }
            )
    both = figures["both joints"]
    summary = (
        f"With {WORN_PENDULUM_COULOMB * 1e3:g} mN m pendulum Dahl friction, a pendulum friction observer "
        f"feeding the VFE cuts the pendulum velocity error "
        f"{paper['theta_dot_mse'] / both['theta_dot_mse']:.0f}x and "
        f"the arm's {paper['phi_dot_mse'] / both['phi_dot_mse']:.0f}x, and mean theta^2 "
        f"{paper['theta_sq'] / both['theta_sq']:.2f}x: the pendulum has no actuator of its own, so its friction "
        f"is observed but not cancelled, and the control gains less than the estimate."
    )
    return Study(
        title="Friction observer on both joints",
        rows=rows,
        summary=summary,
        figures={"pendulum_observer_velocities": plot_velocity_estimates(results["both joints"])},
        logs={
            "pendulum_observer_paper": results["paper (arm observer only)"],
            "pendulum_observer_both": results["both joints"],
        },
    )
