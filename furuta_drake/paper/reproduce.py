"""The paper's experiments on the simulated Lund rig: Tables I-II, Fig. 5 and Figs. 6-7.

The simulated rig (``paper_rig_config``) is what ``docs/paper.md`` says about the real one: arm Dahl friction of
0.012 N m (phi_dot > 0) and 0.018 N m (phi_dot < 0) with sigma0 = 10 N m/rad, pendulum Coulomb friction of
0.001 N m, 4096-count encoders sampled at 1 kHz, the 0.2 N m torque limit. The paper does not say what kept
its arm moving; here a seeded multisine torque disturbance (0.2-3 Hz) plays that role, with an RMS chosen so
that the arm's excursions are of the size Table I reports.

Each experiment returns plain data (tables as lists of rows, steady values as dicts) so that the CLI, the
notebook and the tests share it.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import LogVectorOutput, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial

from furuta_drake.config import ExcitationConfig, SimulationConfig
from furuta_drake.diagram import add_vfe_with_dahl, connect_arm_reference, start_at
from furuta_drake.friction import FrictionParameters, JointFrictionParameters
from furuta_drake.observers.dahl import DahlAdaptation
from furuta_drake.observers.hg import HighGainObserver
from furuta_drake.observers.k_sigma import KSigmaAdaptationParameters
from furuta_drake.paper.metrics import butterworth_velocity_reference, squared_error_statistics, steady_phases
from furuta_drake.rig import linearized_upright
from furuta_drake.simulate import SimulationResult, simulate

# The paper's values (Tables I-II, Fig. 6), squared errors in rad^2 and (rad/s)^2.
PAPER_TABLE1 = {
    ("phi", "mean"): (3.5e-3, 2.3e-3),
    ("phi", "std"): (3.4e-3, 2.5e-3),
    ("theta", "mean"): (4.2e-5, 6.4e-5),
    ("theta", "std"): (4.7e-5, 7.7e-5),
}
PAPER_TABLE2 = {
    ("phi_dot", "mean"): (31e-3, 9e-3),
    ("phi_dot", "std"): (48e-3, 13e-3),
    ("theta_dot", "mean"): (4.1e-3, 1.1e-3),
    ("theta_dot", "std"): (6.4e-3, 1.6e-3),
}
PAPER_K_SIGMA_RANGE = (1.34, 2.05)
ARM_COULOMB_POS, ARM_COULOMB_NEG = 0.012, 0.018  # [N m], Sec. V-D / Fig. 7
ARM_SIGMA0 = 10.0  # [N m/rad]
PENDULUM_COULOMB = 0.001  # [N m]
ADAPTATION_ENABLE_TIME = 7.8  # [s], Sec. V-D
UNDERESTIMATED_COULOMB = 0.009  # [N m], the start of Figs. 6-7
ADAPTATION_GAMMA = 15000.0  # [1/((N m)^2 s)]: the paper gives none; K_sigma settles within the 40 s run
TRANSIENT = 1.0  # [s] dropped from every statistic (start-up from theta0)
SWEEP_HG_EPS = (0.002, 0.003, 0.004, 0.005, 0.007, 0.01, 0.014, 0.02)  # [s] error poles at -1/eps
SWEEP_VFE_SCALES = (0.5, 0.7, 1.0, 1.4, 2.0, 3.0)  # times the default eigenvalues of G, -20 ... -35 rad/s


def paper_rig_config(seed: int = 0, duration: float = 20.0) -> SimulationConfig:
    """The simulated Lund rig of the reproduction, LQR on the VFE estimate with friction compensation."""
    config = SimulationConfig.from_rig("lund")
    friction = FrictionParameters(
        arm=JointFrictionParameters(
            model="dahl", coulomb_pos=ARM_COULOMB_POS, coulomb_neg=ARM_COULOMB_NEG, sigma0=ARM_SIGMA0
        ),
        pendulum=JointFrictionParameters(model="static", coulomb_pos=PENDULUM_COULOMB, coulomb_neg=PENDULUM_COULOMB),
    )
    dahl = dataclasses.replace(
        config.observers.dahl, coulomb_pos=ARM_COULOMB_POS, coulomb_neg=ARM_COULOMB_NEG, sigma0=ARM_SIGMA0
    )
    return dataclasses.replace(
        config,
        friction=friction,
        duration=duration,
        seed=seed,
        initial_state=[0.02, 0.0, 0.0, 0.0],
        excitation=ExcitationConfig(torque_rms=0.012, torque_components=10, frequency_min=0.2, frequency_max=3.0),
        observers=dataclasses.replace(config.observers, dahl=dahl, run=["hg", "vfe"]),
        controller=dataclasses.replace(config.controller, velocity_source="vfe", friction_compensation=True),
    )


def with_velocity_source(config: SimulationConfig, source: str) -> SimulationConfig:
    """``config`` with the LQR fed by ``source`` ('hg' or 'vfe'). Friction compensation, when on, uses the Dahl
    observer (Eq. 8) on that source's arm velocity (Sec. IV-A: u = u_LQ - F_hat in both experiments)."""
    return dataclasses.replace(config, controller=dataclasses.replace(config.controller, velocity_source=source))


