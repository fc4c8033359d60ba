"""The drive between a geared motor and the arm in the Drake world, against the mechanics of two inertias: an elastic
coupling rings at sqrt(k (1/J + 1/J_arm)) with the damping ratio c / (2 sqrt(k mu)) and conserves the pair's
momentum; backlash lets the rotor travel 2 b before the arm follows a reversal; the back-EMF brakes the rotor to
u / d; a rigid drive adds J_m N^2 to the arm; the arm's encoder on the motor reads the rotor; the corrected model
keeps the drive."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydrake.systems.analysis import ApplySimulatorConfig, Simulator, SimulatorConfig
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, LogVectorOutput, Sine

from furuta_drake.drive import Coupling
from furuta_drake.effects.corrected import model_config, model_rig
from furuta_drake.effects.surrogate import Model
from furuta_drake.friction import FrictionParameters, JointFrictionParameters
from furuta_drake.plant import make_furuta_plant
from furuta_drake.rig import DriveParameters, MotorParameters, geared_rig
from furuta_drake.world import add_furuta_world

# The pendulum all but removed: a microgram whose coupling m l r and gravity torque m g l vanish beside the arm's,
# with an inertia about its joint that keeps its own equation well conditioned; it stays upright and at rest.
NO_PENDULUM = dict(pendulum_mass=1e-6, pendulum_com=0.01, pendulum_inertia=1e-4, motor=None)
ARM_INERTIA = 3.2e-4  # [kg m^2] the geared rig's arm without its rotor
LOG_PERIOD = 2.5e-4  # [s]


def rig_with(drive: DriveParameters, **changes):
    return geared_rig().replace(drive=drive, **(NO_PENDULUM | changes))


def run(rig, seconds: float, command, *, state=(0.0, 0.0, 0.0, 0.0), rotor=None, friction=None):
    """(times, true states (n, 4), rotor states (n, 2)) sampled every LOG_PERIOD of ``rig``'s world from ``state``
    (the rotor at ``rotor`` [psi, psi_dot], else untwisted) under the torque-equivalent ``command`` (a number [N m]
    or a Drake source system), integrated by RK5 at accuracy 1e-9."""
    builder = DiagramBuilder()
    world = add_furuta_world(builder, rig=rig, control_period=rig.sample_period, friction=friction)
    source = builder.AddSystem(ConstantVectorSource([command]) if np.isscalar(command) else command)
    builder.Connect(source.get_output_port(0), world.arm_torque_input)
    loggers = [
        LogVectorOutput(port, builder, publish_period=LOG_PERIOD)
        for port in (world.true_state, world.drive.get_output_port())
    ]
    diagram = builder.Build()
    simulator = Simulator(diagram)
    ApplySimulatorConfig(
        SimulatorConfig(integration_scheme="runge_kutta5", accuracy=1e-9, max_step_size=1e-4), simulator
    )
    context = simulator.get_mutable_context()
    world.set_state(context, np.asarray(state, dtype=float))
    if rotor is not None:
        world.drive.GetMyMutableContextFromRoot(context).get_mutable_continuous_state_vector().SetFromVector(rotor)
    simulator.AdvanceTo(seconds)
    arm, rotor_log = (logger.FindLog(context) for logger in loggers)
    return arm.sample_times(), arm.data().T, rotor_log.data().T


def crossings(t: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Times [s] at which ``y`` crosses zero upwards (linear interpolation)."""
    i = np.flatnonzero((y[:-1] < 0) & (y[1:] >= 0))
    return t[i] - y[i] * (t[i + 1] - t[i]) / (y[i + 1] - y[i])


def test_an_elastic_drive_rings_at_the_two_mass_frequency_and_conserves_momentum():
    k = 2.0  # [N m/rad]
    rig = rig_with(DriveParameters(gear_ratio=30.0, rotor_inertia=1e-6, stiffness=k))
    J, Ja = 1e-6 * 30.0**2, ARM_INERTIA + 1e-6 * geared_rig().arm_length ** 2
    t, arm, rotor = run(rig, 0.3, 0.0, rotor=[0.01, 0.0])
    twist = rotor[:, 0] - arm[:, 1]
    period = np.diff(crossings(t, twist)).mean()
    assert 2 * math.pi / period == pytest.approx(math.sqrt(k * (1 / J + 1 / Ja)), rel=1e-4)
    # No torque from outside: J psi_dot + J_a phi_dot stays 0, so the arm swings J / J_a times the rotor's amplitude.
    assert np.abs(J * rotor[:, 1] + Ja * arm[:, 3]).max() < 1e-6 * J * np.abs(rotor[:, 1]).max()
    assert np.ptp(arm[:, 1]) == pytest.approx(J / Ja * np.ptp(rotor[:, 0]), rel=1e-3)
    assert np.abs(arm[:, 0]).max() < 1e-6  # the vestigial pendulum stays put


def test_an_elastic_drives_damping_ratio_is_c_over_twice_sqrt_k_mu():
    k, zeta = 2.0, 0.05
    J, Ja = 9e-4, ARM_INERTIA + 1e-6 * geared_rig().arm_length ** 2
    mu = J * Ja / (J + Ja)
    c = 2 * zeta * math.sqrt(k * mu)
    rig = rig_with(DriveParameters(gear_ratio=30.0, rotor_inertia=1e-6, stiffness=k, damping=c))
    t, arm, rotor = run(rig, 0.5, 0.0, rotor=[0.01, 0.0])  # 7 periods
    twist = rotor[:, 0] - arm[:, 1]
    peaks = np.flatnonzero((twist[1:-1] > twist[:-2]) & (twist[1:-1] >= twist[2:])) + 1
    decrement = np.log(twist[peaks[0]] / twist[peaks[4]]) / 4  # per period: 2 pi zeta / sqrt(1 - zeta^2)
    assert decrement / math.sqrt(4 * math.pi**2 + decrement**2) == pytest.approx(zeta, rel=2e-3)


