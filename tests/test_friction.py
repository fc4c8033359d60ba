"""Friction laws and the JointFriction system against closed-form physics: viscous spin-down, Coulomb stop,
Dahl hysteresis and presliding stiffness, energy conservation without friction and dissipation with it,
Drake's Linearize through AutoDiffXd, and the passivity of the laws for random parameters."""

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from pydrake.systems.analysis import ResetIntegratorFromFlags, Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Linearize

from furuta_drake.errors import ConfigError
from furuta_drake.friction import (
    FrictionParameters,
    JointFriction,
    JointFrictionParameters,
    JointFrictionSystem,
    bristle_derivative,
    bristle_friction_torque,
    dahl_exact_step,
    static_friction_torque,
    stribeck_curve,
)
from furuta_drake.plant import add_furuta_plant, make_furuta_plant, plant_to_paper_permutation
from furuta_drake.rig import linearized_upright, lund_rig

RIG = lund_rig()
ARM_INERTIA = RIG.arm_inertia_total  # J_arm + m r^2: the arm with the hanging pendulum held rigid [kg m^2]
ENERGY_SCALE = RIG.gravity_torque  # m g l [J]


class Furuta:
    """The Lund plant with a friction system (``law``: the simulations' C++ JointFrictionSystem by default) wired to
    its applied-generalized-force input, zero motor torque."""

    def __init__(self, friction: FrictionParameters, law=JointFrictionSystem):
        builder = DiagramBuilder()
        self.plant, _ = add_furuta_plant(builder, "lund", with_scene_graph=False)
        self.friction = builder.AddSystem(law(self.plant, friction))
        builder.Connect(self.plant.get_state_output_port(), self.friction.get_input_port())
        builder.Connect(
            self.friction.GetOutputPort("generalized_force_Nm"), self.plant.get_applied_generalized_force_input_port()
        )
        builder.ExportInput(self.plant.get_actuation_input_port(), "arm_torque_Nm")
        self.diagram = builder.Build()

    def simulate(self, times, *, theta, phi_dot, lock_pendulum=False, accuracy=1e-8, integrator="runge_kutta3"):
        """Start at rest but for the arm rate, advance through ``times``; return per sample
        [phi, theta, phi_dot, theta_dot, plant energy, bristle states...]."""
        context = self.diagram.CreateDefaultContext()
        self.diagram.get_input_port(0).FixValue(context, [0.0])
        plant_context = self.plant.GetMyMutableContextFromRoot(context)
        arm, pendulum = self.plant.GetJointByName("arm"), self.plant.GetJointByName("pendulum")
        pendulum.set_angle(plant_context, theta)
        arm.set_angular_rate(plant_context, phi_dot)
        if lock_pendulum:
            pendulum.Lock(plant_context)
        simulator = Simulator(self.diagram, context)
        ResetIntegratorFromFlags(simulator, integrator, 0.01)
        simulator.get_mutable_integrator().set_target_accuracy(accuracy)
        friction_context = self.friction.GetMyContextFromRoot(context)
        rows = []
        for t in times:
            simulator.AdvanceTo(t)
            energy = self.plant.CalcKineticEnergy(plant_context) + self.plant.CalcPotentialEnergy(plant_context)
            bristles = friction_context.get_continuous_state_vector().CopyToVector()
            rows.append(
                [
                    arm.get_angle(plant_context),
                    pendulum.get_angle(plant_context),
                    arm.get_angular_rate(plant_context),
                    pendulum.get_angular_rate(plant_context),
                    energy,
                    *bristles,
                ]
            )
        return np.array(rows)


def test_the_arm_inertia_with_the_pendulum_hanging_is_the_rigs_lumped_constant():
    plant = make_furuta_plant("lund")
    context = plant.CreateDefaultContext()
    plant.GetJointByName("pendulum").set_angle(context, math.pi)
    arm = plant.GetJointByName("arm").velocity_start()
    assert plant.CalcMassMatrix(context)[arm, arm] == pytest.approx(ARM_INERTIA, rel=1e-6)


