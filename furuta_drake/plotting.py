"""One plotting module for the CLI and the notebooks: states, torque, velocity estimates, friction estimates.

Labels carry units; every function takes a :class:`~furuta_drake.simulate.SimulationResult` and returns the
matplotlib Figure (and saves it when given a path), so notebooks show what the CLI writes.
"""

from __future__ import annotations

from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np

STATE_LABELS = [r"$\theta$ [rad]", r"$\phi$ [rad]", r"$\dot\theta$ [rad/s]", r"$\dot\phi$ [rad/s]"]


def plot_states(result, path: str | Path | None = None):
    """True states, encoder angles, observer estimates and the commanded torque over time."""
    fig, axes = plt.subplots(5, 1, figsize=(9, 11), sharex=True)
    t = result.time
    for i, ax in enumerate(axes[:4]):
        ax.plot(t, result.state[:, i], "k", lw=1.2, label="true")
        if i < 2:
            ax.plot(t, result.measured[:, i], color="0.6", lw=0.8, ls="--", label="encoder")
        for name, estimate in result.estimates.items():
            ax.plot(t, estimate[:, i], lw=0.8, label=name.upper())
        ax.set_ylabel(STATE_LABELS[i])
        ax.grid(alpha=0.3)
    axes[0].legend(loc="upper right", fontsize=8, ncol=4)
    axes[4].plot(t, result.torque, "tab:purple", lw=0.8)
    axes[4].set_ylabel("torque command [N m]")
    axes[4].set_xlabel("time [s]")
    axes[4].grid(alpha=0.3)
    fig.tight_layout()
    return _save(fig, path)


def plot_velocity_estimates(result, reference: np.ndarray | None = None, path: str | Path | None = None):
    """Velocity estimates against the true velocities (and an optional reference, e.g. the Butterworth one)."""
    fig, axes = plt.subplots(2, 1, figsize=(9, 6), sharex=True)
    for ax, i, label in ((axes[0], 3, STATE_LABELS[3]), (axes[1], 2, STATE_LABELS[2])):
        ax.plot(result.time, result.state[:, i], "k", lw=1.2, label="true")
        if reference is not None:
            ax.plot(result.time, reference[:, i - 2], "b--", lw=1.0, label="5 Hz Butterworth")
        for name, estimate in result.estimates.items():
            ax.plot(result.time, estimate[:, i], lw=0.8, label=name.upper())
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8, ncol=4)
    axes[1].set_xlabel("time [s]")
    fig.tight_layout()
    return _save(fig, path)


def plot_friction_estimates(
    result, path: str | Path | None = None, title: str = "", calibrated: tuple[float, float] | None = None
):
    """Arm friction: the Dahl estimate F_hat, F_hat + eps_hat_F (paper Fig. 5, 7) and the true friction."""
    fig, ax = plt.subplots(figsize=(9, 4))
    _draw_friction(ax, result, calibrated)
    ax.set_title(title)
    ax.legend(fontsize=8, ncol=3)
    fig.tight_layout()
    return _save(fig, path)


def plot_control_signals(results: dict, path: str | Path | None = None):
    """Fig. 4: the torque command of each run ({title: result}) side by side."""
    fig, axes = plt.subplots(1, len(results), figsize=(5.5 * len(results), 3.5), sharey=True, squeeze=False)
    for ax, (title, result) in zip(axes[0], results.items()):
        ax.plot(result.time, result.torque, "k", lw=0.6)
        ax.set_title(title, fontsize=10)
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("torque command [N m]")
    fig.tight_layout()
    return _save(fig, path)


def plot_fig5(results: dict, calibrated: tuple[float, float], path: str | Path | None = None):
    """Fig. 5: F_hat, eps_hat_F and F_hat + eps_hat_F for each Dahl parameter set ({title: result}), with the
    calibrated steady levels (pos, neg) [N m] and the true friction."""
    fig, axes = plt.subplots(len(results), 1, figsize=(9, 3.6 * len(results)), sharex=True, squeeze=False)
    for ax, (title, result) in zip(axes[:, 0], results.items()):
        _draw_friction(ax, result, calibrated)
        ax.set_title(title, fontsize=10)
    axes[0, 0].legend(fontsize=8, ncol=3)
    fig.tight_layout()
    return _save(fig, path)


