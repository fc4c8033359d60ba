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


def plot_friction_estimates(result, path: str | Path | None = None, title: str = ""):
    """Arm friction: the Dahl estimate F_hat, F_hat + eps_hat_F (paper Fig. 5, 7) and the true friction."""
    fig, ax = plt.subplots(figsize=(9, 4))
    t = result.time
    ax.plot(t, result.true_friction[:, 1], "g-.", lw=1.2, label="true arm friction")
    if "friction_estimate" in result.signals:
        f_hat = result.signals["friction_estimate"][:, 0]
        ax.plot(t, f_hat, "k", lw=1.0, label=r"$\hat F_\phi$")
        if "friction_error_estimate" in result.signals:
            eps = result.signals["friction_error_estimate"][:, 1]
            ax.plot(t, eps, "r--", lw=0.8, label=r"$\hat\epsilon_{F\phi}$")
            ax.plot(t, f_hat + eps, "b:", lw=1.2, label=r"$\hat F_\phi + \hat\epsilon_{F\phi}$")
    ax.set_xlabel("time [s]")
    ax.set_ylabel("arm friction torque [N m]")
    ax.set_title(title)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, ncol=2)
    fig.tight_layout()
    return _save(fig, path)


def _save(fig, path):
    if path is not None:
        fig.savefig(path, dpi=110)
        plt.close(fig)
    return fig