def test_viscous_friction_spins_the_arm_down_exponentially():
    """J phi'' = -b phi' (pendulum locked hanging, so the arm is one rigid body): phi' = w0 exp(-b t / J)."""
    b, w0 = 2e-3, 3.0
    furuta = Furuta(FrictionParameters(arm=JointFrictionParameters(model="static", viscous=b)))
    times = np.array([0.25, 0.5, 1.0, 2.0, 4.0])
    rows = furuta.simulate(times, theta=math.pi, phi_dot=w0, lock_pendulum=True, accuracy=1e-7)
    np.testing.assert_allclose(rows[:, 2], w0 * np.exp(-b * times / ARM_INERTIA), rtol=1e-4)
    # The arm angle is the integral: (J w0 / b)(1 - exp(-b t / J)).
    np.testing.assert_allclose(rows[:, 0], ARM_INERTIA * w0 / b * (1 - np.exp(-b * times / ARM_INERTIA)), rtol=1e-4)


def test_coulomb_friction_stops_the_arm_at_j_w0_over_fc():
    """Constant torque Fc against the motion: phi' = w0 - Fc t / J until t_stop = J w0 / Fc, having travelled
    J w0^2 / (2 Fc); then the arm stays at rest. tanh(v / v_reg) is within 1e-4 of sign(v) above 5 v_reg."""
    fc, w0 = 0.01, 2.0
    arm = JointFrictionParameters.coulomb(fc)
    furuta = Furuta(FrictionParameters(arm=arm))
    t_stop = ARM_INERTIA * w0 / fc
    times = np.arange(1, 1101) * 1e-3
    rows = furuta.simulate(times, theta=math.pi, phi_dot=w0, lock_pendulum=True, accuracy=1e-6)
    sliding = times < 0.9 * t_stop
    np.testing.assert_allclose(rows[sliding, 2], w0 - fc * times[sliding] / ARM_INERTIA, rtol=1e-3)
    stopped_at = times[np.argmax(rows[:, 2] < 5 * arm.regularization_velocity)]
    assert stopped_at == pytest.approx(t_stop, rel=2e-2)
    assert np.all(np.abs(rows[times > 1.02 * t_stop, 2]) < 1e-3 * w0)
    assert rows[-1, 0] == pytest.approx(ARM_INERTIA * w0**2 / (2 * fc), rel=2e-2)


def run_friction_alone(params: FrictionParameters, *, theta_dot: float, phi_dot: float, duration: float):
    """JointFriction driven by a constant plant state; returns (friction_torque_Nm, generalized_force_Nm)."""
    plant = make_furuta_plant("lund")
    system = JointFriction(plant, params)
    context = system.CreateDefaultContext()
    x = np.zeros(plant.num_multibody_states())
    nq = plant.num_positions()
    x[nq + plant.GetJointByName("pendulum").velocity_start()] = theta_dot
    x[nq + plant.GetJointByName("arm").velocity_start()] = phi_dot
    system.get_input_port().FixValue(context, x)
    simulator = Simulator(system, context)
    simulator.get_mutable_integrator().set_target_accuracy(1e-10)
    simulator.AdvanceTo(duration)
    torque = system.GetOutputPort("friction_torque_Nm").Eval(context)
    force = system.GetOutputPort("generalized_force_Nm").Eval(context)
    expected_force = np.zeros(plant.num_velocities())
    expected_force[plant.GetJointByName("pendulum").velocity_start()] = torque[0]
    expected_force[plant.GetJointByName("arm").velocity_start()] = torque[1]
    np.testing.assert_array_equal(force, expected_force)
    return torque, force


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_dahl_friction_settles_to_the_coulomb_level_of_each_direction(direction):
    """At constant v, Eq. 7 drives z to Fc(v) sign(v) / sigma0 at the rate sigma0 |v| / Fc: the exerted torque
    tends to -Fc(v) sign(v), with Fc+ = 0.012 N m and Fc- = 0.018 N m on the arm (the paper's Sec. V-D) and another pair
    on the pendulum moving the other way."""
    params = FrictionParameters(
        arm=JointFrictionParameters.dahl(0.012, 0.018, sigma0=10.0),
        pendulum=JointFrictionParameters.dahl(0.002, 0.003, sigma0=5.0),
    )
    # 0.5 rad/s for 0.2 s: 83 arm and 417 pendulum time constants (slowest: Fc- of the arm, 0.018/(10*0.5) s).
    torque, _ = run_friction_alone(params, theta_dot=-0.5 * direction, phi_dot=0.5 * direction, duration=0.2)
    arm_level, pendulum_level = (0.012, 0.003) if direction > 0 else (0.018, 0.002)
    np.testing.assert_allclose(torque, [direction * pendulum_level, -direction * arm_level], rtol=1e-6)


