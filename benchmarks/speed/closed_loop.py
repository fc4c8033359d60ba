"""Wall time and real-time factor of a closed loop per diagram configuration, against the C++ floor and a scipy
peer (targets: the full paper diagram >= 10x real time on one core, <= 1.5x its C++ floor, >= 5x faster than the
scipy peer).

Configurations, all on the default Lund config (``SimulationConfig.from_rig("lund")``: 4096-count encoders at
1 kHz, LQR with the 0.2 N m limit, RK3 at accuracy 1e-4, theta0 = 0.1 rad):

- ``true LQR``: LQR on the encoder angles and the true velocities (reference diagram (iv));
- ``HG``: LQR on the high-gain observer (Eq. 4);
- ``VFE+Dahl``: LQR on the VFE observer (Eq. 11) with the Dahl observer (Eq. 8) and u = u_LQ - F_hat;
- ``VFE+Dahl+K``: the same with the K_sigma adaptation (Eq. 18): the full paper diagram.

Each is timed three ways in the same process, interleaved, best of ``--repeats``, in CPU seconds of this
process (``time.process_time``: the wall time of the run alone on one core; on a machine shared with other jobs
the wall time also counts their time slices, so the package's best wall time is printed beside it):

- ``furuta_drake.simulate.simulate`` on a built diagram (the package, envelope checks included; build time
  excluded);
- the C++ floor: the same sampled loop from C++ systems only, wired directly: the MultibodyPlant, a
  ``ZeroOrderHold`` sampling the true state, the encoder's periodic sampler (its symbolic C++ system, the first
  sample a constant), the observer's discrete ``LinearSystem``, for the VFE configurations the package's Dahl
  observer and K_sigma adapter (symbolic expressions evaluated in C++:
  :func:`furuta_drake.symbolic_system.discrete_symbolic_system`), the LQR as ``MatrixGain`` -> ``Saturation`` ->
  ``ZeroOrderHold``, loggers of the same signals and the same integrator. So the package's excess over the floor
  is what it adds around the same computations: the encoder's initialization sample (a Python event, once per
  run), the envelope checks between chunks of simulated time, and its wiring (the world's actuator and friction
  ports, the LQR's compensation and u_LQ ports, the true friction's sampler and logger, each block a Diagram of
  its own); ``--profile`` lists the Python calls of one run. ``x bare`` compares the package with the bare loop
  instead: the same loop without the encoder's quantisation (a ``ZeroOrderHold`` sampler) and without the friction
  observer and its adapter (F_hat = 0), the floor before these blocks were C++: what they cost, in the package's
  C++ systems, shows there. (The discrete update of a symbolic block cannot be a
  ``SymbolicVectorSystem(time_period=h)`` itself: in a diagram with continuous state Drake evaluates every
  subsystem's time derivatives at every integrator stage, and that system's derivatives abort unless its period
  is zero. Drake's ``DiscreteTimeApproximation`` holds it instead, so nothing of it runs between samples.)
- the scipy peer: the same sampled loop written for this benchmark, the package's closed-form Furuta equations
  (the diagnosis surrogate's, in the lumped constants a, b, c, d; tests pin them to the MultibodyPlant)
  integrated by ``solve_ivp`` (RK45, rtol 1e-8, atol 1e-10; a looser
  tolerance is not faster: each 1 ms period is one or two RK45 steps and the per-call overhead dominates) over
  each period with the torque held, the discrete blocks updated at each sample from the values held before it
  (Drake's discrete semantics).

The peer must give the package's trajectory. With the 4096-count encoder two correct integrations agree only
until the first sample at which they read different counts: while the counts do not change the loop does not
see a sub-count deviation, which grows at the pendulum's unstable pole (6.9 1/s) until it flips a count (the
package at accuracy 1e-4 and at 1e-10 part the same way). So the table prints the deviation until the first
differing count and when that happens, and the check is made on the same loops with a 2^32-count encoder (one
count 1.5e-9 rad), over the whole run: max |x_package - x_peer| <= ``TOLERANCE``.

Run from the repository root: ``PYTHONPATH=. python benchmarks/speed/closed_loop.py [--duration 10] [--repeats 3]
[--profile]`` (``--profile``: also the cProfile top entries of one run of the full diagram).
"""