@dataclass
class TableRuns:
    """The runs of Sec. IV: LQR on HG and LQR on VFE (both observers running in each, same seed and
    excitation), the observer sweeps that tuned both observers, and the config they were tuned from."""

    hg_run: SimulationResult
    vfe_run: SimulationResult
    config: SimulationConfig
    sweep: list[dict]


def _after_transient(result: SimulationResult) -> slice:
    return slice(int(np.searchsorted(result.time, result.time[0] + TRANSIENT)), None)


def table1(runs: TableRuns) -> list[dict]:
    """Table I: mean and std of the squared measured angles under HG-based and VFE-based control."""
    rows = []
    for index, signal in ((1, "phi"), (0, "theta")):
        stats = {
            name: squared_error_statistics(run.measured[_after_transient(run), index])
            for name, run in (("HG", runs.hg_run), ("VFE", runs.vfe_run))
        }
        rows += _beside_paper({"signal": signal}, stats, PAPER_TABLE1)
    return rows


def _beside_paper(key: dict, stats: dict, paper: dict) -> list[dict]:
    """The mean and std rows of one signal (``key`` holds its name): HG and VFE ``stats`` beside the ``paper``
    table's values."""
    rows = []
    for statistic in ("mean", "std"):
        paper_hg, paper_vfe = paper[(key["signal"], statistic)]
        rows.append(
            {
                **key,
                "statistic": statistic,
                "HG": stats["HG"][statistic],
                "VFE": stats["VFE"][statistic],
                "paper_HG": paper_hg,
                "paper_VFE": paper_vfe,
            }
        )
    return rows


def table2(runs: TableRuns) -> list[dict]:
    """Table II: squared velocity errors of HG and VFE, both running on the VFE-controlled run, against the
    zero-phase 5 Hz Butterworth reference (as the paper) and against the true velocity (which the simulation
    knows)."""
    run = runs.vfe_run
    references = velocity_references(run, runs.config)
    keep = _after_transient(run)
    rows = []
    for reference_name, reference in references.items():
        for index, signal in ((1, "phi_dot"), (0, "theta_dot")):
            stats = {
                name.upper(): squared_error_statistics(run.estimates[name][keep, 2 + index] - reference[keep, index])
                for name in ("hg", "vfe")
            }
            rows += _beside_paper({"reference": reference_name, "signal": signal}, stats, PAPER_TABLE2)
    return rows


def velocity_references(result: SimulationResult, config: SimulationConfig) -> dict[str, np.ndarray]:
    """Table II's two references for [theta_dot, phi_dot]: the paper's zero-phase 5 Hz Butterworth of the
    encoder angles' derivative, and the true velocity."""
    return {
        "butterworth": butterworth_velocity_reference(result.measured, config.control_period),
        "true": result.state[:, 2:],
    }