def test_dahl_presliding_stiffness_is_sigma0_and_follows_the_hysteresis_curve():
    """Dahl friction is rate-independent: from rest (z = 0) over a monotone displacement x, Eq. 7 gives
    F(x) = -Fc (1 - exp(-sigma0 x / Fc)), so dF/dx = -sigma0 at x = 0."""
    fc, sigma0, v = 0.012, 10.0, 1e-3
    params = FrictionParameters(arm=JointFrictionParameters.dahl(fc, fc, sigma0=sigma0))
    x_small = 1e-6  # sigma0 x / Fc = 8e-4: F = -sigma0 x (1 - 4e-4)
    torque, _ = run_friction_alone(params, theta_dot=0.0, phi_dot=v, duration=x_small / v)
    assert torque[1] / x_small == pytest.approx(-sigma0, rel=1e-3)
    assert torque[0] == 0.0
    for x in (0.5 * fc / sigma0, 2.0 * fc / sigma0):
        torque, _ = run_friction_alone(params, theta_dot=0.0, phi_dot=v, duration=x / v)
        assert torque[1] == pytest.approx(-fc * (1 - math.exp(-sigma0 * x / fc)), rel=1e-6)
        # The discrete observers' exact step reaches the same bristle state in one step of any size.
        assert -sigma0 * dahl_exact_step(0.0, v, x / v, sigma0, fc) == pytest.approx(torque[1], rel=1e-6)


@pytest.mark.parametrize("direction", [1.0, -1.0])
def test_lugre_and_static_models_settle_on_the_stribeck_curve(direction):
    """At constant v the LuGre bristle stops (dz/dt = 0), leaving F = -(g(v) sign(v) + sigma2 v); the static
    model gives the same away from v_reg. At |v| = vs / 2 the Stribeck curve is Fc + (Fs - Fc) exp(-1/4)."""
    fc, fs, vs, b = 0.01, 0.02, 0.05, 1e-3
    v = direction * vs / 2
    expected = -direction * (fc + (fs - fc) * math.exp(-0.25)) - b * v
    lugre = JointFrictionParameters(
        model="lugre",
        coulomb_pos=fc,
        coulomb_neg=fc,
        static_pos=fs,
        static_neg=fs,
        stribeck_velocity=vs,
        viscous=b,
        sigma0=10.0,
        sigma1=0.01,
    )
    static = JointFrictionParameters(
        model="static",
        coulomb_pos=fc,
        coulomb_neg=fc,
        static_pos=fs,
        static_neg=fs,
        stribeck_velocity=vs,
        viscous=b,
        regularization_velocity=1e-4,
    )
    torque, _ = run_friction_alone(
        FrictionParameters(arm=lugre, pendulum=static), theta_dot=v, phi_dot=v, duration=1.0
    )  # LuGre time constant g / (sigma0 |v|) < 0.07 s
    np.testing.assert_allclose(torque, [expected, expected], rtol=1e-6)


def test_without_friction_energy_is_conserved_over_ten_seconds():
    """Pendulum released horizontal (theta = pi/2) with the arm turning: no friction, no input, so the plant's
    kinetic plus potential energy is constant; drift below 1e-6 of m g l over 10 s."""
    furuta = Furuta(FrictionParameters())
    rows = furuta.simulate(
        np.linspace(0.5, 10.0, 20), theta=math.pi / 2, phi_dot=1.0, accuracy=1e-10, integrator="runge_kutta5"
    )
    assert np.ptp(rows[:, 1]) > 1.0  # it does swing
    drift = np.abs(rows[:, 4] - rows[0, 4]) / ENERGY_SCALE
    assert drift.max() < 1e-6