from __future__ import annotations

import argparse
import cProfile
import dataclasses
import math
import pstats
import time

import numpy as np
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import DiagramBuilder, OutputPort
from pydrake.systems.primitives import (
    ConstantVectorSource,
    LogVectorOutput,
    MatrixGain,
    Multiplexer,
    Saturation,
    ZeroOrderHold,
)
from scipy.integrate import solve_ivp
from scipy.linalg import expm

from furuta_drake.config import SimulationConfig
from furuta_drake.diagram import build_furuta_diagram
from furuta_drake.effects.surrogate import Model, _accelerations
from furuta_drake.encoder import periodic_sampler, quantise
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.observers.dahl import DahlAdaptation, DahlFrictionObserver
from furuta_drake.observers.hg import HighGainObserver, continuous_high_gain_observer
from furuta_drake.observers.k_sigma import KSigmaAdaptationParameters, KSigmaAdapter
from furuta_drake.observers.vfe import VfeObserver, continuous_vfe_observer
from furuta_drake.plant import add_furuta_plant, plant_to_paper_permutation
from furuta_drake.rig import linearized_upright
from furuta_drake.simulate import SimulationResult, simulate

TARGET_REAL_TIME, TARGET_FLOOR_RATIO, TARGET_PEER_SPEEDUP = 10.0, 1.5, 5.0
TOLERANCE = 1e-4  # [rad, rad/s] package vs peer with the fine encoder: RK3 at accuracy 1e-4 against RK45 at 1e-8
FINE_COUNTS = 2**32
PEER_RTOL, PEER_ATOL = 1e-8, 1e-10


def configurations(duration: float) -> dict[str, SimulationConfig]:
    """The four diagrams of the table on the default Lund config."""
    base = dataclasses.replace(SimulationConfig.from_rig("lund"), duration=duration)

    def variant(source: str, compensation: bool = False, adaptation: bool = False) -> SimulationConfig:
        law = DahlAdaptation(k_sigma=KSigmaAdaptationParameters()) if adaptation else None
        return dataclasses.replace(
            base,
            controller=dataclasses.replace(base.controller, velocity_source=source, friction_compensation=compensation),
            observers=dataclasses.replace(
                base.observers, dahl=dataclasses.replace(base.observers.dahl, adaptation=law)
            ),
        )

    return {
        "true LQR": variant("true"),
        "HG": variant("hg"),
        "VFE+Dahl": variant("vfe", True),
        "VFE+Dahl+K": variant("vfe", True, True),
    }


# --- The C++ floor ------------------------------------------------------------------------------------------------


