"""The nested loop (plant, observer, Dahl observer, LQR) linearized at the upright and affine in a frozen K_sigma,
and the tools that judge its stability: stable K_sigma intervals, common quadratic Lyapunov functions, a sampled
region of attraction and basin maps (the paper leaves stability open, Sec. VI-VII).

**Linearization at the upright.** At rest (velocity 0) a Dahl (or LuGre) bristle is in its presliding regime,
where it is linear: dz/dt = v - sigma0 |v| z / Fc(v) has the derivative v at v = 0 (|v| z is of second order),
so the friction is a spring of stiffness sigma0 on the bristle, F = -sigma0 z, z' = joint velocity. Drake's
``Linearize`` of the MultibodyPlant with the :class:`~furuta_drake.friction.JointFriction` system gives exactly
this (:func:`presliding_plant`). The Dahl observer (Eq. 8-9, 16) is linear there too: z_hat' = v_hat + K_z,
K_z = -(sigma0_hat / rho) (eps_phi + rho2 eps_v) (the sigma1 |v| factor is 1 at v = 0) and F_hat = -K_sigma
(sigma0_hat z_hat + (sigma1 + sigma2) v_hat). With K_sigma frozen, the loop plant (+ presliding friction) +
observer (VFE, Eq. 11, fed by F_hat; or HG, Eq. 4) + Dahl observer + LQR with compensation u = u_LQ - F_hat is
a linear system, affine in K_sigma: A(K_sigma) = A0 + K_sigma A1 (:func:`linear_loop`), in continuous time or
as the loop of the simulation sampled at the control period (zero-order hold of the plant, the observers' exact
discretisation, the Dahl observer's exact step linearized to z_hat + h (v_hat + K_z), the controller's one-period
hold).
Coulomb levels do not enter: they only set how far the presliding regime reaches (|F| well below Fc).

**The conserved mode.** z - angle is constant in presliding (z' = joint velocity), whatever the controller:
the linearized loop always has an eigenvalue 0 (1 in discrete time), the memory of where the bristle stuck.
Equilibria form a line: the arm returns to phi = 0 (the Dahl observer's K_z is an integral action on eps_phi)
while the bristle keeps a preload that F_hat compensates. Stability is judged on the invariant subspace
{z - angle = 0} (``W x = 0``), whose eigenvalues are the others.

**Adaptation.** Eq. 18 adapts only while |v_hat| exceeds its threshold (Sec. V-C), so near the equilibrium
K_sigma is frozen and the frozen-K_sigma eigenvalues decide local stability. The K_sigma+/- branches switch
with the sign of v_hat, and adaptation moves K_sigma while the arm moves: a common quadratic Lyapunov function
(:func:`common_lyapunov`) on an interval of K_sigma covers any K_sigma(t) in it (A is affine in K_sigma, so
its two ends suffice).

What this does not prove: the sliding regime (|F| at Fc, the |v| z terms) is nonlinear and outside the
linearization; the Coulomb friction of the pendulum has no linearization (left out: it only dissipates);
saturation and quantisation are left out. :func:`lyapunov_region` (a sampled quadratic Lyapunov estimate of the
true-state LQR loop with the torque limit, where Drake's ``RegionOfAttraction`` on a cubic fit of the plant is
beyond Clarabel and CSDP) and :func:`basin_map` (the full nonlinear sampled loop simulated from a
grid of initial states) cover the large motions.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np
from pydrake.solvers import ClarabelSolver, MathematicalProgram
from pydrake.systems.analysis import DiscreteTimeApproximation

from furuta_drake.config import SimulationConfig
from furuta_drake.controllers.lqr import upright_linearization, zero_order_hold
from furuta_drake.diagram import controller_gain
from furuta_drake.errors import ConfigError, SimulationDiverged
from furuta_drake.friction import FrictionParameters, JointFrictionParameters
from furuta_drake.observers.hg import continuous_high_gain_observer
from furuta_drake.observers.vfe import continuous_vfe_observer
from furuta_drake.plant import make_furuta_plant, plant_to_paper_permutation
from furuta_drake.rig import linearized_upright
from furuta_drake.world import linearized_world

OBSERVERS = ("vfe", "hg")


@dataclass
class PreslidingPlant:
    """The plant with its bristles linearized at the upright: d/dt [x; z] = A [x; z] + B u, x in paper order,
    z the bristle states (pendulum before arm, bristle models only); ``conserved`` rows W with W A = 0 (one
    z - angle per bristle)."""

    A: np.ndarray
    B: np.ndarray
    conserved: np.ndarray


def presliding_plant(config: SimulationConfig) -> PreslidingPlant:
    """Drake's ``Linearize`` at the upright of ``config``'s world (:func:`furuta_drake.world.add_furuta_world`)
    with its bristle friction (Dahl/LuGre joints; static Coulomb friction has no linearization at rest and is
    left out) and the rig's back-EMF, permuted to paper order. The actuator chain, spring, cogging and a drive's
    backlash and elasticity are left out."""
    keep = {
        joint: p if p.has_bristles else JointFrictionParameters()
        for joint, p in (("arm", config.friction.arm), ("pendulum", config.friction.pendulum))
    }
    A, B = linearized_world(
        rig=config.rig.with_rigid_drive(), friction=FrictionParameters(**keep), control_period=config.control_period
    )
    nb = A.shape[0] - 4
    bristle_joints = [index for index, p in ((0, keep["pendulum"]), (1, keep["arm"])) if p.has_bristles]
    W = np.zeros((nb, 4 + nb))
    for k, angle in enumerate(bristle_joints):
        W[k, 4 + k], W[k, angle] = 1.0, -1.0
    return PreslidingPlant(A, B, W)


@dataclass
class LinearLoop:
    """The linearized nested loop, affine in K_sigma: A(K_sigma) = ``A0`` + K_sigma ``A1`` (continuous, or the
    one-period map when ``period`` is set). State: [x (4), z (bristles), observer state, z_hat, (u: discrete
    only)]; ``slices`` names these blocks; ``conserved`` W spans z - angle (W A = 0, or W A = W discrete)."""

    A0: np.ndarray
    A1: np.ndarray
    conserved: np.ndarray
    slices: dict
    period: float | None

    def matrix(self, k_sigma: float) -> np.ndarray:
        return self.A0 + k_sigma * self.A1

    def reduced(self, k_sigma: float) -> np.ndarray:
        """A(K_sigma) on the invariant subspace {W x = 0} (an orthonormal basis Q: Q^T A Q)."""
        Q = self._basis()
        return Q.T @ self.matrix(k_sigma) @ Q

    def _basis(self) -> np.ndarray:
        if not hasattr(self, "_Q"):
            n = self.A0.shape[0]
            if self.conserved.shape[0] == 0:
                self._Q = np.eye(n)
            else:
                _, _, Vt = np.linalg.svd(self.conserved)
                self._Q = Vt[self.conserved.shape[0] :].T
        return self._Q

    def eigenvalues(self, k_sigma: float) -> np.ndarray:
        """Eigenvalues on the invariant subspace (the conserved mode removed)."""
        return np.linalg.eigvals(self.reduced(k_sigma))

    def decay_rate(self, k_sigma: float) -> float:
        """The slowest mode's rate [1/s]: max Re(lambda), or ln(max |z|) / period in discrete time (< 0:
        stable)."""
        eigenvalues = self.eigenvalues(k_sigma)
        if self.period is None:
            return float(np.max(eigenvalues.real))
        return float(np.log(np.max(np.abs(eigenvalues))) / self.period)


def linear_loop(
    config: SimulationConfig,
    observer: str = "vfe",
    discrete: bool = False,
    friction_compensation: bool = True,
    injection_sign: int = 1,
) -> LinearLoop:
    """The loop of ``config`` (its rig, bristle friction, LQR design, observer gains, Dahl observer) linearized
    at the upright with ``observer`` feeding the LQR and the Dahl observer (module docstring); ``discrete``: at
    the control period. The LQR is ``config``'s gain or its design, as in :func:`furuta_drake.diagram`.
    ``injection_sign`` multiplies K_z: 1 is Eq. 9 as printed (and as DahlFrictionObserver implements it), -1
    the reversed injection."""
    if observer not in OBSERVERS:
        raise ConfigError(f"observer must be one of {list(OBSERVERS)}, got {observer!r}")
    if injection_sign not in (1, -1):
        raise ConfigError(f"injection_sign must be 1 or -1, got {injection_sign!r}")
    config.validate()
    dahl = config.observers.dahl
    A_model, B_F = linearized_upright(config.rig)
    K = controller_gain(make_furuta_plant(config.rig), config)
    plant = presliding_plant(config)
    npl = plant.A.shape[0]
    period = config.control_period
    if observer == "vfe":
        obs = continuous_vfe_observer(A_model, B_F, config.observers.vfe)
    else:
        obs = continuous_high_gain_observer(A_model, B_F, config.observers.hg)
    nw = obs.A().shape[0]
    s = {"plant": slice(0, npl), "observer": slice(npl, npl + nw), "z_hat": npl + nw}
    n = npl + nw + 1 + (1 if discrete else 0)
    if discrete:
        s["command"] = n - 1
    y = np.zeros((2, n))
    y[:, s["plant"]] = np.eye(npl)[:2]  # the measured [theta, phi]
    x_hat = np.zeros((4, n))
    x_hat[:, s["observer"]] = np.eye(nw)[:4]
    v_hat = x_hat[3]
    # F_hat = K_sigma f1 . state (Eq. 16 linearized); the command u = u0 . state + K_sigma u1 . state (in
    # discrete time the held command is a state, updated from x_hat and F_hat).
    f1 = -(dahl.sigma0 * np.eye(n)[s["z_hat"]] + (dahl.sigma1 + dahl.sigma2) * v_hat)
    compensation = 1.0 if friction_compensation else 0.0
    if discrete:
        u0, u1 = np.eye(n)[s["command"]], np.zeros(n)
    else:
        u0, u1 = -K @ x_hat, -compensation * f1
    # Eq. 9 linearized: z_hat' = v_hat - (sigma0 / rho) (phi + rho2 v_hat).
    z_rate = v_hat.copy()
    if dahl.rho is not None:
        z_rate -= injection_sign * (dahl.sigma0 / dahl.rho) * (y[1] + dahl.rho2 * v_hat)
    A0, A1 = np.zeros((n, n)), np.zeros((n, n))
    if discrete:
        Phi, Gamma = zero_order_hold(plant.A, plant.B, period)
        observer_d = DiscreteTimeApproximation(obs, period)
        Ad, Bd = observer_d.A(), observer_d.B()
        A0[s["plant"], s["plant"]] = Phi
        A0[s["plant"]] += np.outer(Gamma[:, 0], u0)
        A0[s["observer"], s["observer"]] = Ad
        A0[s["observer"]] += Bd[:, :2] @ y + np.outer(Bd[:, 2], u0)
        A1[s["observer"]] += np.outer(Bd[:, 3], f1) if observer == "vfe" else 0.0
        A0[s["z_hat"]] = np.eye(n)[s["z_hat"]] + period * z_rate
        A0[s["command"]] = -K @ x_hat
        A1[s["command"]] = -compensation * f1
    else:
        A0[s["plant"], s["plant"]] = plant.A
        A0[s["plant"]] += np.outer(plant.B[:, 0], u0)
        A1[s["plant"]] += np.outer(plant.B[:, 0], u1)
        A0[s["observer"], s["observer"]] = obs.A()
        Bo = obs.B()
        A0[s["observer"]] += Bo[:, :2] @ y + np.outer(Bo[:, 2], u0)
        A1[s["observer"]] += np.outer(Bo[:, 2], u1) + (np.outer(Bo[:, 3], f1) if observer == "vfe" else 0.0)
        A0[s["z_hat"]] = z_rate
    W = np.zeros((plant.conserved.shape[0], n))
    W[:, s["plant"]] = plant.conserved
    return LinearLoop(A0, A1, W, s, period if discrete else None)


def stable_intervals(
    loop: LinearLoop, k_min: float = 0.05, k_max: float = 6.0, points: int = 240, tolerance: float = 1e-4
) -> list[tuple[float, float]]:
    """The intervals of frozen K_sigma in [k_min, k_max] where the loop is exponentially stable (decay rate < 0),
    each end refined by bisection to ``tolerance``; an end at k_min or k_max means the stable range goes on."""
    grid = np.geomspace(k_min, k_max, points)
    stable = np.array([loop.decay_rate(k) < 0 for k in grid])

    def edge(a: float, b: float) -> float:  # the stability changes between a and b
        stable_a = loop.decay_rate(a) < 0
        while b - a > tolerance:
            middle = 0.5 * (a + b)
            if (loop.decay_rate(middle) < 0) == stable_a:
                a = middle
            else:
                b = middle
        return 0.5 * (a + b)

    intervals, start = [], None
    for i, k in enumerate(grid):
        if stable[i] and start is None:
            start = k_min if i == 0 else edge(grid[i - 1], k)
        if start is not None and (i == points - 1 or not stable[i + 1]):
            intervals.append((start, k_max if i == points - 1 else edge(k, grid[i + 1])))
            start = None
    return intervals


def interval_containing(intervals: list[tuple[float, float]], k_sigma: float) -> tuple[float, float] | None:
    """The interval of ``intervals`` that contains ``k_sigma``, or None."""
    return next(((a, b) for a, b in intervals if a <= k_sigma <= b), None)


def common_lyapunov(loop: LinearLoop, k_low: float, k_high: float, rate: float = 0.01) -> np.ndarray | None:
    """A common quadratic Lyapunov function V = xi^T P xi of the reduced loop for every K_sigma in
    [k_low, k_high] (so for any K_sigma(t) there: branch switching, adaptation), or None when the SDP finds
    none. A is affine in K_sigma, so the two ends suffice; V decays at least at ``rate`` [1/s]: continuous
    A_i^T P + P A_i <= -2 rate P, discrete [[(1 - 2 rate h) P, A_i^T P], [P A_i, P]] >= 0, with P >= I.
    Solved with Clarabel and checked a posteriori on the returned P (the certificate does not rest on the
    solver's tolerances)."""
    ends = [loop.reduced(k) for k in (k_low, k_high)]
    n = ends[0].shape[0]
    prog = MathematicalProgram()
    P = prog.NewSymmetricContinuousVariables(n, "P")
    prog.AddPositiveSemidefiniteConstraint(P - np.eye(n))
    for A in ends:
        if loop.period is None:
            prog.AddPositiveSemidefiniteConstraint(-(A.T @ P + P @ A) - 2.0 * rate * P)
        else:
            prog.AddPositiveSemidefiniteConstraint(
                np.block([[(1.0 - 2.0 * rate * loop.period) * P, A.T @ P], [P @ A, P]])
            )
    result = ClarabelSolver().Solve(prog)
    if not result.is_success():
        return None
    P_value = result.GetSolution(P)
    P_value = 0.5 * (P_value + P_value.T)
    if np.min(np.linalg.eigvalsh(P_value)) <= 0:
        return None
    for A in ends:
        decrease = A.T @ P_value + P_value @ A if loop.period is None else A.T @ P_value @ A - P_value
        if not np.max(np.linalg.eigvalsh(decrease)) < 0:
            return None
    return P_value


def widest_common_lyapunov(
    loop: LinearLoop, interval: tuple[float, float], anchor: float = 1.0, steps: int = 8
) -> tuple[float, float] | None:
    """The widest [anchor + s (a - anchor), anchor + s (b - anchor)], s in (0, 1], of the frozen-stable
    ``interval`` = (a, b) with a common quadratic Lyapunov function (bisection on s, ``steps`` SDPs), or None
    when not even the anchor alone has one."""
    a, b = interval

    def ends(s: float) -> tuple[float, float]:
        return anchor + s * (a - anchor), anchor + s * (b - anchor)

    if common_lyapunov(loop, anchor, anchor) is None:
        return None
    if common_lyapunov(loop, *ends(1.0)) is not None:
        return interval
    low, high = 0.0, 1.0
    for _ in range(steps):
        middle = 0.5 * (low + high)
        if common_lyapunov(loop, *ends(middle)) is not None:
            low = middle
        else:
            high = middle
    return ends(low)


@dataclass
class LyapunovRegion:
    """{x : x^T P x <= level} (x = [theta, phi, theta_dot, phi_dot]) where the true-state LQR loop's quadratic
    Lyapunov function decreased at every sampled point (``samples`` of them)."""

    P: np.ndarray
    level: float
    samples: int

    def contains(self, states: np.ndarray) -> np.ndarray:
        states = np.atleast_2d(states)
        return np.einsum("ij,jk,ik->i", states, self.P, states) <= self.level

    def theta_extent(self) -> float:
        """Largest |theta0| at rest inside the region [rad]."""
        return float(np.sqrt(self.level / self.P[0, 0]))


def lyapunov_region(config: SimulationConfig, directions: int = 2000, radii: int = 40, seed: int = 0) -> LyapunovRegion:
    """A region-of-attraction estimate of the balancing loop with the true state: V = x^T P x from the
    Lyapunov equation of the linearized loop with the LQ design's stage cost, (A - B K)^T P + P (A - B K) =
    -(Q + K^T R K) (about the LQ cost-to-go), and the largest level set on
    which dV/dt < 0 at every sampled point, with the MultibodyPlant's full nonlinear dynamics and the torque
    limit u = sat(-K x) (no friction, no observer). Sampled, not certified: ``directions`` random directions,
    each at ``radii`` levels up to the first increase."""
    from pydrake.math import RealContinuousLyapunovEquation

    plant = make_furuta_plant(config.rig)
    context = plant.CreateDefaultContext()
    P_perm = plant_to_paper_permutation(plant)
    A, B = upright_linearization(plant)
    K = controller_gain(plant, config)
    lqr = config.controller.lqr
    P = RealContinuousLyapunovEquation(A - B @ K, np.diag(lqr.state_weights) + lqr.input_weight * K.T @ K)
    limit = lqr.torque_limit
    rng = np.random.default_rng(seed)
    L = np.linalg.cholesky(P)
    unit = rng.standard_normal((directions, 4))
    unit = np.linalg.solve(L.T, (unit / np.linalg.norm(unit, axis=1, keepdims=True)).T).T  # x^T P x = 1
    # The level where the torque limit is first reached, u_max^2 / (K P^-1 K^T), scales the search.
    saturation_level = limit**2 / float((K @ np.linalg.solve(P, K.T))[0, 0])
    levels = saturation_level * np.geomspace(0.1, 30.0, radii)
    level = levels[-1]
    for d in unit:
        for v in levels[levels < level]:
            x = np.sqrt(v) * d
            plant.SetPositionsAndVelocities(context, P_perm.T @ x)
            plant.get_actuation_input_port().FixValue(context, [np.clip(-(K @ x)[0], -limit, limit)])
            xdot = P_perm @ plant.EvalTimeDerivatives(context).CopyToVector()
            if 2.0 * x @ P @ xdot >= 0.0:
                level = v
                break
    return LyapunovRegion(P, float(levels[levels < level][-1]) if np.any(levels < level) else 0.0, directions * radii)


CAUGHT_THETA = 0.05  # [rad] |theta| over the last CAUGHT_WINDOW of a run below this: caught
CAUGHT_WINDOW = 0.2  # [s]
FALLEN_THETA = 0.5  # [rad] the monitor's bound in basin runs (stops a falling run early)


def catches(config: SimulationConfig) -> bool:
    """Whether the full nonlinear sampled loop of ``config`` balances from its initial state: the monitor never
    stops it (|theta| <= FALLEN_THETA, no runaway) and |theta| stays below CAUGHT_THETA over the last
    CAUGHT_WINDOW."""
    from furuta_drake.simulate import simulate

    try:
        result = simulate(config)
    except SimulationDiverged:
        return False
    last = result.time >= result.time[-1] - CAUGHT_WINDOW
    return bool(np.max(np.abs(result.state[last, 0])) < CAUGHT_THETA)


def basin_configs(config: SimulationConfig, thetas, theta_dots, duration: float) -> list[SimulationConfig]:
    """``config`` started at rest in the arm (phi = phi_dot = 0) from every (theta0, theta_dot0) of the grid
    (theta0 fastest), without excitation torque, for ``duration`` s, the monitor stopping falls at
    FALLEN_THETA."""
    from furuta_drake.config import ExcitationConfig

    base = dataclasses.replace(
        config,
        duration=duration,
        excitation=ExcitationConfig(),
        monitor=dataclasses.replace(config.monitor, theta_bound=FALLEN_THETA),
    )
    return [
        dataclasses.replace(base, initial_state=[float(theta), 0.0, float(theta_dot), 0.0])
        for theta_dot in theta_dots
        for theta in thetas
    ]


def basin_map(config: SimulationConfig, thetas, theta_dots, duration: float = 2.0, workers: int = 1) -> np.ndarray:
    """Caught (True) or fallen for each initial (theta0, theta_dot0): shape (len(theta_dots), len(thetas)).
    ``workers`` > 1 runs the simulations on a local Dask cluster of that many processes."""
    configs = basin_configs(config, thetas, theta_dots, duration)
    if workers > 1:
        from furuta_drake.sweep import dask_client, map_on_dask

        with dask_client(workers=workers, tasks=len(configs)) as client:
            outcome = map_on_dask(client, catches, configs)
    else:
        outcome = [catches(c) for c in configs]
    return np.array(outcome, dtype=bool).reshape(len(theta_dots), len(thetas))
