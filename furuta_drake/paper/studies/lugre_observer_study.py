"""Study: the LuGre observer (Sec. VII). The friction observer with a LuGre model (Stribeck curve g(v), bristle
damping sigma1, viscous sigma2; Freidovich et al. 2006) in place of Dahl, on a rig whose arm friction is LuGre with
a Stribeck effect, against the paper's Dahl observer calibrated at the Coulomb levels. Both observers use the same
VFE observer and the LQR with friction compensation."""

from __future__ import annotations

import dataclasses

from furuta_drake.friction import JointFrictionParameters
from furuta_drake.paper import reproduce
from furuta_drake.paper.metrics import observer_figures
from furuta_drake.paper.studies import Study
from furuta_drake.plotting import plot_friction_estimates
from furuta_drake.simulate import simulate

STRIBECK = {"static_pos": 0.020, "static_neg": 0.030, "stribeck_velocity": 0.1}  # Fs+/- [N m], vs [rad/s]
SIGMA1 = 0.1  # [N m s/rad], about a third of the critical damping 2 sqrt(sigma0 J_arm)
SIGMA2 = 0.002  # [N m s/rad]


def study(seed: int = 0, small: bool = False) -> Study:
    """Friction and velocity estimation errors of the Dahl and the LuGre observer on a LuGre rig."""
    base = reproduce.paper_rig_config(seed=seed, duration=6.0 if small else 20.0)
    arm = JointFrictionParameters(
        model="lugre",
        coulomb_pos=reproduce.ARM_COULOMB_POS,
        coulomb_neg=reproduce.ARM_COULOMB_NEG,
        sigma0=reproduce.ARM_SIGMA0,
        sigma1=SIGMA1,
        viscous=SIGMA2,
        **STRIBECK,
    )
    rig = dataclasses.replace(
        base,
        friction=dataclasses.replace(base.friction, arm=arm),
        observers=dataclasses.replace(base.observers, run=["vfe"]),
    )
    lugre = dataclasses.replace(rig.observers.dahl, sigma1=SIGMA1, sigma2=SIGMA2, **STRIBECK)
    runs = {
        "Dahl observer (paper)": rig,
        "LuGre observer": dataclasses.replace(rig, observers=dataclasses.replace(rig.observers, dahl=lugre)),
    }
    results = {label: simulate(config) for label, config in runs.items()}
    dahl, ours = (observer_figures(result, reproduce.TRANSIENT) for result in results.values())
    rows = [
        {"metric": metric, "paper": dahl[metric], "extension": ours[metric], "unit": unit, "note": ""}
        for metric, unit in (
            ("F_hat_rms_error", "N m"),
            ("F_hat_plus_eps_rms_error", "N m"),
            ("phi_dot_mse", "(rad/s)^2"),
            ("theta_dot_mse", "(rad/s)^2"),
            ("phi_sq", "rad^2"),
            ("theta_sq", "rad^2"),
        )
    ]
    summary = (
        f"On an arm with LuGre friction (Stribeck breakaway {STRIBECK['static_pos']}/{STRIBECK['static_neg']} "
        f"N m over Coulomb {reproduce.ARM_COULOMB_POS}/{reproduce.ARM_COULOMB_NEG} N m), the LuGre observer's "
        f"F_hat is {dahl['F_hat_rms_error'] / ours['F_hat_rms_error']:.1f}x closer to the true friction than "
        f"the Dahl observer's, and the VFE arm velocity error is "
        f"{dahl['phi_dot_mse'] / ours['phi_dot_mse']:.1f}x lower; control accuracy (phi^2, theta^2) changes "
        f"little, as with Table I."
    )
    return Study(
        title="LuGre observer",
        rows=rows,
        summary=summary,
        figures={
            f"lugre_observer_{name}": plot_friction_estimates(result, title=label)
            for (label, result), name in zip(results.items(), ("dahl", "lugre"))
        },
        logs={
            "lugre_rig_dahl_observer": results["Dahl observer (paper)"],
            "lugre_rig_lugre_observer": results["LuGre observer"],
        },
    )