FRICTION_MODELS = {
    "static": JointFrictionParameters(
        model="static", coulomb_pos=0.004, coulomb_neg=0.006, static_pos=0.008, static_neg=0.008, viscous=1e-4
    ),
    "dahl": JointFrictionParameters.dahl(0.012, 0.018, sigma0=10.0, viscous=1e-4),
    # Passive with the storage sigma0 z^2 / 2 while |v| <= 4 g (sigma1 + sigma2) / sigma1^2: 38 rad/s on the arm,
    # 19 rad/s on the pendulum (half the levels); the swing stays below 10 rad/s.
    "lugre": JointFrictionParameters(
        model="lugre",
        coulomb_pos=0.004,
        coulomb_neg=0.006,
        static_pos=0.008,
        static_neg=0.008,
        viscous=1e-4,
        sigma0=10.0,
        sigma1=5e-4,
    ),
}


@pytest.mark.parametrize("model", sorted(FRICTION_MODELS))
def test_friction_never_adds_energy(model):
    """Friction on both joints (the pendulum at half the arm's levels), pendulum swinging from theta = pi/2:
    the plant energy plus the bristle energy sigma0 z^2 / 2 (none for the static model) never rises between
    2 ms samples over 1.5 s, and friction removes a clear share of it."""
    arm = FRICTION_MODELS[model]
    pendulum = dataclasses.replace(
        arm, coulomb_pos=arm.coulomb_pos / 2, coulomb_neg=arm.coulomb_neg / 2, static_pos=None, static_neg=None
    )
    furuta = Furuta(FrictionParameters(arm=arm, pendulum=pendulum))
    rows = furuta.simulate(np.arange(1, 751) * 2e-3, theta=math.pi / 2, phi_dot=1.0, accuracy=1e-7)
    bristle_energy = 0.5 * arm.sigma0 * np.sum(rows[:, 5:] ** 2, axis=1)  # pendulum and arm share sigma0
    stored = rows[:, 4] + bristle_energy
    assert np.all(np.diff(stored) <= 1e-9 * ENERGY_SCALE)
    assert stored[-1] < stored[0] - 0.1 * ENERGY_SCALE


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("coulomb_pos", -0.01, "friction.arm.coulomb_pos"),
        ("coulomb_neg", float("nan"), "friction.arm.coulomb_neg"),
        ("viscous", -1e-3, "friction.arm.viscous"),
        ("sigma0", 0.0, "friction.arm.sigma0 must be > 0"),
        ("sigma0", -10.0, "friction.arm.sigma0 must be > 0"),
        ("sigma1", -1.0, "friction.arm.sigma1"),
        ("static_pos", 0.005, "friction.arm.static_pos must be >= the Coulomb level"),
        ("stribeck_velocity", 0.0, "friction.arm.stribeck_velocity"),
        ("regularization_velocity", -1e-3, "friction.arm.regularization_velocity"),
        ("model", "coulomb", "friction.arm.model"),
    ],
)
def test_validate_names_the_non_physical_field(field, value, message):
    arm = JointFrictionParameters(**{"model": "lugre", "coulomb_pos": 0.012, "coulomb_neg": 0.018, field: value})
    with pytest.raises(ConfigError, match=message.replace(".", r"\.")):
        FrictionParameters(arm=arm).validate()
    with pytest.raises(ConfigError, match=message.replace(".", r"\.")):
        JointFriction(make_furuta_plant("lund"), FrictionParameters(arm=arm))


def test_dahl_needs_positive_coulomb_levels_but_static_friction_may_be_purely_viscous():
    with pytest.raises(ConfigError, match=r"friction\.pendulum\.coulomb_neg must be > 0 for the dahl model"):
        FrictionParameters(pendulum=JointFrictionParameters.dahl(0.01, 0.0, sigma0=10.0)).validate()
    FrictionParameters(
        arm=JointFrictionParameters(model="static", viscous=1e-3),
        pendulum=JointFrictionParameters(model="static", sigma0=-1.0),
    ).validate()