def replay_observers(result: SimulationResult, config: SimulationConfig, *, hg=None, vfe=None, model=None) -> dict:
    """Run observers offline on a run's logged encoder angles and torque commands (a Drake diagram of
    ``TrajectorySource`` s and the observer systems), returning their state estimates aligned with the run.

    ``hg``: HighGainParameters; ``vfe``: (VfeParameters, DahlObserverParameters or None: no friction model, the
    VFE's F_hat input held at 0 so that eps_hat_F carries all the friction). ``model``: the observers' (A, B_F)
    (default: the upright linearisation of ``config.rig``); with ``config.observers.start_at_initial_state`` they
    start at ``config.initial_state`` (else at x_hat = 0).

    Row k of the log (the sample of t_k, see ``simulate._tape``) is fed from t_k + period / 2 on, so that, as in
    the closed loop, the update at t_{k+1} reads the measurement of t_k and the torque applied over
    [t_k, t_{k+1}); after the start-up transient the replayed estimates equal the closed loop's.
    """
    period = config.control_period
    times = result.time + period / 2  # between two updates: immune to the rounding of the re-timed log
    builder = DiagramBuilder()
    angles = builder.AddSystem(TrajectorySource(PiecewisePolynomial.ZeroOrderHold(times, result.measured.T)))
    torque = builder.AddSystem(TrajectorySource(PiecewisePolynomial.ZeroOrderHold(times, result.torque.reshape(1, -1))))
    A, B_F = model if model is not None else linearized_upright(config.rig)
    loggers, linear = {}, []
    if hg is not None:
        hg_system = builder.AddSystem(HighGainObserver((A, B_F), hg, period=period))
        builder.Connect(angles.get_output_port(), hg_system.GetInputPort("measured_angles_rad"))
        builder.Connect(torque.get_output_port(), hg_system.GetInputPort("arm_torque_Nm"))
        loggers["hg"] = LogVectorOutput(hg_system.GetOutputPort("state_estimate"), builder, period)
        linear.append(hg_system)
    if vfe is not None:
        vfe_params, dahl_params = vfe
        nested = add_vfe_with_dahl(
            builder,
            (A, B_F),
            vfe_params,
            dahl_params,
            angles.get_output_port(),
            torque.get_output_port(),
            config.observers.pendulum_friction,
            period=period,
        )
        connect_arm_reference(builder, None, [nested.dahl] if nested.dahl is not None else [])
        vfe_system = nested.vfe
        loggers["vfe"] = LogVectorOutput(vfe_system.GetOutputPort("state_estimate"), builder, period)
        linear.append(vfe_system)
    if config.observers.start_at_initial_state:
        start_at(linear, config.initial_state)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    simulator.AdvanceTo(result.time[-1] + 1.5 * period)  # past the last sample's publish, whatever the rounding
    context = simulator.get_context()
    # Logged at t_k + period, the estimate of the state at t_k (see simulate._tape): drop the first sample.
    return {name: logger.FindLog(context).data().T[1 : 1 + result.time.size] for name, logger in loggers.items()}


def sweep_candidates(config: SimulationConfig, dahl) -> list[tuple[str, str, float, dict]]:
    """The fairness sweep's candidates as (observer, parameter, value, ``replay_observers`` keyword arguments):
    the HG observer for every eps in ``SWEEP_HG_EPS``, the VFE observer with the Dahl observer ``dahl``
    (DahlObserverParameters, or None for no friction model) for every scale of its eigenvalues in
    ``SWEEP_VFE_SCALES``."""
    candidates = [
        ("hg", "eps", eps, {"hg": dataclasses.replace(config.observers.hg, eps_theta=eps, eps_phi=eps)})
        for eps in SWEEP_HG_EPS
    ]
    candidates += [
        ("vfe", "eigenvalue_scale", scale, {"vfe": (_scaled_vfe(config, scale), dahl)}) for scale in SWEEP_VFE_SCALES
    ]
    return candidates


