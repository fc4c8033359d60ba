"""Study: swing-up and catch (Sec. VII's last open point). The energy swing-up of
:mod:`furuta_drake.controllers.swingup` on the simulated Lund rig of the reproduction (arm Dahl friction, pendulum
Coulomb friction, 4096-count encoders, the 0.2 N m limit; no excitation torque: the swing is the excitation), with
the paper's HG and VFE + Dahl observers running side by side, against the truth, over the large motion and after
the catch; the swing-up controller fed by the paper's HG observer against the kinematic high-gain observer; and a
swing-up log for the diagnosis."""

from __future__ import annotations

import dataclasses
import math
import tempfile
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

from furuta_drake.config import swingup_config
from furuta_drake.controllers.swingup import BALANCE, catch_time, pendulum_energy, wrap_angle
from furuta_drake.paper import reproduce
from furuta_drake.paper.studies import Study
from furuta_drake.results import write_log_csv
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import dump_yaml_dataclass

SETTLE = 1.0  # [s] after the catch before the balance figures are read
START_OFFSETS = (-0.3, -0.1, -0.02, 0.02, 0.1, 0.3)  # [rad] starts theta0 = pi + offset of the robustness count


def swingup_rig_config(seed: int = 0, duration: float = 10.0):
    """The reproduction's rig (``reproduce.paper_rig_config``) without its excitation torque, HG and VFE running."""
    config = reproduce.paper_rig_config(seed=seed, duration=duration)
    return dataclasses.replace(
        config,
        excitation=dataclasses.replace(config.excitation, torque_rms=0.0),
        observers=dataclasses.replace(config.observers, run=["hg", "vfe"]),
    )


def study(seed: int = 0, small: bool = False) -> Study:
    """Time to catch, arm excursion and velocity errors of the observers over a swing-up; with ``small`` a 3 s
    run, no robustness count and no diagnosis."""
    duration = 3.0 if small else 10.0
    config = swingup_rig_config(seed, duration)
    ours = simulate(swingup_config(config, duration=duration))
    paper = simulate(swingup_config(config, duration=duration, velocity_source="hg"))
    t_ours, t_paper = catch_time(ours), catch_time(paper)
    balance = ours.time > t_ours + SETTLE if math.isfinite(t_ours) else np.zeros(ours.time.size, bool)
    rms = _phase_velocity_rms(ours, t_ours, balance)
    rows = _run_rows(ours, paper, t_ours, t_paper, config, duration) + _observer_rows(rms)
    caught = None
    if not small:
        caught = _starts_caught(config, duration)
        rows.append(
            _row(
                f"starts caught within {duration:g} s",
                None,
                caught,
                "of " + str(len(START_OFFSETS)),
                "theta0 = pi + " + ", ".join(f"{o:g}" for o in START_OFFSETS) + " rad",
            )
        )
    summary = _summary(ours, t_ours, t_paper, rms, balance.any(), config, duration)
    if caught is not None:
        summary += (
            f" From perturbed starts {caught} of {len(START_OFFSETS)} are caught within {duration:g} s; the "
            f"time to catch varies from start to start, as the pendulum's energy alone is not conserved "
            f"while the arm moves."
        )
        summary += " " + _diagnose(ours, config)

    return Study(
        title="Swing-up and catch",
        rows=rows,
        summary=summary,
        figures={"swingup_states": plot_swingup(ours, config), "swingup_energy": plot_energy(ours, config)},
        logs={"swingup": ours},
    )


def _phase_velocity_rms(result, t_catch: float, balance: np.ndarray) -> dict:
    """{(observer, phase): [theta_dot, phi_dot] RMS error [rad/s]} of every estimate of ``result`` over the swing
    (before ``t_catch``) and over ``balance``."""
    swing = result.time < (t_catch if math.isfinite(t_catch) else math.inf)
    return {
        (name, phase): _velocity_rms(result, name, mask)
        for name in result.estimates
        for phase, mask in (("swing", swing), ("balance", balance))
    }