def linearize_upright(friction: FrictionParameters):
    """A and the arm-torque B of plant + JointFriction at the upright at rest, plant states in paper order
    first (the friction's bristle states after them, unpermuted)."""
    furuta = Furuta(friction, law=JointFriction)
    context = furuta.diagram.CreateDefaultContext()
    furuta.diagram.get_input_port(0).FixValue(context, [0.0])
    linear = Linearize(furuta.diagram, context)
    P = plant_to_paper_permutation(furuta.plant)
    n = linear.A().shape[0]
    T = np.eye(n)
    T[:4, :4] = P
    return T @ linear.A() @ T.T, T @ linear.B()


@pytest.mark.parametrize("coulomb", [0.0, 0.002])
def test_linearize_through_static_friction_adds_damping_on_the_velocity_columns(coulomb):
    """Regularised static friction F = -(Fc tanh(v / v_reg) + b v) has slope -(b + Fc / v_reg) at v = 0, so
    A_damped = A - B_F diag(c_theta, c_phi) on the velocity columns (paper Eq. 2-3 with tau = [F_theta, F_phi])."""
    b_theta, b_phi, v_reg = 2e-4, 3e-3, 0.5
    friction = FrictionParameters(
        arm=JointFrictionParameters.coulomb(coulomb, b_phi, regularization_velocity=v_reg),
        pendulum=JointFrictionParameters.coulomb(coulomb / 2, b_theta, regularization_velocity=v_reg),
    )
    A, B = linearize_upright(friction)
    A0, B_F = linearized_upright(RIG)
    damping = np.diag([b_theta + coulomb / 2 / v_reg, b_phi + coulomb / v_reg])
    expected = A0.copy()
    expected[:, 2:] -= B_F @ damping
    np.testing.assert_allclose(A, expected, rtol=1e-3, atol=1e-9)
    np.testing.assert_allclose(B[:, 0], B_F[:, 1], rtol=1e-3)


@pytest.mark.parametrize("model", ["dahl", "lugre"])
def test_linearize_through_bristle_friction_sees_the_presliding_spring(model):
    """At rest with z = 0 the bristle law linearises to dz/dt = v and F = -(sigma0 z + (sigma1 + sigma2) v): a
    spring of stiffness sigma0 and a damper sigma1 + sigma2 (zero sigma1 for Dahl) on the arm, acting through
    the arm-torque column of B_F."""
    sigma0, sigma1, sigma2 = 10.0, 2e-3, 1e-4
    arm = JointFrictionParameters(
        model=model, coulomb_pos=0.012, coulomb_neg=0.018, sigma0=sigma0, sigma1=sigma1, viscous=sigma2
    )
    A, _ = linearize_upright(FrictionParameters(arm=arm))
    A0, B_F = linearized_upright(RIG)
    expected = np.zeros((5, 5))
    expected[:4, :4] = A0
    expected[:4, 3] -= (sigma1 * (model == "lugre") + sigma2) * B_F[:, 1]
    expected[:4, 4] = -sigma0 * B_F[:, 1]
    expected[4, 3] = 1.0
    np.testing.assert_allclose(A, expected, rtol=1e-3, atol=1e-9)


levels = st.floats(0.0, 0.1)
velocities = st.floats(-100.0, 100.0, allow_nan=False)