def floor_simulator(config: SimulationConfig, gain: np.ndarray, bare: bool = False) -> Simulator:
    """The sampled loop of ``config`` from Drake's C++ systems only (see the module docstring); ``bare``: the bare
    loop, without the encoder's quantisation and the friction observer."""
    rig, period = config.rig, config.control_period
    builder = DiagramBuilder()
    plant, _ = add_furuta_plant(builder, rig, time_step=0.0, with_scene_graph=False)
    to_paper = builder.AddSystem(MatrixGain(plant_to_paper_permutation(plant)))
    builder.Connect(plant.get_state_output_port(), to_paper.get_input_port())
    true_state = to_paper.get_output_port()
    state_sample = builder.AddSystem(ZeroOrderHold(period, 4))
    builder.Connect(true_state, state_sample.get_input_port())
    measured = _floor_encoder(builder, config, true_state, bare)

    hold = builder.AddSystem(ZeroOrderHold(period, 1))
    builder.Connect(hold.get_output_port(), plant.get_actuation_input_port())
    command = hold.get_output_port()
    estimate, friction = _floor_observers(builder, config, true_state, measured, command, bare)
    law = -np.asarray(gain).reshape(1, 4)
    if friction is not None:  # u = u_LQ - F_hat
        law = np.hstack([law, [[-1.0]]])
        stacked = builder.AddSystem(Multiplexer([4, 1]))
        builder.Connect(estimate, stacked.get_input_port(0))
        builder.Connect(friction, stacked.get_input_port(1))
        estimate = stacked.get_output_port()
    lqr = builder.AddSystem(MatrixGain(law))
    limit = config.controller.lqr.torque_limit
    saturation = builder.AddSystem(Saturation([-limit], [limit]))
    builder.Connect(estimate, lqr.get_input_port())
    builder.Connect(lqr.get_output_port(), saturation.get_input_port())
    builder.Connect(saturation.get_output_port(), hold.get_input_port())
    for port in (state_sample.get_output_port(), measured, command):
        LogVectorOutput(port, builder, publish_period=period)

    simulator = Simulator(builder.Build())
    ApplySimulatorConfig(SimulatorConfig(**dataclasses.asdict(config.simulator)), simulator)
    plant_context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    plant.SetPositionsAndVelocities(plant_context, plant_to_paper_permutation(plant).T @ config.initial_state)
    return simulator


def _floor_encoder(builder: DiagramBuilder, config: SimulationConfig, true_state, bare: bool) -> OutputPort:
    """The encoder's C++ periodic sampler, its first sample a constant (the package takes it at initialization);
    ``bare``: a ``ZeroOrderHold`` of the angles."""
    if bare:
        angles = builder.AddSystem(MatrixGain(np.hstack([np.eye(2), np.zeros((2, 2))])))
        encoder = builder.AddSystem(ZeroOrderHold(config.control_period, 2))
        builder.Connect(true_state, angles.get_input_port())
        builder.Connect(angles.get_output_port(), encoder.get_input_port())
        return encoder.get_output_port()
    resolution = config.encoder.encoder_resolution
    sampler = builder.AddSystem(periodic_sampler(resolution, config.control_period))
    first = builder.AddSystem(ConstantVectorSource([quantise(angle, resolution) for angle in config.initial_state[:2]]))
    builder.Connect(true_state, sampler.GetInputPort("true_state"))
    builder.Connect(first.get_output_port(), sampler.GetInputPort("first_sample_rad"))
    return sampler.GetOutputPort("measured_angles_rad")