def velocity_errors(estimate: np.ndarray, references: dict[str, np.ndarray]) -> dict[str, float]:
    """Mean squared error [(rad/s)^2] of an observer's velocity ``estimate`` (n, 2: [theta_dot, phi_dot]) against
    each reference (n, 2), keyed ``{signal}_mse_{reference}``."""
    row = {}
    for reference_name, reference in references.items():
        for index, signal in ((1, "phi_dot"), (0, "theta_dot")):
            row[f"{signal}_mse_{reference_name}"] = squared_error_statistics(estimate[:, index] - reference[:, index])[
                "mean"
            ]
    return row


def mark_best(rows: list[dict], key: str) -> list[dict]:
    """Mark, per observer, the row with the lowest ``key`` (``best``: True) and the others False."""
    for observer in dict.fromkeys(row["observer"] for row in rows):
        mine = [row for row in rows if row["observer"] == observer]
        best = min(mine, key=lambda row: row[key])
        for row in mine:
            row["best"] = row is best
    return rows


def observer_sweep(pilot: SimulationResult, config: SimulationConfig) -> list[dict]:
    """Replay every candidate of :func:`sweep_candidates` on the pilot run's measurements and give each one's mean
    squared velocity errors against both references (rows marked ``best`` have the lowest arm error vs the
    true velocity, per observer)."""
    keep = _after_transient(pilot)
    references = {name: reference[keep] for name, reference in velocity_references(pilot, config).items()}
    rows = []
    for observer, parameter, value, kwargs in sweep_candidates(config, config.observers.dahl):
        estimate = replay_observers(pilot, config, **kwargs)[observer][keep, 2:]
        rows.append(
            {"observer": observer, "parameter": parameter, "value": value, **velocity_errors(estimate, references)}
        )
    return mark_best(rows, "phi_dot_mse_true")


def tuned_config(config: SimulationConfig, sweep: list[dict]) -> SimulationConfig:
    """``config`` with the HG eps and the VFE eigenvalue scale the sweep found best."""
    best = {row["observer"]: row["value"] for row in sweep if row["best"]}
    hg = dataclasses.replace(config.observers.hg, eps_theta=best["hg"], eps_phi=best["hg"])
    return dataclasses.replace(
        config, observers=dataclasses.replace(config.observers, hg=hg, vfe=_scaled_vfe(config, best["vfe"]))
    )


def _scaled_vfe(config: SimulationConfig, scale: float):
    vfe = config.observers.vfe
    return dataclasses.replace(vfe, eigenvalues=[scale * value for value in vfe.eigenvalues])


def run_table_experiments(config: SimulationConfig, progress=None) -> TableRuns:
    """Tables I-II with a fair comparison: a pilot run (LQR on VFE) tunes both observers offline
    (``observer_sweep``), then the two runs of Sec. IV use the tuned observers: LQR on HG, and LQR on VFE
    with friction compensation, both observers running side by side in each, same seed and excitation."""
    pilot = simulate(with_velocity_source(config, "vfe"))
    report_progress(progress, "pilot run")
    sweep = observer_sweep(pilot, config)
    report_progress(progress, "observer sweep")
    tuned = tuned_config(config, sweep)
    runs = {}
    for source in ("hg", "vfe"):
        runs[source] = simulate(with_velocity_source(tuned, source))
        report_progress(progress, f"table run with LQR on {source.upper()}")
    return TableRuns(runs["hg"], runs["vfe"], tuned, sweep)


def report_progress(progress, message: str) -> None:
    if progress is not None:
        progress(message)


