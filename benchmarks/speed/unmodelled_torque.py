"""Cost of an unmodelled torque in a simulation, and of evaluating its expression.

1. The Lund rig balancing under the LQR (``simulate``), with and without torque expressions of the form a
   diagnosis writes (a few library terms) on the arm and on both joints: wall time, best of ``REPEATS``, and its
   ratio to the run without. A torque changes the motion, so the integrator may take more or fewer steps.
2. A free swing of the world alone (``add_furuta_world``, open loop, RK3 at 1e-4, steps of at most 1 ms as in
   ``simulate``) with the arm torque as :class:`~furuta_drake.unmodelled.UnmodelledTorque` (Python) and, for
   reference, as Drake's C++ ``SymbolicVectorSystem`` of the same expression (which cannot say which key gave a
   non-finite torque): wall time, integrator steps and the final state, so the evaluations are compared on the
   same steps.
3. One ``Torque.at`` call (the system's per-stage evaluation) and one vectorised call on 1000 states.

Run from the repository root: ``python benchmarks/speed/unmodelled_torque.py``.
"""

from __future__ import annotations

import time

import numpy as np
from pydrake.symbolic import Variable, cos, sin, tanh
from pydrake.symbolic import abs as symbolic_abs
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import SymbolicVectorSystem

from furuta_drake.config import SimulationConfig
from furuta_drake.plant import joint_indices
from furuta_drake.rig import lund_rig
from furuta_drake.simulate import simulate
from furuta_drake.unmodelled import UnmodelledTorqueParameters, compile_torque
from furuta_drake.world import add_furuta_world

DURATION, SWING, REPEATS = 5.0, 10.0, 3  # [s] balancing, [s] free swing, runs per case
ARM = "0.002*sin(7*phi) - 3e-4*tanh(phi_dot/0.2) + 1e-4*abs(phi_dot)*phi_dot*cos(phi)"
PENDULUM = "-2e-5*tanh(theta_dot/0.2) + 1e-4*sin(theta)"
CASES = {
    "none": UnmodelledTorqueParameters(),
    "arm": UnmodelledTorqueParameters(arm=ARM),
    "arm + pendulum": UnmodelledTorqueParameters(arm=ARM, pendulum=PENDULUM),
}


def _balancing(torque: UnmodelledTorqueParameters) -> float:
    config = SimulationConfig.from_rig("lund", unmodelled_torque=torque, duration=DURATION)
    return min(simulate(config).wall_time for _ in range(REPEATS))


def _swing(kind: str) -> tuple[float, int, np.ndarray]:
    """(best wall time [s], integrator steps, final paper state) of the free swing with the arm torque as
    ``kind``: "none", "python" or "symbolic"."""
    builder = DiagramBuilder()
    torque = UnmodelledTorqueParameters(arm=ARM) if kind == "python" else None
    world = add_furuta_world(builder, rig=lund_rig(), control_period=1e-3, unmodelled_torque=torque)
    if kind == "symbolic":
        theta, phi, theta_dot, phi_dot, dummy = (Variable(n) for n in ("theta", "phi", "theta_dot", "phi_dot", "z"))
        arm = 0.002 * sin(7 * phi) - 3e-4 * tanh(phi_dot / 0.2) + 1e-4 * symbolic_abs(phi_dot) * phi_dot * cos(phi)
        output = [0.0 * theta, 0.0 * theta]
        output[joint_indices(world.plant)[1]] = arm
        # A SymbolicVectorSystem without state fails in DoCalcTimeDerivatives; one constant state avoids it.
        system = builder.AddSystem(
            SymbolicVectorSystem(
                state=[dummy], input=[theta, phi, theta_dot, phi_dot], dynamics=[0.0 * dummy], output=output
            )
        )
        builder.Connect(world.true_state, system.get_input_port())
        builder.Connect(system.get_output_port(), world.plant.get_applied_generalized_force_input_port())
    builder.ExportInput(world.arm_torque_input)
    diagram = builder.Build()
    best = np.inf
    for _ in range(REPEATS):
        simulator = Simulator(diagram)
        ApplySimulatorConfig(
            SimulatorConfig(integration_scheme="runge_kutta3", accuracy=1e-4, max_step_size=1e-3), simulator
        )
        context = simulator.get_mutable_context()
        diagram.get_input_port().FixValue(context, [0.0])
        plant_context = world.plant.GetMyMutableContextFromRoot(context)
        world.plant.SetPositionsAndVelocities(plant_context, world.to_paper.T @ np.array([2.5, 0.0, 0.0, 3.0]))
        start = time.perf_counter()
        simulator.AdvanceTo(SWING)
        best = min(best, time.perf_counter() - start)
    return best, simulator.get_num_steps_taken(), world.to_paper @ world.plant.GetPositionsAndVelocities(plant_context)


def _call_times() -> tuple[float, float]:
    torque = compile_torque(ARM, "arm")
    x = np.array([0.01, 0.2, -0.1, 0.5])
    n = 20000
    start = time.perf_counter()
    for _ in range(n):
        torque.at(x)
    single = (time.perf_counter() - start) / n
    states = np.random.default_rng(0).uniform(-1, 1, (4, 1000))
    start = time.perf_counter()
    for _ in range(100):
        torque(*states)
    return single, (time.perf_counter() - start) / 100


def main() -> None:
    times = {name: _balancing(torque) for name, torque in CASES.items()}
    print(f"1. Lund rig balancing, {DURATION:g} s simulated, best of {REPEATS}")
    print(f"{'torque':<16}{'wall [s]':>10}{'ratio':>8}")
    for name, wall in times.items():
        print(f"{name:<16}{wall:>10.3f}{wall / times['none']:>8.2f}")
    print(f"2. free swing of the world, {SWING:g} s, arm torque {ARM}")
    print(f"{'system':<16}{'wall [s]':>10}{'steps':>8}  final [theta, phi, theta_dot, phi_dot]")
    for kind in ("none", "python", "symbolic"):
        wall, steps, x = _swing(kind)
        print(f"{kind:<16}{wall:>10.3f}{steps:>8}  {np.array2string(x, precision=8)}")
    single, vectorised = _call_times()
    print(f"3. Torque.at, one state: {single * 1e6:.2f} us; vectorised, 1000 states: {vectorised * 1e6:.1f} us")


if __name__ == "__main__":
    main()