def _floor_observers(builder: DiagramBuilder, config: SimulationConfig, true_state, measured, command, bare: bool):
    """(state estimate, F_hat or None) of the controller's velocity source, logged as the package logs them: the
    true velocities beside the angles, the HG observer, or the VFE observer nested with the Dahl observer and, when
    it adapts, its K_sigma adapter (the package's C++ systems); ``bare``: the VFE observer with F_hat = 0."""
    period, observers = config.control_period, config.observers
    model = linearized_upright(config.rig)
    source = config.controller.velocity_source
    if source == "true":
        velocities = builder.AddSystem(MatrixGain(np.hstack([np.zeros((2, 2)), np.eye(2)])))
        builder.Connect(true_state, velocities.get_input_port())
        mux = builder.AddSystem(Multiplexer([2, 2]))
        builder.Connect(measured, mux.get_input_port(0))
        builder.Connect(velocities.get_output_port(), mux.get_input_port(1))
        return mux.get_output_port(), None
    if source == "hg":
        observer = builder.AddSystem(HighGainObserver(model, observers.hg, period=period))
    else:
        observer = builder.AddSystem(VfeObserver(model, observers.vfe, period=period))
    builder.Connect(measured, observer.GetInputPort("measured_angles_rad"))
    builder.Connect(command, observer.GetInputPort("arm_torque_Nm"))
    estimate = observer.GetOutputPort("state_estimate")
    LogVectorOutput(estimate, builder, publish_period=period)
    if source == "hg":
        return estimate, None
    if bare:
        no_friction = builder.AddSystem(ConstantVectorSource([0.0]))
        builder.Connect(no_friction.get_output_port(), observer.GetInputPort("friction_estimate_Nm"))
        LogVectorOutput(observer.GetOutputPort("friction_error_estimate_Nm"), builder, publish_period=period)
        return estimate, None
    dahl = builder.AddSystem(DahlFrictionObserver(observers.dahl, period=period))
    arm_velocity = builder.AddSystem(MatrixGain(np.array([[0.0, 0.0, 0.0, 1.0]])))
    upright = builder.AddSystem(ConstantVectorSource([0.0, 0.0]))
    builder.Connect(estimate, arm_velocity.get_input_port())
    builder.Connect(arm_velocity.get_output_port(), dahl.GetInputPort("arm_velocity_estimate_rad_per_s"))
    builder.Connect(measured, dahl.GetInputPort("measured_angles_rad"))
    builder.Connect(upright.get_output_port(), dahl.GetInputPort("arm_reference_rad"))
    friction = dahl.GetOutputPort("friction_estimate_Nm")
    builder.Connect(friction, observer.GetInputPort("friction_estimate_Nm"))
    error = observer.GetOutputPort("friction_error_estimate_Nm")
    signals = [friction, error]
    adaptation = observers.dahl.adaptation
    if adaptation is not None:
        adapter = builder.AddSystem(KSigmaAdapter(adaptation.k_sigma, period=period, sigma0=observers.dahl.sigma0))
        builder.Connect(arm_velocity.get_output_port(), adapter.GetInputPort("arm_velocity_estimate_rad_per_s"))
        builder.Connect(dahl.GetOutputPort("bristle_state_rad"), adapter.GetInputPort("bristle_state_rad"))
        builder.Connect(error, adapter.GetInputPort("friction_error_estimate_Nm"))
        builder.Connect(adapter.GetOutputPort("K_sigma"), dahl.GetInputPort("K_sigma"))
        signals.append(adapter.GetOutputPort("K_sigma_branches"))
    for port in signals:
        LogVectorOutput(port, builder, publish_period=period)
    return estimate, friction if config.controller.friction_compensation else None


def time_floor(config: SimulationConfig, gain: np.ndarray, bare: bool = False) -> float:
    simulator = floor_simulator(config, gain, bare)
    start = time.process_time()
    simulator.Initialize()
    simulator.AdvanceTo(config.duration)
    return time.process_time() - start


def time_package(config: SimulationConfig) -> tuple[float, SimulationResult]:
    built = build_furuta_diagram(config)
    start = time.process_time()
    result = simulate(config, built=built)
    return time.process_time() - start, result


# --- The scipy peer -----------------------------------------------------------------------------------------------