def test_backlash_lets_the_rotor_travel_twice_its_half_width_before_the_arm_follows_a_reversal():
    """A heavy rotor swung back and forth drives a light arm whose viscous friction stops it within a millisecond
    once the teeth part: at each reversal the arm waits where the rotor left it, b behind the rotor's turning point,
    until the rotor has come back 2 b."""
    b = 0.02  # [rad]
    rig = rig_with(DriveParameters(gear_ratio=30.0, rotor_inertia=1e-5, backlash=b))
    friction = FrictionParameters(arm=JointFrictionParameters(model="static", viscous=ARM_INERTIA / 1e-3))
    t, arm, rotor = run(rig, 0.7, Sine(0.3, 2 * math.pi, 0.0, 1), friction=friction)
    psi, phi = rotor[:, 0], arm[:, 1]
    turns = np.flatnonzero((rotor[:-1, 1] > 0) & (rotor[1:, 1] <= 0))  # the rotor turns back from + (at 0.53 s)
    assert len(turns) == 1
    for i in turns:
        assert psi[i] - phi[i] == pytest.approx(b, rel=0.02)  # the arm a half-width behind
        follows = i + np.flatnonzero(phi[i:] < phi[i] - 1e-3 * b)[0]  # the arm moves back
        assert psi[i] - psi[follows] == pytest.approx(2 * b, rel=0.02)
        assert np.ptp(phi[i:follows]) < 2e-3 * b  # and waits while the rotor crosses the play


def test_a_tooth_only_pushes():
    law = Coupling(backlash=0.01, stiffness=100.0, damping=1.0)
    assert law.torque(0.005, 50.0) == 0.0  # in the play, whatever the rate
    assert law.torque(0.011, 0.0) == pytest.approx(0.1)  # 1 mrad into the + flank
    assert law.torque(0.011, -1.0) == 0.0  # leaving it faster than the spring pushes: no pull
    assert law.torque(-0.011, -1.0) == pytest.approx(-1.1)


def test_the_back_emf_brakes_the_rotor_and_the_arm_to_the_free_running_speed():
    """A constant torque-equivalent command u through an elastic drive: rotor and frictionless arm settle at the
    speed where the back-EMF kt ke / R of the rotor's speed takes all of u."""
    motor = MotorParameters(resistance=2.2, torque_constant=0.3, backemf_constant=0.3)
    rig = rig_with(DriveParameters(gear_ratio=30.0, rotor_inertia=1e-6, stiffness=2.0, damping=0.01), motor=motor)
    u, d = 0.05, 0.3 * 0.3 / 2.2
    _, arm, rotor = run(rig, 1.0, u)  # the mechanical time constant (J + J_a) / d is 30 ms
    assert arm[-1, 3] == pytest.approx(u / d, rel=1e-6) and rotor[-1, 1] == pytest.approx(u / d, rel=1e-6)


def test_a_rigid_drive_adds_the_rotors_reflected_inertia_to_the_arm():
    rig = geared_rig()
    plant = make_furuta_plant(rig)
    context = plant.CreateDefaultContext()
    arm = plant.GetJointByName("arm").velocity_start()
    # At theta = 0 the arm's diagonal entry is a = J_arm + J_m N^2 + m r^2 (docs/paper.md's a, with the rotor).
    expected = ARM_INERTIA + 1e-6 * 30.0**2 + rig.pendulum_mass * rig.arm_length**2
    assert plant.CalcMassMatrix(context)[arm, arm] == pytest.approx(expected, rel=1e-12)


def test_the_arm_encoder_on_the_motor_reads_the_rotor():
    rig = rig_with(DriveParameters(gear_ratio=30.0, rotor_inertia=1e-6, backlash=0.02, encoder="motor"))
    builder = DiagramBuilder()
    world = add_furuta_world(builder, rig=rig, control_period=rig.sample_period)
    builder.ExportInput(world.arm_torque_input)
    builder.ExportOutput(world.encoder_state, "encoder_state")
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    world.set_state(context, np.array([0.1, 0.4, -1.0, 2.0]))
    assert diagram.GetOutputPort("encoder_state").Eval(context) == pytest.approx([0.1, 0.4, -1.0, 2.0])
    rotor = world.drive.GetMyMutableContextFromRoot(context).get_mutable_continuous_state_vector()
    rotor.SetFromVector([0.415, 2.5])  # turned 15 mrad past the arm, within the play
    assert diagram.GetOutputPort("encoder_state").Eval(context) == pytest.approx([0.1, 0.415, -1.0, 2.5])


def test_the_corrected_model_keeps_the_drive_its_rotor_scaled_with_the_arm():
    """A fitted arm inertia 1.2 times the rig file's: the arm and the rotor it turns keep their shares of it."""
    rig = geared_rig()
    model = Model.from_rig(rig).replace(arm_inertia_total=1.2 * rig.arm_inertia_total)
    corrected = model_rig(model, rig)
    assert corrected.arm_inertia_total == pytest.approx(1.2 * rig.arm_inertia_total, rel=1e-12)
    assert corrected.drive.rotor_inertia == pytest.approx(1.2e-6, rel=1e-12)
    tip = rig.pendulum_mass * rig.arm_length**2  # the pendulum's mass at the arm's tip, kept
    assert corrected.arm_inertia == pytest.approx(1.2 * (ARM_INERTIA + tip) - tip, rel=1e-9)
    assert model_config(rig, model).rig.drive == corrected.drive