def plot_k_sigma(result, enable_time: float, paper_range: tuple[float, float], path: str | Path | None = None):
    """Fig. 6: the K_sigma in use (black), K_sigma- (red dashed) and K_sigma+ (blue dashed) over time."""
    fig, ax = plt.subplots(figsize=(9, 4))
    branches = result.signals["K_sigma"]
    in_use = np.where(result.estimates["vfe"][:, 3] > 0, branches[:, 0], branches[:, 1])
    ax.plot(result.time, in_use, "k", lw=0.8, label=r"$K_\sigma$ in use")
    ax.plot(result.time, branches[:, 1], "r--", lw=1.4, label=r"$K_\sigma^-$ ($\dot\phi < 0$)")
    ax.plot(result.time, branches[:, 0], "b--", lw=1.4, label=r"$K_\sigma^+$ ($\dot\phi > 0$)")
    ax.axvline(enable_time, color="0.5", ls=":", lw=1.0, label=f"adaptation on, t = {enable_time:g} s")
    ax.axhspan(*paper_range, color="0.85", alpha=0.5, label="paper's range")
    ax.set_xlabel("time [s]")
    ax.set_ylabel(r"$K_\sigma$ [-]")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=3)
    fig.tight_layout()
    return _save(fig, path)


def plot_observer_sweep(rows: list[dict], path: str | Path | None = None):
    """The fairness sweep of Tables I-II: each observer's mean squared velocity errors (vs the true velocity,
    solid; vs the 5 Hz Butterworth reference, dashed) against its tuning parameter, the chosen one circled."""
    observers = list(dict.fromkeys(row["observer"] for row in rows))
    fig, axes = plt.subplots(1, len(observers), figsize=(5 * len(observers), 4), squeeze=False)
    for ax, observer in zip(axes[0], observers):
        mine = [row for row in rows if row["observer"] == observer]
        x = np.array([row["value"] for row in mine])
        for signal, color in (("phi_dot", "tab:blue"), ("theta_dot", "tab:orange")):
            for reference, style in (("true", "-"), ("butterworth", "--")):
                ax.plot(
                    x,
                    [row[f"{signal}_mse_{reference}"] for row in mine],
                    style,
                    marker="o",
                    ms=3,
                    color=color,
                    label=f"{signal} vs {reference}",
                )
            best = next(row for row in mine if row["best"])
            ax.plot(best["value"], best[f"{signal}_mse_true"], "o", ms=11, mfc="none", color="k")
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel(f"{observer.upper()} {mine[0]['parameter']}")
        ax.set_ylabel(r"mean squared velocity error [rad$^2$/s$^2$]")
        ax.grid(alpha=0.3, which="both")
    axes[0, 0].legend(fontsize=8)
    fig.tight_layout()
    return _save(fig, path)


def plot_parameter_adaptation(trajectories: dict, true: dict, enable_time: float, path: str | Path | None = None):
    """Dahl parameters over time, divided by their true values, for the one-gain law (dashed: what K_sigma
    implies) and the two-parameter law (solid), one column per start ({start: (time, paper, ours)})."""
    fig, axes = plt.subplots(1, len(trajectories), figsize=(6 * len(trajectories), 4), sharey=True, squeeze=False)
    colors = {"Fc+": "tab:blue", "Fc-": "tab:red", "sigma0": "k"}
    for ax, (start, (time, paper, ours)) in zip(axes[0], trajectories.items()):
        for name, values in ours.items():
            ax.plot(time, values / true[name], color=colors[name], lw=1.4, label=f"{name}, two-parameter law")
        for name, values in paper.items():
            truth = true["sigma0"] if name.startswith("sigma0") else true[name]
            color = colors["sigma0"] if name.startswith("sigma0") else colors[name]
            ax.plot(time, values / truth, color=color, lw=1.0, ls="--", label=f"{name}, one-gain law (Eq. 18)")
        ax.axhline(1.0, color="0.5", lw=0.8)
        ax.axvline(enable_time, color="0.5", ls=":", lw=1.0)
        ax.set_title(f"{start} start", fontsize=10)
        ax.set_xlabel("time [s]")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("estimate / true value [-]")
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    return _save(fig, path)


def plot_real_observers(estimates: dict, path: str | Path | None = None):
    """Velocity estimates of the observers replayed on real runs against the reference velocity: one column per
    (model, log) of ``estimates`` ({(model, log): {"segment": Segment, "hg": estimate, "vfe": estimate}}), arm
    velocity above, pendulum velocity below, over the judged samples."""
    keys = list(estimates)
    fig, axes = plt.subplots(2, len(keys), figsize=(4.2 * len(keys), 5.5), squeeze=False)
    for column, key in enumerate(keys):
        entry = estimates[key]
        segment = entry["segment"]
        judged = np.flatnonzero(segment.judged)
        shown = judged[: min(judged.size, int(round(1.0 / (segment.result.time[1] - segment.result.time[0]))))]
        t = segment.result.time[shown] + segment.start_time
        for row, (index, label) in enumerate(((1, STATE_LABELS[3]), (0, STATE_LABELS[2]))):
            ax = axes[row, column]
            ax.plot(t, segment.reference[shown, index], "k", lw=1.4, label="zero-phase Butterworth")
            for name, color in (("hg", "tab:orange"), ("vfe", "tab:blue")):
                ax.plot(t, entry[name][shown, 2 + index], color=color, lw=0.8, label=name.upper())
            ax.set_ylabel(label)
            ax.grid(alpha=0.3)
        axes[0, column].set_title(f"{key[1]}\n{key[0]} model ({segment.equilibrium})", fontsize=8)
        axes[1, column].set_xlabel("time [s]")
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    return _save(fig, path)