def steady_friction_values(
    result: SimulationResult,
    config: SimulationConfig,
    start_time: float = TRANSIENT,
    threshold: float = 0.05,
    min_duration: float = 0.1,
) -> dict:
    """Mean F_hat, F_hat + eps_hat_F (arm entry) and the true arm friction [N m] over steady sliding phases
    after ``start_time``, per direction of the true arm velocity ('pos': phi_dot > 0, 'neg': phi_dot < 0)."""
    keep = result.time >= start_time
    min_samples = int(min_duration / config.control_period)
    masks = steady_phases(result.state[:, 3], threshold, min_samples)
    f_hat = result.signals["friction_estimate"][:, 0]
    eps = result.signals["friction_error_estimate"][:, 1]
    values = {}
    for sign, label in ((1, "pos"), (-1, "neg")):
        mask = masks[sign] & keep
        values[label] = {
            "F_hat": float(np.mean(f_hat[mask])) if mask.any() else float("nan"),
            "F_hat_plus_eps": float(np.mean((f_hat + eps)[mask])) if mask.any() else float("nan"),
            "true": float(np.mean(result.true_friction[mask, 1])) if mask.any() else float("nan"),
            "samples": int(mask.sum()),
        }
    return values


def fig5_experiment(config: SimulationConfig, factors=(("set1_low", 0.7), ("set2_high", 1.3)), progress=None) -> dict:
    """Fig. 5: LQR on VFE without friction compensation (u = u_LQ), with Dahl observer parameters (Fc and
    sigma0) calibrated too low and too high; F_hat differs between the sets, F_hat + eps_hat_F should not."""
    outcome = {}
    for name, factor in factors:
        dahl = dataclasses.replace(
            config.observers.dahl,
            coulomb_pos=factor * ARM_COULOMB_POS,
            coulomb_neg=factor * ARM_COULOMB_NEG,
            sigma0=factor * ARM_SIGMA0,
        )
        run_config = dataclasses.replace(
            config,
            controller=dataclasses.replace(config.controller, velocity_source="vfe", friction_compensation=False),
            observers=dataclasses.replace(config.observers, dahl=dahl, run=["vfe"]),
        )
        result = simulate(run_config)
        report_progress(progress, f"Fig. 5 run, {name}")
        outcome[name] = {
            "factor": factor,
            "result": result,
            "config": run_config,
            "steady": steady_friction_values(result, run_config),
        }
    return outcome


def adaptation_config(config: SimulationConfig, duration: float = 40.0) -> SimulationConfig:
    """Figs. 6-7: an underestimated Dahl observer (Fc_hat = 0.009 N m both ways, K_sigma = 1), LQR on VFE
    without compensation (Sec. V-C: the arm must move to excite the adaptation), K_sigma adaptation enabled
    at t = 7.8 s."""
    adaptation = DahlAdaptation(
        k_sigma=KSigmaAdaptationParameters(enable_time=ADAPTATION_ENABLE_TIME, gamma=ADAPTATION_GAMMA)
    )
    dahl = dataclasses.replace(
        config.observers.dahl,
        coulomb_pos=UNDERESTIMATED_COULOMB,
        coulomb_neg=UNDERESTIMATED_COULOMB,
        adaptation=adaptation,
    )
    return dataclasses.replace(
        config,
        duration=duration,
        controller=dataclasses.replace(config.controller, velocity_source="vfe", friction_compensation=False),
        observers=dataclasses.replace(config.observers, dahl=dahl, run=["vfe"]),
    )


def adaptation_experiment(config: SimulationConfig, duration: float = 40.0, progress=None) -> dict:
    """Run Figs. 6-7 and read the final K_sigma+/- and the adapted friction estimate in the last third."""
    run_config = adaptation_config(config, duration)
    result = simulate(run_config)
    report_progress(progress, "Figs. 6-7 run")
    branches = result.signals["K_sigma"]
    steady = steady_friction_values(result, run_config, start_time=run_config.duration * 2.0 / 3.0)
    return {
        "result": result,
        "config": run_config,
        "summary": {
            "K_sigma_plus": float(branches[-1, 0]),
            "K_sigma_minus": float(branches[-1, 1]),
            "friction_pos": steady["pos"]["F_hat"],
            "friction_neg": steady["neg"]["F_hat"],
            "theta_abs_max": float(np.max(np.abs(result.state[:, 0]))),
            "enable_time": ADAPTATION_ENABLE_TIME,
        },
    }