def held_input_discretisation(A: np.ndarray, B: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
    """Ad, Bd of dx/dt = A x + B u with u held over h (matrix exponential of the augmented system)."""
    n, m = B.shape
    augmented = np.zeros((n + m, n + m))
    augmented[:n, :n], augmented[:n, n:] = A, B
    exponential = expm(augmented * h)
    return exponential[:n, :n], exponential[:n, n:]


def scipy_closed_loop(config: SimulationConfig, gain: np.ndarray) -> tuple[float, np.ndarray, np.ndarray]:
    """CPU time, true states [theta, phi, theta_dot, phi_dot] and encoder angles at each sample of the peer
    (see the module docstring). Row k is the sample at t_k = k h, like ``SimulationResult.state``/``measured``."""
    rig, h = config.rig, config.control_period
    count = config.encoder.encoder_resolution
    limit = config.controller.lqr.torque_limit
    negative_gain = -np.asarray(gain, dtype=float).ravel()
    source = config.controller.velocity_source
    compensate = config.controller.friction_compensation
    A, B_F = linearized_upright(rig)
    if source == "hg":
        continuous = continuous_high_gain_observer(A, B_F, config.observers.hg)
    else:
        continuous = continuous_vfe_observer(A, B_F, config.observers.vfe)
    Ad, Bd = held_input_discretisation(continuous.A(), continuous.B(), h)
    dahl = config.observers.dahl
    adapt = dahl.adaptation is not None
    adaptation = dahl.adaptation.k_sigma if adapt else None
    sigma0 = dahl.sigma0

    frictionless = JointFrictionParameters()  # the package's closed-form equations, frictionless like this loop
    model = Model.from_rig(rig).replace(arm_friction=frictionless, pendulum_friction=frictionless)

    def dynamics(t, x, u):
        return _accelerations(model, x, u)

    def quantise(x):
        return np.array([count * round(x[0] / count), count * round(x[1] / count)])

    steps = round(config.duration / h)
    states, measured = np.empty((steps, 4)), np.empty((steps, 2))
    start = time.process_time()
    x = np.asarray(config.initial_state, dtype=float)
    y = quantise(x)  # the encoder's initialization sample
    observer = np.zeros(Ad.shape[0])
    z, k_sigma, u = 0.0, [adaptation.initial, adaptation.initial] if adapt else [1.0, 1.0], 0.0
    for k in range(steps):
        t = k * h
        states[k] = x
        # Every block reads the values held before this sample (Drake's discrete update semantics).
        f_hat = 0.0
        if source == "vfe":
            v = observer[3]
            branch = 0 if v > 0 else 1
            f_hat = -(k_sigma[branch] if adapt else 1.0) * sigma0 * z
            level = dahl.coulomb_pos if v > 0 else dahl.coulomb_neg
            rate = sigma0 * abs(v) / level
            decay = math.exp(-rate * h)
            steady = level * np.sign(v) / sigma0
            injection = -(sigma0 / dahl.rho) * (y[1] + dahl.rho2 * v)
            held = -math.expm1(-rate * h) / rate if rate > 0 else h
            z_next = steady + (z - steady) * decay + held * injection
            if adapt and t >= adaptation.enable_time and abs(v) > adaptation.velocity_threshold:
                k_sigma[branch] += h * -adaptation.gamma * observer[5] * sigma0 * z
            observer_input = np.array([y[0], y[1], u, f_hat])
            z = z_next
        elif source == "hg":
            observer_input = np.array([y[0], y[1], u])
        if source == "true":
            estimate = np.array([y[0], y[1], x[2], x[3]])
        else:
            estimate = observer[:4]
        u_lq = float(negative_gain @ estimate)
        if source != "true":
            observer = Ad @ observer + Bd @ observer_input
        u = min(max(u_lq - f_hat if compensate else u_lq, -limit), limit)
        y = measured[k] = quantise(x)
        x = solve_ivp(dynamics, (t, t + h), x, args=(u,), rtol=PEER_RTOL, atol=PEER_ATOL).y[:, -1]
    return time.process_time() - start, states, measured


# --- The table ----------------------------------------------------------------------------------------------------


def agreement(
    config: SimulationConfig, result: SimulationResult, states: np.ndarray, measured: np.ndarray
) -> tuple[float, float]:
    """(max |x_package - x_peer| up to the first sample whose encoder counts differ, that sample's time [s];
    the run's duration if none differs)."""
    differs = np.flatnonzero(np.any(result.measured != measured, axis=1))
    first = differs[0] if differs.size else len(states)
    return float(np.max(np.abs(result.state[:first] - states[:first]))), first * config.control_period


def with_fine_encoder(config: SimulationConfig) -> SimulationConfig:
    return dataclasses.replace(config, encoder=dataclasses.replace(config.encoder, counts_per_rev=FINE_COUNTS))


def measure(configs: dict[str, SimulationConfig], repeats: int) -> dict[str, dict]:
    """Per configuration, the best of ``repeats`` interleaved runs: ``package``, ``wall``, ``floor``, ``bare``
    and ``peer`` [s], and on the first repeat the agreement with the peer: ``until`` (:func:`agreement`) and
    ``check`` (the 2^32-count encoder's max |dx|)."""
    times = {name: dict.fromkeys(("package", "wall", "floor", "bare", "peer"), math.inf) for name in configs}
    for repeat in range(repeats):  # interleaved: other load on the machine comes and goes
        for name, config in configs.items():
            best = times[name]
            seconds, result = time_package(config)
            best["package"], best["wall"] = min(best["package"], seconds), min(best["wall"], result.wall_time)
            best["floor"] = min(best["floor"], time_floor(config, result.lqr_gain))
            best["bare"] = min(best["bare"], time_floor(config, result.lqr_gain, bare=True))
            seconds, states, measured = scipy_closed_loop(config, result.lqr_gain)
            best["peer"] = min(best["peer"], seconds)
            if repeat == 0:
                best["until"] = agreement(config, result, states, measured)
                _, fine_states, _ = scipy_closed_loop(with_fine_encoder(config), result.lqr_gain)
                best["check"] = float(np.max(np.abs(simulate(with_fine_encoder(config)).state - fine_states)))
    return times


def report(times: dict[str, dict], duration: float, repeats: int) -> None:
    """The table and the targets."""
    print(
        f"{duration:g} s closed loop, Lund rig, best of {repeats}, CPU seconds on one core; x real = "
        f"simulated / CPU s, ratio = CPU s / C++ floor's (x bare: / the bare loop's), speedup = scipy peer's CPU s / "
        f"CPU s"
    )
    print(
        f"{'config':<11} {'cpu [s]':>7} {'wall [s]':>8} {'x real':>6} {'floor [s]':>9} {'ratio':>5} {'x bare':>6} "
        f"{'scipy [s]':>9} {'speedup':>7} | {'max|dx| until counts differ (t)':>31} {'2^32-count max|dx|':>18}"
    )
    for name, t in times.items():
        deviation, time_differs = t["until"]
        print(
            f"{name:<11} {t['package']:>7.3f} {t['wall']:>8.3f} {duration / t['package']:>6.1f} {t['floor']:>9.3f} "
            f"{t['package'] / t['floor']:>5.2f} {t['package'] / t['bare']:>6.2f} {t['peer']:>9.2f} "
            f"{t['peer'] / t['package']:>7.1f} | {deviation:>22.1e} ({time_differs:>5.2f} s) {t['check']:>18.1e}"
        )
    full = times["VFE+Dahl+K"]
    checks = [
        (f"full diagram >= {TARGET_REAL_TIME:g}x real time", duration / full["package"] >= TARGET_REAL_TIME),
        (
            f"full diagram <= {TARGET_FLOOR_RATIO:g}x its C++ floor",
            full["package"] / full["floor"] <= TARGET_FLOOR_RATIO,
        ),
        (
            f"full diagram >= {TARGET_PEER_SPEEDUP:g}x faster than the scipy peer",
            full["peer"] / full["package"] >= TARGET_PEER_SPEEDUP,
        ),
        (
            f"package = scipy peer within {TOLERANCE:g} (2^32-count encoder)",
            max(t["check"] for t in times.values()) <= TOLERANCE,
        ),
    ]
    for label, met in checks:
        print(f"{label}: {'met' if met else 'NOT met'}")
    print(
        f"the C++ floor itself is {full['peer'] / full['floor']:.1f}x faster than the scipy peer (full diagram's "
        f"loop): the ceiling of the speedup for any Drake diagram of this loop"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=10.0, help="simulated seconds per run")
    parser.add_argument("--repeats", type=int, default=3, help="timed runs per configuration (the best is kept)")
    parser.add_argument("--profile", action="store_true", help="print the profile of the full diagram's run")
    args = parser.parse_args()
    configs = configurations(args.duration)
    report(measure(configs, args.repeats), args.duration, args.repeats)
    if args.profile:
        full = configs["VFE+Dahl+K"]
        profiler = cProfile.Profile()
        built = build_furuta_diagram(full)
        profiler.runcall(simulate, full, built=built)
        pstats.Stats(profiler).sort_stats("tottime").print_stats(12)


if __name__ == "__main__":
    main()