@settings(max_examples=25, deadline=None)
@given(
    coulomb_pos=levels,
    coulomb_neg=levels,
    stribeck_extra=st.tuples(levels, levels),
    stribeck_velocity=st.floats(1e-3, 1.0),
    viscous=levels,
    regularization_velocity=st.floats(1e-5, 0.1),
    v=velocities,
    v_array=st.lists(velocities, min_size=1, max_size=8),
)
def test_static_friction_never_injects_energy(
    coulomb_pos, coulomb_neg, stribeck_extra, stribeck_velocity, viscous, regularization_velocity, v, v_array
):
    p = JointFrictionParameters(
        model="static",
        coulomb_pos=coulomb_pos,
        coulomb_neg=coulomb_neg,
        static_pos=coulomb_pos + stribeck_extra[0],
        static_neg=coulomb_neg + stribeck_extra[1],
        stribeck_velocity=stribeck_velocity,
        viscous=viscous,
        regularization_velocity=regularization_velocity,
    )
    p.validate()
    assert static_friction_torque(v, p) * v <= 0.0
    v_array = np.array(v_array)
    assert np.all(static_friction_torque(v_array, p) * v_array <= 0.0)
    bound = max(p.static_levels) + viscous * np.abs(v_array)
    assert np.all(np.abs(static_friction_torque(v_array, p)) <= bound + 1e-15)
    # The array path (used by the diagnosis surrogate) agrees with the scalar path (used by the Drake system).
    np.testing.assert_allclose(
        static_friction_torque(v_array, p),
        [static_friction_torque(float(u), p) for u in v_array],
        rtol=1e-12,
        atol=1e-300,
    )
    lugre = dataclasses.replace(
        p,
        model="lugre",
        coulomb_pos=coulomb_pos + 1e-3,
        coulomb_neg=coulomb_neg + 2e-3,
        static_pos=None,
        static_neg=None,
        sigma1=1e-3,
    )
    z = 0.5 * v_array * 1e-3
    np.testing.assert_allclose(
        bristle_derivative(z, v_array, lugre),
        [bristle_derivative(zi, float(u), lugre) for zi, u in zip(z, v_array)],
        rtol=1e-12,
    )


@settings(max_examples=25, deadline=None)
@given(
    z0=st.floats(-1.0, 1.0),
    v=velocities,
    dt=st.tuples(st.floats(0.0, 1.0), st.floats(0.0, 1.0)),
    sigma0=st.floats(0.1, 1e4),
    coulomb_level=st.floats(1e-4, 1.0),
)
def test_dahl_exact_step_is_bounded_and_is_a_flow(z0, v, dt, sigma0, coulomb_level):
    """|z| never exceeds max(|z0|, Fc / sigma0) at any step size, and two steps equal one step over their sum
    (an exact solution composes)."""
    z1 = dahl_exact_step(z0, v, dt[0], sigma0, coulomb_level)
    assert abs(z1) <= max(abs(z0), coulomb_level / sigma0) * (1 + 1e-12)
    z2 = dahl_exact_step(z1, v, dt[1], sigma0, coulomb_level)
    assert z2 == pytest.approx(dahl_exact_step(z0, v, dt[0] + dt[1], sigma0, coulomb_level), rel=1e-9, abs=1e-15)


positive_levels = st.floats(1e-4, 0.1)
normal_velocities = st.floats(-100.0, 100.0, allow_subnormal=False)  # subnormal products lose their digits


def bristle_dissipation(z, v, p: JointFrictionParameters) -> float:
    """Power the friction torque puts into the joint plus the rate of the bristle energy sigma0 z^2 / 2 [W]:
    F v + sigma0 z dz/dt. Passivity of the bristle element is this being <= 0."""
    return bristle_friction_torque(z, v, p) * v + p.sigma0 * z * bristle_derivative(z, v, p)


@settings(max_examples=25, deadline=None)
@given(
    coulomb_pos=positive_levels,
    coulomb_neg=positive_levels,
    sigma0=st.floats(0.1, 1e4),
    viscous=levels,
    z=st.floats(-1.0, 1.0, allow_subnormal=False),
    v=normal_velocities,
)
def test_dahl_friction_never_injects_energy_at_any_bristle_state(coulomb_pos, coulomb_neg, sigma0, viscous, z, v):
    """Dahl (Eq. 7): F v + sigma0 z dz/dt = -b v^2 - sigma0^2 |v| z^2 / Fc <= 0 for every z and v."""
    p = JointFrictionParameters.dahl(coulomb_pos, coulomb_neg, sigma0=sigma0, viscous=viscous)
    p.validate()
    level = coulomb_pos if v > 0 else coulomb_neg
    dissipation = bristle_dissipation(z, v, p)
    rounding = 1e-12 * sigma0 * abs(z * v) + 1e-300  # F v and sigma0 z dz/dt cancel their sigma0 z v terms
    assert dissipation <= rounding
    assert dissipation == pytest.approx(-viscous * v**2 - sigma0**2 * abs(v) * z**2 / level, rel=1e-9, abs=rounding)