def _run_rows(ours, paper, t_ours: float, t_paper: float, config, duration: float) -> list[dict]:
    """Time to catch, arm excursion before it and peak torque of the swing-up on the paper's HG (``paper``) and on
    the kinematic HG (``ours``)."""
    return [
        _row(
            "time to catch from hanging",
            _finite(t_paper),
            _finite(t_ours),
            "s",
            f"swing-up controller on the paper's HG vs on the kinematic HG; None: no catch in {duration:g} s",
        ),
        _row(
            "max |phi| before the catch",
            _max_abs(paper.state[:, 1], paper, t_paper),
            _max_abs(ours.state[:, 1], ours, t_ours),
            "rad",
            "same two runs",
        ),
        _row(
            "max |torque command|",
            float(np.max(np.abs(paper.torque))),
            float(np.max(np.abs(ours.torque))),
            "N m",
            f"rig limit {config.controller.lqr.torque_limit:g} N m",
        ),
    ]


def _observer_rows(rms: dict) -> list[dict]:
    """The velocity errors of :func:`_phase_velocity_rms`, the paper's HG against VFE + Dahl and against the
    kinematic HG, in each phase and for each joint."""
    rows = []
    for phase, what in (
        ("swing", "during the swing (before the catch)"),
        ("balance", f"balancing ({SETTLE:g} s after the catch on)"),
    ):
        for index, joint in ((0, "theta_dot"), (1, "phi_dot")):
            for label, source, note in (
                ("VFE + Dahl", "vfe", "both observers on the kinematic-HG-controlled run"),
                ("kinematic HG", "kinematic_hg", "the kinematic HG feeds the controller"),
            ):
                rows.append(
                    _row(
                        f"{joint} RMS error {what}, HG vs {label}",
                        rms[("hg", phase)][index],
                        rms[(source, phase)][index],
                        "rad/s",
                        note,
                    )
                )
    return rows


def _starts_caught(config, duration: float) -> int:
    """How many of the starts theta0 = pi + ``START_OFFSETS`` the swing-up catches within ``duration``."""
    return sum(
        math.isfinite(catch_time(simulate(swingup_config(config, duration=duration, theta0=math.pi + offset))))
        for offset in START_OFFSETS
    )


def _summary(ours, t_ours: float, t_paper: float, rms: dict, balanced: bool, config, duration: float) -> str:
    """The catch of both runs and the observers' velocity errors over the swing and, when ``balanced``, after
    the catch."""
    limit = config.controller.lqr.torque_limit
    summary = (
        f"From hanging on the paper's rig the energy swing-up, fed by a high-gain observer on the kinematic model "
        f"(no gravity, no input: invariant to whole turns), catches at {t_ours:.2f} s with the arm within "
        f"{_max_abs(ours.state[:, 1], ours, t_ours):.2f} rad and |u| <= {limit:g} N m; fed by the paper's HG it "
        + (f"catches at {t_paper:.2f} s." if math.isfinite(t_paper) else f"does not catch in {duration:g} s.")
        + f" Over the swing the paper's HG, built on the upright linearization, is off by "
        f"{rms[('hg', 'swing')][0]:.2f} rad/s RMS on theta_dot (VFE + Dahl {rms[('vfe', 'swing')][0]:.2f}, "
        f"kinematic HG {rms[('kinematic_hg', 'swing')][0]:.2f})"
    )
    if not balanced:
        return summary + "."
    return summary + (
        f"; after a catch at theta = {ours.state[-1, 0] - wrap_angle(ours.state[-1, 0]):.2f} rad the "
        f"HG stays biased ({rms[('hg', 'balance')][0]:.2f} rad/s: alpha1 theta counts the turn) while the "
        f"VFE's eps_hat_F absorbs the constant model error ({rms[('vfe', 'balance')][0]:.3f} rad/s)."
    )


def _velocity_rms(result, name: str, mask: np.ndarray) -> np.ndarray:
    if not mask.any():
        return np.full(2, math.nan)
    error = result.estimates[name][mask, 2:] - result.state[mask, 2:]
    return np.sqrt(np.mean(error**2, axis=0))


def _finite(value: float) -> float | None:
    return value if math.isfinite(value) else None


