"""Cost of an unmodelled torque in a simulation: the Lund rig balancing under the LQR, with and without a torque
expression on each joint (the form a diagnosis writes: a few library terms), and one call of the expression.

Printed: wall time of each run (best of ``REPEATS``), its ratio to the run without the torque, and the time of one
``Torque.at`` call (the system's per-stage evaluation) and of one vectorised call on 1000 states.

Run from the repository root: ``python benchmarks/unmodelled_torque_speed.py``.
"""

from __future__ import annotations

import time

import numpy as np

from furuta_drake.config import SimulationConfig
from furuta_drake.simulate import simulate
from furuta_drake.unmodelled import UnmodelledTorqueParameters, compile_torque

DURATION, REPEATS = 5.0, 3  # [s] simulated, runs per case
ARM = "0.002*sin(7*phi) - 3e-4*tanh(phi_dot/0.02) + 1e-4*abs(phi_dot)*phi_dot*cos(phi)"
PENDULUM = "-2e-5*tanh(theta_dot/0.02) + 1e-4*sin(theta)"
CASES = {
    "none": UnmodelledTorqueParameters(),
    "arm": UnmodelledTorqueParameters(arm=ARM),
    "arm + pendulum": UnmodelledTorqueParameters(arm=ARM, pendulum=PENDULUM),
}


def _best_wall_time(torque: UnmodelledTorqueParameters) -> float:
    config = SimulationConfig.from_rig("lund", unmodelled_torque=torque, duration=DURATION)
    return min(simulate(config).wall_time for _ in range(REPEATS))


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
    times = {name: _best_wall_time(torque) for name, torque in CASES.items()}
    print(f"Lund rig balancing, {DURATION:g} s simulated, best of {REPEATS}")
    print(f"{'torque':<16}{'wall [s]':>10}{'ratio':>8}")
    for name, wall in times.items():
        print(f"{name:<16}{wall:>10.3f}{wall / times['none']:>8.2f}")
    single, vectorised = _call_times()
    print(f"Torque.at, one state: {single * 1e6:.2f} us; vectorised, 1000 states: {vectorised * 1e6:.1f} us")


if __name__ == "__main__":
    main()