@settings(max_examples=25, deadline=None)
@given(
    coulomb=st.tuples(positive_levels, positive_levels),
    stribeck_extra=st.tuples(levels, levels),
    stribeck_velocity=st.floats(1e-3, 1.0),
    sigma0=st.floats(0.1, 1e4),
    sigma1=st.floats(1e-6, 1e-1),
    viscous=levels,
    speed=st.floats(1e-3, 100.0),
    direction=st.sampled_from([1.0, -1.0]),
    z_share=st.floats(-1, 1),
)
def test_lugre_friction_never_injects_energy_within_its_velocity_bound(
    coulomb, stribeck_extra, stribeck_velocity, sigma0, sigma1, viscous, speed, direction, z_share
):
    """LuGre: F v + sigma0 z dz/dt = -(sigma1 + sigma2) v^2 + sigma1 sigma0 |v| v z / g - sigma0^2 |v| z^2 / g, a
    concave quadratic in z whose maximum sigma1^2 |v|^3 / (4 g) - (sigma1 + sigma2) v^2 is <= 0 exactly when
    |v| <= 4 g(v) (sigma1 + sigma2) / sigma1^2 (the bound friction.py states). Checked at the maximising z (an
    energy-injecting bristle state exists beyond the bound) and at a random z (none within it)."""
    p = JointFrictionParameters(
        model="lugre",
        coulomb_pos=coulomb[0],
        coulomb_neg=coulomb[1],
        static_pos=coulomb[0] + stribeck_extra[0],
        static_neg=coulomb[1] + stribeck_extra[1],
        stribeck_velocity=stribeck_velocity,
        sigma0=sigma0,
        sigma1=sigma1,
        viscous=viscous,
    )
    p.validate()
    v = direction * speed
    g = float(stribeck_curve(v, p))
    bound = 4 * g * (sigma1 + viscous) / sigma1**2
    assume(abs(speed / bound - 1) > 1e-6)
    z_worst = sigma1 * v / (2 * sigma0)  # argmax over z of the dissipation
    worst = bristle_dissipation(z_worst, v, p)
    if speed < bound:
        assert worst <= 1e-12 * (sigma1 + viscous) * v**2
        z = z_share * 2 * g / sigma0
        assert bristle_dissipation(z, v, p) <= 1e-12 * ((sigma1 + viscous) * v**2 + sigma0 * abs(z * v))
    else:
        assert worst > 0.0