def plot_real_closed_loop(runs: dict, title: str, path: str | Path | None = None):
    """A real swing-up and its simulations side by side ({source: (tape, voltage [V])}): pendulum and arm
    angles (encoder) and the voltage over time."""
    fig, axes = plt.subplots(3, 1, figsize=(10, 8), sharex=True)
    styles = {"real": dict(color="k", lw=1.4)}
    for source, (result, voltage) in runs.items():
        style = styles.get(source, dict(lw=0.9))
        axes[0].plot(result.time, result.measured[:, 0], label=source, **style)
        axes[1].plot(result.time, result.measured[:, 1], **style)
        axes[2].plot(result.time, voltage, **{**style, "lw": 0.6})
    for ax, label in zip(axes, (r"$\theta$ (unwrapped) [rad]", r"$\phi$ [rad]", "voltage [V]")):
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
    axes[0].set_title(title, fontsize=10)
    axes[0].legend(fontsize=8, ncol=4)
    axes[2].set_xlabel("time [s]")
    fig.tight_layout()
    return _save(fig, path)


def plot_controller_fit(
    time: np.ndarray, logged: np.ndarray, replayed: dict, title: str, path: str | Path | None = None
):
    """The logged voltage against the controller's voltage from the logged angles with each velocity source
    ({label: voltage [V]})."""
    fig, ax = plt.subplots(figsize=(10, 3.8))
    ax.plot(time, logged, "k", lw=1.6, label="logged")
    for label, voltage in replayed.items():
        ax.plot(time, voltage, lw=0.8, label=label)
    ax.set_xlabel("time [s]")
    ax.set_ylabel("voltage [V]")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    fig.tight_layout()
    return _save(fig, path)


def plot_limit_cycle_spectra(spectra: dict, path: str | Path | None = None):
    """Welch spectra of the balancing pendulum angle, one panel per log ({log: {source: (frequency [Hz],
    power [rad^2/Hz])}})."""
    fig, axes = plt.subplots(1, len(spectra), figsize=(4.2 * len(spectra), 3.6), squeeze=False, sharey=True)
    for ax, (log, sources) in zip(axes[0], spectra.items()):
        for source, (frequency, power) in sources.items():
            ax.semilogy(
                frequency, power, **({"color": "k", "lw": 1.6} if source == "real" else {"lw": 0.9}), label=source
            )
        ax.set_title(log, fontsize=8)
        ax.set_xlabel("frequency [Hz]")
        ax.grid(alpha=0.3, which="both")
    axes[0, 0].set_ylabel(r"$\theta$ power [rad$^2$/Hz]")
    axes[0, 0].legend(fontsize=7)
    fig.tight_layout()
    return _save(fig, path)


def _draw_friction(ax, result, calibrated: tuple[float, float] | None):
    t = result.time
    ax.plot(t, result.true_friction[:, 1], color="tab:green", lw=1.0, alpha=0.7, label="true arm friction")
    if calibrated is not None:
        for level in (-calibrated[0], calibrated[1]):
            ax.axhline(level, color="tab:green", ls="-.", lw=1.0)
    if "friction_estimate" in result.signals:
        f_hat = result.signals["friction_estimate"][:, 0]
        ax.plot(t, f_hat, "k", lw=1.0, label=r"$\hat F_\phi$")
        if "friction_error_estimate" in result.signals:
            eps = result.signals["friction_error_estimate"][:, 1]
            ax.plot(t, eps, "r--", lw=0.8, label=r"$\hat\epsilon_{F\phi}$")
            ax.plot(t, f_hat + eps, "b:", lw=1.2, label=r"$\hat F_\phi + \hat\epsilon_{F\phi}$")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("arm friction torque [N m]")
    ax.grid(alpha=0.3)


def _save(fig, path):
    if path is not None:
        fig.savefig(path, dpi=110)
        plt.close(fig)
    return fig
