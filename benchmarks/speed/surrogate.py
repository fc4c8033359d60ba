"""Speed of the diagnosis surrogate's compiled RK4 against scipy's ``solve_ivp`` on the same windows.

QUBE-Servo 2 windows of 250 samples at 1 kHz (1 ms RK4 steps) from random states under a random held torque, the
arm with Dahl friction and the pendulum with Coulomb friction. The reference integrates each window with
``solve_ivp`` (RK45, rtol 1e-10, steps of at most the held input's 1 ms) on the surrogate's own right-hand side
(``_accelerations``, the bristle's torque from the Dahl law of ``friction.py``), in this process. Printed: time per
window and per window-step of each, their ratio, and the largest difference of the angles in encoder counts (the
compiled RK4's own integration error). The compiled kernel is also timed at 40, 200 and 1000 windows: a fit's
cost evaluations use a few hundred.

Run from the repository root: ``PYTHONPATH=. python benchmarks/speed/surrogate.py``.
"""

from __future__ import annotations

import time

import numpy as np
from scipy.integrate import solve_ivp

from furuta_drake.effects.surrogate import Model, _accelerations, predict_windows
from furuta_drake.friction import JointFrictionParameters, bristle_derivative, bristle_friction_torque
from furuta_drake.rig import encoder_resolution, qube_servo2_rig

HORIZON, PERIOD = 250, 1e-3


def _problem(windows: int, seed: int = 0):
    rig = qube_servo2_rig()
    model = Model.from_rig(rig).replace(
        arm_friction=JointFrictionParameters.dahl(1.5e-3, 1.5e-3, sigma0=1.5),
        pendulum_friction=JointFrictionParameters.coulomb(5e-5, regularization_velocity=0.02),
    )
    rng = np.random.default_rng(seed)
    command = 0.3 * rig.gravity_torque * rng.standard_normal(20 * HORIZON)
    starts = rng.integers(300, command.size - HORIZON, windows)
    x0 = np.vstack([rng.uniform(-np.pi, np.pi, windows), rng.uniform(-1, 1, (3, windows))])
    return rig, model, command, starts, x0


def _reference(model: Model, command, start: int, x0: np.ndarray) -> np.ndarray:
    """One window by solve_ivp: the plant's 4 states and the arm's bristle (Eq. 7) as a 5th."""
    p = model.arm_friction

    def rhs(t, y):
        tau = command[start + min(int(t / PERIOD + 1e-9), HORIZON - 2)]
        tau += bristle_friction_torque(y[4], y[3], p)
        return np.append(_accelerations(model, y[:4], tau), bristle_derivative(y[4], y[3], p))

    times = np.arange(HORIZON) * PERIOD
    sol = solve_ivp(rhs, (0, times[-1]), np.append(x0, 0.0), t_eval=times, rtol=1e-10, atol=1e-12, max_step=PERIOD)
    return sol.y[:2]


def main() -> None:
    rig, model, command, starts, x0 = _problem(20)
    count = encoder_resolution(rig.counts_per_rev)
    predict_windows(model, x0, command, starts, HORIZON, PERIOD, 1, np.zeros(starts.size))  # compile (or load)
    t = time.perf_counter()
    compiled = predict_windows(model, x0, command, starts, HORIZON, PERIOD, 1, np.zeros(starts.size))
    compiled_s = time.perf_counter() - t
    t = time.perf_counter()
    reference = np.stack([_reference(model, command, s, x0[:, w]) for w, s in enumerate(starts)], axis=-1)
    reference_s = time.perf_counter() - t
    steps = starts.size * (HORIZON - 1)
    print(f"{starts.size} windows of {HORIZON} samples at {PERIOD * 1e3:g} ms, Dahl arm, Coulomb pendulum")
    for label, seconds in (("solve_ivp RK45 (reference)", reference_s), ("compiled RK4", compiled_s)):
        per_window, per_step = seconds / starts.size * 1e3, seconds / steps * 1e9
        print(f"  {label + ':':28s}{per_window:9.3f} ms/window {per_step:9.0f} ns/step")
    print(f"  ratio reference / compiled: {reference_s / compiled_s:9.0f}x")
    print(
        f"  largest angle difference:   {np.max(np.abs(compiled.transpose(1, 0, 2) - reference)) / count:9.4f} counts"
    )
    for windows in (40, 200, 1000):
        _, _, command, starts, x0 = _problem(windows, seed=1)
        t = time.perf_counter()
        for _ in range(5):
            predict_windows(model, x0, command, starts, HORIZON, PERIOD, 1, np.zeros(windows))
        seconds = (time.perf_counter() - t) / 5
        per_step = seconds / (windows * (HORIZON - 1)) * 1e9
        print(f"  compiled, {windows:4d} windows:      {seconds * 1e3:9.2f} ms/call   {per_step:9.0f} ns/step")


if __name__ == "__main__":
    main()