def _max_abs(signal: np.ndarray, result, t_catch: float) -> float:
    before = result.time < (t_catch if math.isfinite(t_catch) else math.inf)
    return float(np.max(np.abs(signal[before])))


def _row(metric: str, paper, extension, unit: str, note: str) -> dict:
    def as_float(v):
        return None if v is None or not math.isfinite(v) else float(v)

    return {"metric": metric, "paper": as_float(paper), "extension": as_float(extension), "unit": unit, "note": note}


def _diagnose(result, config) -> str:
    """Run the diagnosis (``furuta-drake diagnose --rig rig.yaml --train swingup.csv``) on the swing-up log against
    the frictionless nominal rig and say what it selected, against the rig's true friction."""
    from furuta_drake.diagnosis.pipeline import diagnose

    with tempfile.TemporaryDirectory() as directory:
        directory = Path(directory)
        write_log_csv(result, directory / "swingup.csv")
        (directory / "rig.yaml").write_text(dump_yaml_dataclass(config.rig))
        report = diagnose(rig=directory / "rig.yaml", train=[directory / "swingup.csv"]).to_json()
    arm = config.friction.arm
    ranks = {entry["effect"]: i + 1 for i, entry in enumerate(report["ranking"])}
    return (
        f"The diagnosis of the swing-up log against the frictionless nominal rig says {report['verdict']} "
        f"(effects {', '.join(report['effects'])}; held-out gap {report['gap']['nominal']['heldout']:.2f} -> "
        f"{report['gap']['with_effects']['heldout']:.2f} counts), where the truth is arm Dahl friction "
        f"{arm.coulomb_pos:g}/{arm.coulomb_neg:g} N m (arm_coulomb_friction ranks "
        f"{ranks.get('arm_coulomb_friction')}, friction_asymmetry {ranks.get('friction_asymmetry')}); with one "
        f"log, blocks spread over it are held out, swing and balancing alike."
    )


def plot_swingup(result, config):
    """theta (wrapped), phi and the torque command over time, the hand-over to the LQR marked."""
    fig, axes = plt.subplots(3, 1, figsize=(9, 8), sharex=True)
    t = result.time
    axes[0].plot(t, wrap_angle(result.state[:, 0]), "k", lw=1.0)
    axes[0].set_ylabel(r"$\theta$ wrapped [rad]")
    axes[1].plot(t, result.state[:, 1], "k", lw=1.0)
    axes[1].set_ylabel(r"$\phi$ [rad]")
    limit = config.controller.lqr.torque_limit
    axes[2].plot(t, result.torque, "tab:purple", lw=0.8)
    axes[2].axhline(limit, color="0.5", ls=":")
    axes[2].axhline(-limit, color="0.5", ls=":")
    axes[2].set_ylabel("torque command [N m]")
    axes[2].set_xlabel("time [s]")
    _mark_handovers(axes, result)
    fig.tight_layout()
    return fig


def plot_energy(result, config):
    """The pendulum energy E (Astrom-Furuta) of the true state and of the controller's estimate, in units of m g l."""
    fig, ax = plt.subplots(figsize=(9, 4))
    mgl = config.rig.gravity_torque
    ax.plot(
        result.time,
        pendulum_energy(config.rig, result.state[:, 0], result.state[:, 2]) / mgl,
        "k",
        lw=1.0,
        label="true state",
    )
    ax.plot(
        result.time,
        result.signals["pendulum_energy_J"][:, 0] / mgl,
        "tab:orange",
        lw=0.8,
        label="controller (kinematic HG)",
    )
    ax.set_ylabel("E / (m g l) [-]")
    ax.set_xlabel("time [s]")
    ax.legend(fontsize=8)
    _mark_handovers([ax], result)
    fig.tight_layout()
    return fig


def _mark_handovers(axes, result) -> None:
    mode = result.signals["swingup_mode"][:, 0]
    for k in np.flatnonzero(np.diff(mode)) + 1:
        for ax in axes:
            ax.axvline(result.time[k], color="tab:green" if mode[k] == BALANCE else "tab:red", ls="--", lw=0.8)
    for ax in axes:
        ax.grid(alpha=0.3)