@pytest.mark.parametrize("law", [JointFrictionSystem, JointFriction])
@pytest.mark.parametrize("presliding", [1e-4, 3e-5])
def test_a_stiff_bristle_reversing_under_a_coarse_first_step_stays_in_its_range(presliding, law):
    """A Dahl arm whose presliding displacement Fc / sigma0 is a tenth of a milliradian, moving at 2 rad/s with
    its bristle at the opposite bound: the bristle rate sigma0 |v| / Fc is 2e4 1/s, so an explicit integrator's
    first trial step of 1 ms is 20 time constants long. The error-controlled integrator of the replays must reject
    it and go on (the law is evaluated on the bristle's physical range |z| <= Fc / sigma0), and the bristle then
    saturates at +Fc / sigma0: the exerted torque is -Fc."""
    from pydrake.systems.analysis import ApplySimulatorConfig

    from furuta_drake.diagnosis.gap.replay import REPLAY_INTEGRATOR

    builder = DiagramBuilder()
    plant, _ = add_furuta_plant(builder, "qube_servo2", with_scene_graph=False)
    level = 1.5e-3
    friction = builder.AddSystem(
        law(plant, FrictionParameters(arm=JointFrictionParameters.dahl(level, level, sigma0=level / presliding)))
    )
    builder.Connect(plant.get_state_output_port(), friction.get_input_port())
    builder.Connect(friction.GetOutputPort("generalized_force_Nm"), plant.get_applied_generalized_force_input_port())
    diagram = builder.Build()
    simulator = Simulator(diagram)
    ApplySimulatorConfig(REPLAY_INTEGRATOR, simulator)
    simulator.get_mutable_integrator().request_initial_step_size_target(1e-3)
    context = simulator.get_mutable_context()
    plant_context = plant.GetMyMutableContextFromRoot(context)
    plant.get_actuation_input_port().FixValue(plant_context, [0.0])
    arm = plant.GetJointByName("arm")
    arm.set_angular_rate(plant_context, 2.0)
    friction_context = friction.GetMyMutableContextFromRoot(context)
    friction_context.get_mutable_continuous_state_vector().SetFromVector([-presliding])
    simulator.AdvanceTo(0.005)
    z = friction_context.get_continuous_state_vector().GetAtIndex(0)
    assert abs(z) == pytest.approx(presliding, rel=1e-2)  # at its bound, to the integrator's accuracy
    assert arm.get_angular_rate(plant_context) > 1.0  # 1.5 mN m slows the 2.3e-4 kg m^2 arm by 0.03 rad/s
    torque = friction.GetOutputPort("friction_torque_Nm").Eval(friction_context)[1]
    assert torque == pytest.approx(-level, rel=1e-3)


TWO_SYSTEM_LAWS = [
    FrictionParameters(arm=JointFrictionParameters.coulomb(0.012, 1e-4)),
    FrictionParameters(
        arm=JointFrictionParameters(
            model="static", coulomb_pos=0.01, coulomb_neg=0.014, static_pos=0.02, static_neg=0.03, viscous=1e-4
        ),
        pendulum=JointFrictionParameters.coulomb(5e-4, 1e-6),
    ),
    FrictionParameters(arm=JointFrictionParameters.dahl(0.012, 0.010, 10.0, 1e-4)),
    FrictionParameters(
        arm=JointFrictionParameters(
            model="lugre", coulomb_pos=0.01, coulomb_neg=0.01, static_pos=0.02, static_neg=0.02, sigma1=0.01
        ),
        pendulum=JointFrictionParameters.dahl(1e-3, 1e-3, 5.0),
    ),
]


@pytest.mark.parametrize("params", TWO_SYSTEM_LAWS, ids=["coulomb", "asymmetric_stribeck", "dahl", "lugre_and_dahl"])
def test_the_cpp_system_gives_the_python_systems_torques_and_bristle_rates(params):
    """JointFrictionSystem (the laws as C++ expressions) and JointFriction (the same laws in Python) at random
    plant states and bristles, beyond the bristles' range too (a trial stage's): the same outputs and bristle rates
    to rounding, and the same number of states."""
    plant = make_furuta_plant("lund")
    python, cpp = JointFriction(plant, params), JointFrictionSystem(plant, params)
    contexts = python.CreateDefaultContext(), cpp.CreateDefaultContext()
    assert contexts[0].num_continuous_states() == contexts[1].num_continuous_states()
    rng = np.random.default_rng(3)
    for _ in range(100):
        x = rng.normal(size=4) * [1.0, 1.0, 0.01, 0.01]
        z = rng.normal(size=contexts[0].num_continuous_states()) * 0.003
        values = []
        for system, context in zip((python, cpp), contexts):
            system.get_input_port().FixValue(context, x)
            context.SetContinuousState(z)
            values.append(
                np.concatenate(
                    [
                        system.GetOutputPort("generalized_force_Nm").Eval(context),
                        system.GetOutputPort("friction_torque_Nm").Eval(context),
                        system.EvalTimeDerivatives(context).CopyToVector(),
                    ]
                )
            )
        np.testing.assert_allclose(values[1], values[0], rtol=1e-12, atol=1e-15)
