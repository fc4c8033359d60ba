"""An independent Furuta pendulum simulator (numpy and scipy only) that records "real" logs for validating
``furuta-drake diagnose`` on data it was not written from.

Nothing of furuta_drake's physics, surrogate, friction, actuator or simulation code is used: the equations of
motion are derived here from the rigid bodies, the effects are realised in forms the package does not use
(Karnopp stick-slip, tanh or banded-sign Coulomb friction, a static Stribeck curve, an integer-sample FIFO
delay, an armature inductance or a discrete filter as the lag, two dead-zone and two saturation forms, a linear
or a cubic cable spring, cogging, a drive's gear backlash and elastic coupling), and the runs are integrated with
``scipy.integrate.solve_ivp`` between samples with the command held. furuta_drake is imported only to write the
nominal rig file (:func:`write_rig_file`) and, in ``--check``, to compare the linearisation with the package's.

Equations of motion (generalised coordinates q = [theta, phi]; theta the pendulum angle, 0 upright; phi the arm
angle about the vertical axis). The arm is a rotor of inertia J; the pendulum's joint is at distance r from the
axis, on the arm's radial unit vector e_r; the pendulum swings in the plane of the tangent e_t and the vertical z,
its centre of mass at p = r e_r + l (sin(theta) e_t + cos(theta) z), with mass m and inertia J_p about the two
transverse axes through its centre of mass (none about its own long axis, as the rig file assumes). Its angular
velocity is phi_dot z + theta_dot e_r, whose components on the body axes are theta_dot (joint axis),
phi_dot cos(theta) (long axis) and phi_dot sin(theta) (third axis). With a = J + m r^2, b = J_p + m l^2,
c = m l r and d = m g l the Lagrangian gives

    T = 1/2 [b theta_dot^2 + 2 c cos(theta) theta_dot phi_dot + (a + b sin^2 theta) phi_dot^2],  V = d cos(theta)

    [ b      c co      ] [theta_ddot]   [ d s + b s co phi_dot^2 + tau_theta                     ]
    [ c co   a + b s^2 ] [phi_ddot  ] = [ c s theta_dot^2 - 2 b s co theta_dot phi_dot + tau_phi ]

with s = sin(theta), co = cos(theta), tau_theta and tau_phi the other generalised torques (friction, drive,
spring, cogging).

A drive with backlash or elasticity adds a rotor on the arm's axis, counted on the arm side (its angle psi the
motor's over the gear ratio, its inertia J_r the rotor's times the ratio squared, taken out of the arm's J): the
actuator turns the rotor, J_r psi_ddot = tau_drive - tau_c, and the arm receives tau_c, a spring of stiffness k and
damping c on the twist psi - phi beyond the gear's play +-b (no torque within it):
tau_c = k (psi - phi - b sign(psi - phi)) + c (psi_dot - phi_dot), the damper acting while the teeth touch. A motor's
back-EMF brakes the rotor. A motor-side encoder reads psi as the arm's angle.

Sign conventions (checked in ``--check``): at the upright a positive arm torque gives theta_ddot = -c tau / det < 0;
hanging (cos(theta) = -1) it gives theta_ddot = +c tau / det > 0, so accelerating the arm towards +phi swings the
pendulum towards +theta.

Run ``PYTHONPATH=. python benchmarks/independent/simulator.py --check`` for the simulator's own checks (energy, the
linearisation against ``furuta_drake.rig.linearized_upright``, the sign conventions, balancing runs that stay up).
"""

from __future__ import annotations

import argparse
import dataclasses
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from scipy.integrate import solve_ivp
from scipy.linalg import expm, solve_discrete_are

RTOL, ATOL = 1e-7, 1e-10  # solve_ivp tolerances (angles [rad], velocities [rad/s])
MAX_SWITCHES = 50  # stick-slip mode changes allowed within one sample before the run is declared broken
BAND_NUDGE = 1e-6  # an arm entering a friction dead band starts this fraction of its half-width inside [-]
FALLEN = 0.6  # a balancing run whose |theta| exceeds this [rad] has fallen
VELOCITY_CUTOFF = 25.0  # the controller's dirty derivative [Hz]


@dataclass(frozen=True)
class Bodies:
    """The rigid bodies (SI): arm + rotor inertia about the vertical axis, arm length, pendulum mass, joint to
    centre of mass, pendulum inertia about its centre of mass (transverse), gravity."""

    arm_inertia: float  # J [kg m^2]
    arm_length: float  # r [m]
    pendulum_mass: float  # m [kg]
    pendulum_com: float  # l [m]
    pendulum_inertia: float  # J_p [kg m^2]
    gravity: float = 9.81  # [m/s^2]

    @property
    def a(self) -> float:
        """J + m r^2 [kg m^2]."""
        return self.arm_inertia + self.pendulum_mass * self.arm_length**2

    @property
    def b(self) -> float:
        """J_p + m l^2 [kg m^2]."""
        return self.pendulum_inertia + self.pendulum_mass * self.pendulum_com**2

    @property
    def c(self) -> float:
        """m l r [kg m^2]."""
        return self.pendulum_mass * self.pendulum_com * self.arm_length

    @property
    def d(self) -> float:
        """m g l [N m]."""
        return self.pendulum_mass * self.gravity * self.pendulum_com

    def scaled(self, **factors: float) -> Bodies:
        """These bodies with fields multiplied by ``factors`` (e.g. pendulum_mass=1.2)."""
        return dataclasses.replace(self, **{k: getattr(self, k) * v for k, v in factors.items()})


@dataclass(frozen=True)
class Motor:
    """Armature-controlled DC motor: L di/dt = V - R i - ke phi_dot, tau = kt i (quasi-static when L = 0)."""

    resistance: float  # R [ohm]
    torque_constant: float  # kt [N m/A]
    backemf_constant: float  # ke [V s/rad]
    inductance: float = 0.0  # L [H]

    @property
    def torque_per_volt(self) -> float:
        """kt / R [N m/V]."""
        return self.torque_constant / self.resistance


@dataclass(frozen=True)
class Rig:
    """A nominal rig: bodies, encoder, control period, command limit; ``motor``: the command is a voltage;
    ``gear_ratio`` and ``rotor_inertia``: a gearmotor whose rotor (inertia on the motor side) the bodies' arm
    inertia includes, times the ratio squared."""

    name: str
    bodies: Bodies
    counts_per_rev: int
    sample_period: float  # [s]
    torque_limit: float  # [N m]
    motor: Motor | None = None
    gear_ratio: float = 1.0  # motor turns per arm turn
    rotor_inertia: float = 0.0  # [kg m^2] motor side; 0: no drive stated

    @property
    def rotor_share(self) -> float:
        """The geared rotor's part of the arm inertia, J_m N^2 / J [-]."""
        return self.rotor_inertia * self.gear_ratio**2 / self.bodies.arm_inertia

    @property
    def command_limit(self) -> float:
        """The controller's clip in command units [N m, or V for a motor rig]."""
        return self.torque_limit if self.motor is None else self.torque_limit / self.motor.torque_per_volt

    @property
    def torque_per_command(self) -> float:
        """Torque-equivalent of one command unit [N m per N m or per V]."""
        return 1.0 if self.motor is None else self.motor.torque_per_volt


def lund_like() -> Rig:
    """The Lund pendulum (Lenain et al.; arm 1.274e-3 kg m^2 incl. rotor, r 0.25 m, pendulum 33.2 g with its
    centre of mass 0.30 m out and 9.0e-4 kg m^2 about it), 4096-count encoders at 1 kHz, 0.2 N m, torque logs."""
    bodies = Bodies(
        arm_inertia=1.274e-3, arm_length=0.25, pendulum_mass=0.033172, pendulum_com=0.30, pendulum_inertia=8.997e-4
    )
    return Rig("lund", bodies, counts_per_rev=4096, sample_period=0.001, torque_limit=0.2)


def qube_like() -> Rig:
    """A QUBE-Servo 2 from public data (arm 95 g / 85 mm spun about its centre, rotor 4e-6 kg m^2, pendulum rod
    24 g / 129 mm), 2048-count encoders at 500 Hz, a 10 V amplifier, R 8.4 ohm, kt = ke = 0.042: voltage logs."""
    arm_mass, arm_length, rotor, rod_mass, rod_length = 0.095, 0.085, 4e-6, 0.024, 0.129
    motor = Motor(resistance=8.4, torque_constant=0.042, backemf_constant=0.042)
    bodies = Bodies(
        arm_inertia=arm_mass * arm_length**2 / 12 + rotor,
        arm_length=arm_length,
        pendulum_mass=rod_mass,
        pendulum_com=rod_length / 2,
        pendulum_inertia=rod_mass * rod_length**2 / 12,
    )
    return Rig(
        "qube", bodies, counts_per_rev=2048, sample_period=0.002, torque_limit=10.0 * motor.torque_per_volt, motor=motor
    )


def geared_like() -> Rig:
    """A lab-built rig: a 12 V DC motor through a 30:1 gearbox (rotor 1e-6 kg m^2, so 9e-4 kg m^2 at the arm;
    kt = ke = 0.3 at the arm, R 2.2 ohm), an aluminium arm of 40 g and 0.15 m turned at one end (3.2e-4 kg m^2 with
    its hub), a 30 g rod pendulum 0.25 m long, 2400-count encoders, logged at 100 Hz: voltage logs."""
    motor = Motor(resistance=2.2, torque_constant=0.3, backemf_constant=0.3)
    rotor, ratio, rod_mass, rod_length = 1e-6, 30.0, 0.03, 0.25
    bodies = Bodies(
        arm_inertia=3.2e-4 + rotor * ratio**2,
        arm_length=0.15,
        pendulum_mass=rod_mass,
        pendulum_com=rod_length / 2,
        pendulum_inertia=rod_mass * rod_length**2 / 12,
    )
    return Rig(
        "geared",
        bodies,
        counts_per_rev=2400,
        sample_period=0.01,
        torque_limit=12.0 * motor.torque_per_volt,
        motor=motor,
        gear_ratio=ratio,
        rotor_inertia=rotor,
    )


RIGS = {"lund": lund_like, "qube": qube_like, "geared": geared_like}


@dataclass(frozen=True)
class ArmFriction:
    """The arm's dry friction [N m]. ``form``:

    - ``karnopp``: stick-slip; stuck (phi_dot = 0) while the torque needed to hold the arm stays within
      ``breakaway``, sliding against the Coulomb level otherwise (events resolve the switches exactly: the
      limit of Karnopp's zero-velocity band);
    - ``sign_band``: -F sign(v) outside a dead band |v| <= ``smoothing`` [rad/s], 0 inside. At the band's edge,
      where the sign law chatters, the arm creeps at +-``smoothing`` while the applied torques push it out with
      less than F (the law's Filippov solution; events switch between sliding, creeping and the band);
    - ``tanh``: -F tanh(v / ``smoothing``) (``smoothing`` in rad/s);
    - ``stribeck``: -(F + (``static`` - F) exp(-(v / ``stribeck_velocity``)^2)) tanh(v / ``smoothing``).

    F is ``coulomb_pos`` for v > 0 and ``coulomb_neg`` for v < 0."""

    form: str
    coulomb_pos: float  # [N m]
    coulomb_neg: float  # [N m]
    smoothing: float = 0.0  # [rad/s]
    breakaway: float = 0.0  # [N m]
    static: float = 0.0  # [N m]
    stribeck_velocity: float = 0.0  # [rad/s]

    @property
    def hybrid(self) -> bool:
        """Whether the law is integrated as modes switched by events (karnopp, sign_band)."""
        return self.form in ("karnopp", "sign_band")

    @property
    def hold_velocity(self) -> float:
        """Arm speed [rad/s] at which a hybrid law holds the arm: 0 (stuck) or the band's edge (creep)."""
        return self.smoothing if self.form == "sign_band" else 0.0

    def level(self, direction: float) -> float:
        """The Coulomb level [N m] for motion in ``direction`` (+1 or -1)."""
        return self.coulomb_pos if direction > 0 else self.coulomb_neg

    def torque(self, v: float) -> float:
        """Friction torque on the arm [N m] at arm velocity ``v`` [rad/s] (smooth forms only)."""
        level = self.level(v)
        if self.form == "tanh":
            return -level * math.tanh(v / self.smoothing)
        if self.form == "stribeck":
            curve = level + (self.static - level) * math.exp(-((v / self.stribeck_velocity) ** 2))
            return -curve * math.tanh(v / self.smoothing)
        raise ValueError(f"no smooth torque for form {self.form!r}")


@dataclass(frozen=True)
class Backlash:
    """A gear between the rotor and the arm with a free play of +-``half_gap`` [rad]: the rotor (``rotor_share``
    of the arm inertia) drives the arm only in contact, through a stiff damped tooth contact (or, beside a
    :class:`Belt`, through the belt)."""

    half_gap: float  # [rad]
    rotor_share: float  # rotor inertia / (arm + rotor) inertia [-]
    contact_frequency: float = 150.0  # rotor natural frequency on the tooth contact [Hz]
    contact_damping: float = 0.3  # damping ratio of the contact [-]


@dataclass(frozen=True)
class Belt:
    """An elastic coupling (a belt, a long shaft) between the rotor (``rotor_share`` of the arm inertia) and the
    arm: a spring of ``stiffness`` [N m/rad] and a damper of ``damping`` [N m s/rad] on their twist."""

    stiffness: float  # [N m/rad]
    damping: float  # [N m s/rad]
    rotor_share: float  # rotor inertia / (arm + rotor) inertia [-]


@dataclass(frozen=True)
class World:
    """The true rig: its bodies and every effect the nominal rig file leaves out (defaults: none).

    Command chain, each sample: logged command -> FIFO of ``delay_samples`` (plus, with ``delay_jitter_samples``, a
    seeded uniform 0..J samples more each sample: a USB link, a scheduler) -> discrete first-order filter of time
    constant ``filter_time_constant`` -> ``gain`` -> dead zone -> saturation -> (motor) -> continuous lag of
    ``lag_time_constant`` (torque rig: a back-EMF-compensated armature, L/R) -> arm. Dead zone and saturation are
    in command units (N m, or V on a motor rig)."""

    rig: Rig
    bodies: Bodies | None = None  # the true bodies (None: the rig's)
    motor_inductance: float = 0.0  # [H] (motor rig only)
    arm_friction: ArmFriction | None = None
    arm_viscous: float = 0.0  # [N m s/rad]
    pendulum_coulomb: float = 0.0  # [N m], smoothed by tanh(v / pendulum_smoothing)
    pendulum_viscous: float = 0.0  # [N m s/rad]
    pendulum_smoothing: float = 0.02  # [rad/s]
    counts_per_rev: int | None = None  # the true encoder (None: the rig's)
    noise_std: float = 0.0  # Gaussian noise on both angles [rad]
    noise_correlation_time: float = 0.0  # [s] the noise is first-order low-pass (AR(1)) with this time; 0: white
    delay_samples: int = 0
    delay_jitter_samples: int = 0  # each sample's delay is delay_samples plus a uniform 0..this many samples more
    filter_time_constant: float = 0.0  # [s]
    lag_time_constant: float = 0.0  # [s]
    gain: float = 1.0
    deadzone: float = 0.0  # width [command units]
    deadzone_form: str = "subtract"  # "subtract": u - sat_w(u); "threshold": u if |u| > w else 0
    saturation: float = 0.0  # limit [command units], 0: none
    saturation_form: str = "hard"  # "hard": clip; "tanh": limit tanh(u / limit)
    spring_linear: float = 0.0  # k1 [N m/rad]
    spring_cubic: float = 0.0  # k3 [N m/rad^3]
    spring_offset: float = 0.0  # equilibrium [rad]
    cogging_amplitude: float = 0.0  # [N m]
    cogging_periods: int = 0  # per revolution
    backlash: Backlash | None = None
    belt: Belt | None = None
    encoder_on_rotor: bool = False  # the arm's encoder is the motor's: it reads the rotor (needs a backlash or belt)
    encoder_offset: tuple[float, float] = (0.0, 0.0)  # [theta, phi] read minus true angle [rad]: zeroed off
    drag: float = 0.0  # quadratic arm drag: -drag |phi_dot| phi_dot [N m s^2/rad^2]
    tilt_torque: float = 0.0  # a tilted base's gravity on the arm: -tilt_torque sin(phi - tilt_direction) [N m]
    tilt_direction: float = 0.0  # [rad]
    friction_ripple: float = 0.0  # an arm Coulomb level varying with the angle: -ripple sin(phi) tanh(v/0.01) [N m]
    disturbance_rms: float = 0.0  # [N m] an ongoing arm torque: white noise low-passed at disturbance_corner, held
    # over each sample (AR(1), stationary from the start), seeded by the run
    disturbance_corner: float = 3.0  # [Hz]

    @property
    def true_bodies(self) -> Bodies:
        return self.bodies or self.rig.bodies

    @property
    def motor(self) -> Motor | None:
        if self.rig.motor is None:
            return None
        return dataclasses.replace(self.rig.motor, inductance=self.motor_inductance)

    @property
    def encoder_counts(self) -> int:
        return self.counts_per_rev or self.rig.counts_per_rev

    @property
    def actuator_state(self) -> bool:
        """Whether the actuator has a state: the armature current (motor rig with an inductance) or the lagged
        torque (torque rig with a continuous lag)."""
        if self.rig.motor is None:
            if self.motor_inductance > 0:
                raise ValueError("an armature inductance needs a motor rig (a torque rig takes lag_time_constant)")
            return self.lag_time_constant > 0
        if self.lag_time_constant > 0:
            raise ValueError("a motor rig's lag is its armature inductance (motor_inductance)")
        return self.motor_inductance > 0

    @property
    def extra_states(self) -> int:
        """Number of states beyond [theta, phi, theta_dot, phi_dot]: actuator torque or current, rotor angle and
        velocity."""
        return int(self.actuator_state) + 2 * self.rotor

    @property
    def rotor(self) -> bool:
        """Whether the drive's rotor is a body of its own (backlash or a belt)."""
        return self.backlash is not None or self.belt is not None

    @property
    def stiff(self) -> bool:
        """Whether the ODE needs an implicit-capable method (sharp smooth friction, the tooth contact, a belt)."""
        sharp = self.arm_friction is not None and not self.arm_friction.hybrid
        return sharp or self.rotor or self.pendulum_coulomb > 0


# --- command chain --------------------------------------------------------------------------------------------


@dataclass
class CommandChain:
    """The discrete part of the command chain, with its memory (the FIFO and the filter's last output)."""

    world: World
    fifo: list[float] = field(default_factory=list)
    filtered: float = 0.0
    jitter: np.random.Generator | None = None  # the jittering delay's own stream (the run's draws stay as they are)

    def __post_init__(self):
        self.fifo = [0.0] * (self.world.delay_samples + self.world.delay_jitter_samples)

    def applied(self, command: float) -> float:
        """The command that reaches the motor or arm this sample [command units]."""
        w = self.world
        self.fifo.append(command)
        if w.delay_jitter_samples:
            extra = int(self.jitter.integers(0, w.delay_jitter_samples + 1))
            u = self.fifo[-1 - w.delay_samples - extra]
            self.fifo.pop(0)
        else:
            u = self.fifo.pop(0)
        if w.filter_time_constant > 0:  # backward-Euler 1 / (T s + 1)
            alpha = w.rig.sample_period / (w.filter_time_constant + w.rig.sample_period)
            self.filtered += alpha * (u - self.filtered)
            u = self.filtered
        u *= w.gain
        u = deadzone(u, w.deadzone, w.deadzone_form)
        return saturate(u, w.saturation, w.saturation_form)


def deadzone(u: float, width: float, form: str) -> float:
    """Dead zone of ``width`` [command units]: ``subtract`` takes it off larger commands, ``threshold`` drops the
    commands within it and passes the others whole."""
    if width <= 0:
        return u
    if form == "threshold":
        return u if abs(u) > width else 0.0
    return math.copysign(max(abs(u) - width, 0.0), u)


def saturate(u: float, limit: float, form: str) -> float:
    """``hard``: clip to +-limit; ``tanh``: limit tanh(u / limit) (slope 1 at 0). ``limit`` 0: none."""
    if limit <= 0:
        return u
    if form == "tanh":
        return limit * math.tanh(u / limit)
    return min(max(u, -limit), limit)


# --- dynamics -------------------------------------------------------------------------------------------------


def accelerations(
    bodies: Bodies, theta: float, theta_dot: float, phi_dot: float, tau_theta: float, tau_phi: float
) -> tuple[float, float]:
    """(theta_ddot, phi_ddot) [rad/s^2] of the equations in the module docstring, for generalised torques on the
    pendulum and arm joints [N m]."""
    s, co = math.sin(theta), math.cos(theta)
    a, b, c, d = bodies.a, bodies.b, bodies.c, bodies.d
    m12, m22 = c * co, a + b * s * s
    r1 = d * s + b * s * co * phi_dot**2 + tau_theta
    r2 = c * s * theta_dot**2 - 2.0 * b * s * co * theta_dot * phi_dot + tau_phi
    det = b * m22 - m12 * m12
    return (m22 * r1 - m12 * r2) / det, (b * r2 - m12 * r1) / det


def holding_torque(
    bodies: Bodies, theta: float, theta_dot: float, phi_dot: float, tau_theta: float, tau_phi: float
) -> tuple[float, float]:
    """(friction torque [N m] that keeps the arm's velocity ``phi_dot`` constant, theta_ddot [rad/s^2]
    meanwhile) for the other arm torques ``tau_phi`` [N m]: with phi_ddot = 0 the pendulum row gives
    theta_ddot, the arm row the torque."""
    s, co = math.sin(theta), math.cos(theta)
    theta_ddot = (bodies.d * s + bodies.b * s * co * phi_dot**2 + tau_theta) / bodies.b
    r2 = bodies.c * s * theta_dot**2 - 2.0 * bodies.b * s * co * theta_dot * phi_dot + tau_phi
    return bodies.c * co * theta_ddot - r2, theta_ddot


def energy(bodies: Bodies, x: np.ndarray) -> float:
    """Kinetic plus potential energy [J] of the state [theta, phi, theta_dot, phi_dot] (0 potential at the
    joint's height)."""
    theta, _, theta_dot, phi_dot = x[:4]
    s, co = math.sin(theta), math.cos(theta)
    kinetic = 0.5 * (
        bodies.b * theta_dot**2 + 2 * bodies.c * co * theta_dot * phi_dot + (bodies.a + bodies.b * s * s) * phi_dot**2
    )
    return kinetic + bodies.d * co


class Plant:
    """The continuous part: bodies, friction, spring, cogging, motor, continuous lag, backlash, as one ODE over
    x = [theta, phi, theta_dot, phi_dot, (actuator state), (rotor angle, rotor velocity)]."""

    def __init__(self, world: World):
        self.world = world
        self.disturbance = 0.0  # [N m] the ongoing arm torque over the current sample
        self.bodies = world.true_bodies
        self.motor = world.motor
        self.actuator = 4 if world.actuator_state else None
        self.rotor = 4 + world.actuator_state if world.rotor else None
        if world.encoder_on_rotor and not world.rotor:
            raise ValueError("a motor-side encoder reads a rotor of its own: give the world a backlash or a belt")
        if world.rotor:
            bl, belt = world.backlash, world.belt
            share = belt.rotor_share if belt is not None else bl.rotor_share
            if bl is not None and belt is not None and bl.rotor_share != belt.rotor_share:
                raise ValueError("the backlash and the belt turn one rotor: give them the same rotor_share")
            self.rotor_inertia = share * world.true_bodies.arm_inertia
            self.bodies = dataclasses.replace(self.bodies, arm_inertia=self.bodies.arm_inertia - self.rotor_inertia)
            self.gap = 0.0 if bl is None else bl.half_gap
            if belt is not None:
                self.contact_stiffness, self.contact_damping = belt.stiffness, belt.damping
            else:
                omega = 2 * math.pi * bl.contact_frequency
                self.contact_stiffness = self.rotor_inertia * omega**2
                self.contact_damping = 2 * bl.contact_damping * self.rotor_inertia * omega

    def initial(self, theta: float, phi: float = 0.0) -> np.ndarray:
        x = np.zeros(4 + self.world.extra_states)
        x[0], x[1] = theta, phi
        if self.rotor is not None:
            x[self.rotor] = phi
        return x

    def drive_torque(self, x, u: float) -> float:
        """Torque [N m] the actuator puts on the rotor (or the arm) for the applied command ``u`` [command units]."""
        motor, speed = self.motor, x[self.rotor + 1] if self.rotor is not None else x[3]
        if self.actuator is None:
            return u if motor is None else motor.torque_per_volt * (u - motor.backemf_constant * speed)
        if motor is None:
            return x[self.actuator]  # the lagged torque
        return motor.torque_constant * x[self.actuator]  # kt i

    def actuator_rate(self, x, u: float) -> float:
        """d/dt of the actuator state: the torque lag (u - tau) / T, or the armature di/dt [A/s]."""
        if self.motor is None:
            return (u - x[self.actuator]) / self.world.lag_time_constant
        speed = x[self.rotor + 1] if self.rotor is not None else x[3]
        m = self.motor
        return (u - m.resistance * x[self.actuator] - m.backemf_constant * speed) / m.inductance

    def contact_torque(self, x) -> float:
        """Torque [N m] the rotor puts on the arm through the gear's play and the belt."""
        gap = self.gap
        twist = x[self.rotor] - x[1]
        if gap > 0 and abs(twist) <= gap:
            return 0.0
        return self.contact_stiffness * (twist - math.copysign(gap, twist)) + self.contact_damping * (
            x[self.rotor + 1] - x[3]
        )

    def sensed(self, x) -> np.ndarray:
        """The angles the encoders read [rad]: [theta, phi], or [theta, psi] with the arm's encoder on the motor."""
        return np.array([x[0], x[self.rotor] if self.world.encoder_on_rotor else x[1]])

    def pendulum_torque(self, theta_dot: float) -> float:
        w = self.world
        smooth = w.pendulum_coulomb * math.tanh(theta_dot / w.pendulum_smoothing) if w.pendulum_coulomb else 0.0
        return -smooth - w.pendulum_viscous * theta_dot

    def arm_torque(self, x, u: float) -> float:
        """Every arm torque [N m] but a hybrid friction law's: drive (or contact), viscous, smooth friction,
        spring, cogging."""
        w, phi, phi_dot = self.world, x[1], x[3]
        tau = self.contact_torque(x) if self.rotor is not None else self.drive_torque(x, u)
        tau -= w.arm_viscous * phi_dot
        if w.arm_friction is not None and not w.arm_friction.hybrid:
            tau += w.arm_friction.torque(phi_dot)
        stretch = phi - w.spring_offset
        tau -= w.spring_linear * stretch + w.spring_cubic * stretch**3
        if w.cogging_amplitude:
            tau -= w.cogging_amplitude * math.sin(w.cogging_periods * phi)
        tau -= w.drag * abs(phi_dot) * phi_dot + w.tilt_torque * math.sin(phi - w.tilt_direction)
        tau -= w.friction_ripple * math.sin(phi) * math.tanh(phi_dot / 0.01)
        return tau + self.disturbance

    def rhs(self, x, u: float, coulomb: float = 0.0, held: bool = False) -> list[float]:
        """dx/dt for the applied command ``u``; ``coulomb``: a hybrid law's sliding torque on the arm [N m];
        ``held``: the hybrid law holds the arm's velocity (phi_ddot = 0)."""
        tau_theta, tau_phi = self.pendulum_torque(x[2]), self.arm_torque(x, u)
        if held:
            theta_ddot, phi_ddot = holding_torque(self.bodies, x[0], x[2], x[3], tau_theta, tau_phi)[1], 0.0
        else:
            theta_ddot, phi_ddot = accelerations(self.bodies, x[0], x[2], x[3], tau_theta, tau_phi + coulomb)
        out = [x[2], x[3], theta_ddot, phi_ddot]
        if self.actuator is not None:
            out.append(self.actuator_rate(x, u))
        if self.rotor is not None:
            out += [x[self.rotor + 1], (self.drive_torque(x, u) - self.contact_torque(x)) / self.rotor_inertia]
        return out

    def holding(self, x, u: float) -> float:
        """The friction torque [N m] that would keep the arm's velocity constant in state ``x``."""
        return holding_torque(self.bodies, x[0], x[2], x[3], self.pendulum_torque(x[2]), self.arm_torque(x, u))[0]


class Integrator:
    """Advances the plant over one sample with the applied command held, through ``solve_ivp``.

    A hybrid friction law (:class:`ArmFriction`) is a mode kept across samples: ``("slide", s)`` (moving in
    direction s against the Coulomb level), ``("hold", s)`` (arm velocity held at s times the hold velocity: stuck
    for Karnopp, creeping at the band's edge for sign_band) or ``("band", 0)`` (inside the dead band, no
    friction); terminal events end a mode and :meth:`_at_edge` picks the next."""

    def __init__(self, plant: Plant):
        self.plant = plant
        self.method = "LSODA" if plant.world.stiff else "RK45"
        friction = plant.world.arm_friction
        self.dry = friction if friction is not None and friction.hybrid else None
        self.mode = ("hold", 0) if self.dry is not None and self.dry.hold_velocity == 0 else ("band", 0)

    def step(self, x: np.ndarray, u: float, h: float) -> np.ndarray:
        """The state after ``h`` [s] from ``x`` under the applied command ``u``."""
        if self.dry is None:
            sol = solve_ivp(lambda t, y: self.plant.rhs(y, u), (0.0, h), x, method=self.method, rtol=RTOL, atol=ATOL)
            return sol.y[:, -1]
        return self._hybrid_step(x, u, h)

    def _hybrid_step(self, x: np.ndarray, u: float, h: float) -> np.ndarray:
        t = 0.0
        if self.mode[0] == "hold":
            self.mode = self._hold_exit(x, u) or self.mode
        for _ in range(MAX_SWITCHES):
            if self.mode[0] == "hold":
                x = x.copy()
                x[3] = self.mode[1] * self.dry.hold_velocity
            events = self._events(u)
            sol = solve_ivp(self._rhs(u), (t, h), x, method="RK45", rtol=RTOL, atol=ATOL, events=events)
            x, t = sol.y[:, -1], sol.t[-1]
            if sol.status == 0:
                return x
            fired = next(i for i, times in enumerate(sol.t_events) if times.size)
            self.mode = self._next_mode(x, u, fired)
            if self.mode[0] == "band":  # start strictly inside, so a tangency at the edge cannot refire at once
                inside = (1.0 - BAND_NUDGE) * self.dry.hold_velocity
                x = x.copy()
                x[3] = min(max(x[3], -inside), inside)
        raise RuntimeError(f"more than {MAX_SWITCHES} friction mode switches in one sample")

    def _rhs(self, u: float):
        kind, s = self.mode
        if kind == "hold":
            return lambda t, y: self.plant.rhs(y, u, held=True)
        coulomb = -s * self.dry.level(s) if kind == "slide" else 0.0
        return lambda t, y: self.plant.rhs(y, u, coulomb=coulomb)

    def _events(self, u: float) -> list:
        """Terminal events of the current mode (each crossing zero downwards ends it)."""
        kind, s = self.mode
        edge = self.dry.hold_velocity
        if kind == "slide":
            events = [lambda t, y: s * y[3] - edge]  # slows down to the edge
        elif kind == "band":
            events = [lambda t, y: edge - y[3], lambda t, y: y[3] + edge]  # leaves the band up or down
        elif s == 0:  # stuck (Karnopp): the holding torque reaches the breakaway level
            events = [lambda t, y: self.dry.breakaway - abs(self.plant.holding(y, u))]
        else:  # creeping: the holding torque reaches the Coulomb level, or stops opposing the creep
            events = [
                lambda t, y: self.dry.level(s) - abs(self.plant.holding(y, u)),
                lambda t, y: -s * self.plant.holding(y, u),
            ]
        for event in events:
            event.terminal, event.direction = True, -1
        return events

    def _next_mode(self, x, u: float, fired: int) -> tuple[str, int]:
        kind, s = self.mode
        if kind == "slide":
            return self._at_edge(x, s, u)
        if kind == "band":
            return self._at_edge(x, 1 if fired == 0 else -1, u)
        if s == 0:
            return ("slide", -int(math.copysign(1, self.plant.holding(x, u))))
        return ("slide", s) if fired == 0 else ("band", 0)

    def _at_edge(self, x, s: int, u: float) -> tuple[str, int]:
        """The mode of an arm arriving at the hold velocity from direction ``s`` (sliding down to it, or leaving
        the band through it)."""
        edge = x.copy()
        edge[3] = s * self.dry.hold_velocity
        holding = self.plant.holding(edge, u)
        if self.dry.hold_velocity == 0:
            if abs(holding) <= self.dry.breakaway:
                return ("hold", 0)
            return ("slide", -int(math.copysign(1, holding)))
        if holding * s >= 0:  # the other torques pull the arm back into the band
            return ("band", 0)
        return ("hold", s) if abs(holding) <= self.dry.level(s) else ("slide", s)

    def _hold_exit(self, x, u: float) -> tuple[str, int] | None:
        """At a sample's start (a new command): the mode a held arm leaves for, or None if it stays held."""
        s = self.mode[1]
        holding = self.plant.holding(x, u)
        if s == 0:
            return ("slide", -int(math.copysign(1, holding))) if abs(holding) > self.dry.breakaway else None
        if holding * s >= 0:
            return ("band", 0)
        return ("slide", s) if abs(holding) > self.dry.level(s) else None


# --- sensors, controller, excitation --------------------------------------------------------------------------


def encoder(
    x: np.ndarray, counts_per_rev: int, noise_std: float, rng: np.random.Generator, noise: np.ndarray | None = None
) -> np.ndarray:
    """Measured [theta, phi] [rad]: rounded to whole counts of 2 pi / counts_per_rev, plus Gaussian noise (``noise``:
    this sample's correlated noise instead of a white draw)."""
    count = 2 * math.pi / counts_per_rev
    measured = np.round(x[:2] / count) * count
    if noise is not None:
        return measured + noise
    if noise_std > 0:
        measured = measured + rng.normal(0.0, noise_std, 2)
    return measured


@dataclass
class CorrelatedNoise:
    """Noise of std ``std`` [rad] on both angles, first-order low-pass with ``time`` [s] (an interface that filters
    before it logs): n_k = a n_(k-1) + sqrt(1 - a^2) std e_k, a = exp(-period / time), from its stationary law."""

    std: float
    time: float
    period: float
    rng: np.random.Generator
    state: np.ndarray | None = None

    def next(self) -> np.ndarray:
        a = math.exp(-self.period / self.time)
        if self.state is None:
            self.state = self.rng.normal(0.0, self.std, 2)
        else:
            self.state = a * self.state + math.sqrt(1.0 - a * a) * self.rng.normal(0.0, self.std, 2)
        return self.state


class ArmDisturbance:
    """The world's ongoing arm torque, one value per sample: d_k = a d_(k-1) + sqrt(1 - a^2) rms e_k,
    a = exp(-2 pi corner period), from its stationary law (zero without one)."""

    def __init__(self, world: World, period: float, rng: np.random.Generator):
        self.rms, self.rng = world.disturbance_rms, rng
        self.a = math.exp(-2 * math.pi * world.disturbance_corner * period)
        self.value = rng.normal(0.0, self.rms) if self.rms > 0 else 0.0

    def next(self) -> float:
        if self.rms > 0:
            self.value = self.a * self.value + math.sqrt(1.0 - self.a**2) * self.rms * self.rng.normal()
        return self.value


def linearization(rig: Rig) -> tuple[np.ndarray, np.ndarray]:
    """(A, B) of the nominal rig at the upright, x = [theta, phi, theta_dot, phi_dot], input the command
    (torque, or voltage through the quasi-static motor with its back-EMF damping)."""
    bd = rig.bodies
    M = np.array([[bd.b, bd.c], [bd.c, bd.a]])
    Minv = np.linalg.inv(M)
    A = np.zeros((4, 4))
    A[0, 2] = A[1, 3] = 1.0
    A[2:, 0] = Minv[:, 0] * bd.d
    B = np.zeros((4, 1))
    B[2:, 0] = Minv[:, 1] * rig.torque_per_command
    if rig.motor is not None:
        m = rig.motor
        A[2:, 3] -= Minv[:, 1] * m.torque_per_volt * m.backemf_constant
    return A, B


def discrete_lqr(rig: Rig) -> np.ndarray:
    """State feedback K (1x4, command units per state unit) of a discrete LQR on the zero-order-hold
    discretisation of :func:`linearization`. Bryson weights, deliberately gentle so that the loop tolerates the
    suite's delays, lags and sensor effects with the controller's filtered-difference velocities: 0.1 rad,
    0.3 rad, 5 rad/s, 10 rad/s and a tenth of the command limit."""
    A, B = linearization(rig)
    h = rig.sample_period
    block = np.zeros((5, 5))
    block[:4, :4], block[:4, 4:] = A, B
    phi = expm(block * h)
    Ad, Bd = phi[:4, :4], phi[:4, 4:]
    Q = np.diag(1.0 / np.array([0.1, 0.3, 5.0, 10.0]) ** 2)
    R = np.array([[1.0 / (0.1 * rig.command_limit) ** 2]])
    P = solve_discrete_are(Ad, Bd, Q, R)
    return np.linalg.solve(R + Bd.T @ P @ Bd, Bd.T @ P @ Ad)


@dataclass
class VelocityFilter:
    """Dirty derivative s / (tau s + 1) of the measured angles (backward Euler), ``cutoff`` [Hz]."""

    period: float  # [s]
    cutoff: float  # [Hz]
    last: np.ndarray | None = None
    rate: np.ndarray = field(default_factory=lambda: np.zeros(2))

    def update(self, measured: np.ndarray) -> np.ndarray:
        """[theta_dot, phi_dot] estimates [rad/s]."""
        if self.last is not None:
            tau = 1.0 / (2 * math.pi * self.cutoff)
            self.rate = (tau * self.rate + (measured - self.last)) / (tau + self.period)
        self.last = measured
        return self.rate


def multisine(
    rms: float, f_min: float, f_max: float, times: np.ndarray, rng: np.random.Generator, components: int = 14
) -> np.ndarray:
    """Sum of ``components`` sines on a log-spaced grid [f_min, f_max] [Hz], seeded random phases, at ``rms``."""
    freqs = np.geomspace(f_min, f_max, components)
    phases = rng.uniform(0, 2 * math.pi, components)
    return rms * math.sqrt(2.0 / components) * np.sin(2 * math.pi * np.outer(times, freqs) + phases).sum(axis=1)


def fade_in(times: np.ndarray, seconds: float) -> np.ndarray:
    """Raised-cosine envelope from 0 to 1 over the first ``seconds`` [s] (so an open-loop multisine does not start
    the arm with a constant drift velocity)."""
    ramp = np.clip(times / seconds, 0.0, 1.0) if seconds > 0 else np.ones_like(times)
    return 0.5 - 0.5 * np.cos(np.pi * ramp)


def square_reference(times: np.ndarray, amplitude: float, period: float) -> np.ndarray:
    """Arm reference [rad]: +amplitude for the first half period, then alternating."""
    return amplitude * np.where(np.floor(times / (period / 2)) % 2 == 0, 1.0, -1.0)


# --- runs -----------------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class RunSpec:
    """One run: ``balance`` (discrete LQR with a multisine and an arm square-wave reference), ``hanging``
    (open-loop multisine; excitation RMS as a fraction of m g l, torque-equivalent), ``step`` and ``square`` (open
    loop from rest hanging: the command steps to ``level`` times the command limit at STEP_AT, or switches between
    +-``level`` times it every half ``square_period``, the identification runs a lab records with a gearmotor), or
    a designed experiment (:func:`play`): ``played`` (a given open-loop command from rest hanging) or
    ``played_balance`` (a given dither added to a given state feedback, from rest upright)."""

    kind: str
    duration: float = 8.0  # [s]
    seed: int = 0
    excitation_rms: float = 0.08  # [m g l]
    f_min: float = 0.3  # [Hz]
    f_max: float = 6.0  # [Hz]
    reference_amplitude: float = 0.25  # [rad]
    reference_period: float = 2.5  # [s]
    fade_in: float = 0.0  # [s]
    start: float | None = None  # [rad] the pendulum's initial angle (None: the kind's)
    level: float = 0.3  # [command limit] of a step or square run
    square_period: float = 1.0  # [s]


STEP_AT = 0.5  # [s] a step run's command steps here


def balance_run(duration: float, seed: int) -> RunSpec:
    return RunSpec("balance", duration, seed, excitation_rms=0.08, f_max=6.0)


def hanging_run(duration: float, seed: int) -> RunSpec:
    return RunSpec("hanging", duration, seed, excitation_rms=0.25, f_max=5.0, fade_in=2.0)


def step_command(run: RunSpec, times: np.ndarray, limit: float) -> np.ndarray:
    """The command of a ``step`` or ``square`` run at ``times`` [s], ``limit`` the command limit."""
    if run.kind == "step":
        return np.where(times >= STEP_AT, run.level * limit, 0.0)
    return run.level * limit * square_reference(times, 1.0, run.square_period)


@dataclass
class RunLog:
    """A recorded run: sample times [s], measured angles [rad], logged command (N m or V), true states."""

    time: np.ndarray
    measured: np.ndarray  # (n, 2) [theta, phi]
    command: np.ndarray  # (n,)
    state: np.ndarray  # (n, 4) true [theta, phi, theta_dot, phi_dot]
    command_name: str  # "torque" | "voltage"

    @property
    def fell(self) -> bool:
        return bool(np.max(np.abs(self.state[:, 0])) > FALLEN)


def play(world: World, command: np.ndarray, seed: int, gain: np.ndarray | None = None) -> RunLog:
    """Record a designed experiment on the true rig ``world``: the open-loop ``command`` (command units, one value
    per sample) played from rest hanging, or with ``gain`` (1x4, command units per state unit) the dither added
    to u = -gain [theta, phi, theta_dot, phi_dot] balancing from rest upright (velocities: the controller's
    dirty derivative)."""
    run = RunSpec("played" if gain is None else "played_balance", len(command) * world.rig.sample_period, seed)
    return simulate(world, run, np.asarray(command, dtype=float), gain)


@dataclass
class Compensation:
    """Friction compensation of a balancing controller: a Dahl model of the arm friction driven by the controller's
    arm velocity estimate v, z' = v - sigma0 |v| z / Fc(v) (Fc = ``coulomb_pos`` for v > 0, ``coulomb_neg`` else),
    stepped exactly for each sample's v; the friction torque it estimates is -sigma0 z [N m], and the command adds
    ``gain`` sigma0 z (torque-equivalent) to cancel that share of it."""

    coulomb_pos: float  # [N m]
    coulomb_neg: float  # [N m]
    sigma0: float  # [N m/rad]
    gain: float  # [-]
    z: float = 0.0  # [rad]

    def torque(self, v: float, period: float) -> float:
        """The compensating torque [N m] over the coming sample, after stepping z over it at velocity ``v``."""
        level = self.coulomb_pos if v > 0 else self.coulomb_neg
        steady = math.copysign(level / self.sigma0, v) if v != 0 else self.z
        self.z = steady + (self.z - steady) * math.exp(-self.sigma0 * abs(v) * period / level)
        return self.gain * self.sigma0 * self.z


@dataclass
class StateFeedback:
    """A lab's balancing controller: u = -``gain`` [theta, phi, theta_dot, phi_dot] (command units per state unit)
    on the encoder's angles and their dirty derivative, plus the ``compensation``'s torque (over
    ``torque_per_command``)."""

    gain: np.ndarray
    period: float  # [s]
    torque_per_command: float = 1.0
    compensation: Compensation | None = None
    velocity: VelocityFilter | None = None

    def __call__(self, measured: np.ndarray) -> float:
        if self.velocity is None:
            self.velocity = VelocityFilter(self.period, cutoff=VELOCITY_CUTOFF)
        rates = self.velocity.update(measured)
        u = -float((np.reshape(self.gain, (1, 4)) @ np.concatenate([measured, rates]))[0])
        if self.compensation is not None:
            u += self.compensation.torque(rates[1], self.period) / self.torque_per_command
        return u


def regulate(world: World, controller, duration: float, seed: int, start: float) -> RunLog:
    """Balance the true rig ``world`` from rest at the pendulum angle ``start`` [rad] for ``duration`` [s] under
    ``controller`` (a callable: the measured [theta, phi] [rad] of a sample -> the command of that sample, command
    units; e.g. :class:`StateFeedback`), with nothing else acting."""
    run = RunSpec("played_balance", duration, seed, start=start)
    return simulate(world, run, np.zeros(round(duration / world.rig.sample_period)), controller=controller)


def simulate(
    world: World,
    run: RunSpec,
    command: np.ndarray | None = None,
    played_gain: np.ndarray | None = None,
    controller=None,
) -> RunLog:
    """Record ``run`` on the true rig ``world``; the controller knows only the nominal rig. ``command``: the
    excitation of a played run, ``played_gain`` the state feedback of a ``played_balance`` one, or ``controller``
    its controller (:func:`regulate`)."""
    rig = world.rig
    h = rig.sample_period
    rng = np.random.default_rng([run.seed, 7])
    times = np.arange(round(run.duration / h)) * h
    scale = rig.bodies.d / rig.torque_per_command  # m g l in command units
    if run.kind.startswith("played"):
        excitation = command
    elif run.kind in ("step", "square"):
        excitation = step_command(run, times, rig.command_limit)
    else:
        excitation = multisine(run.excitation_rms * scale, run.f_min, run.f_max, times, rng)
        excitation = excitation * fade_in(times, run.fade_in)
    plant, chain = Plant(world), CommandChain(world, jitter=np.random.default_rng([run.seed, 11]))
    correlated = (
        CorrelatedNoise(world.noise_std, world.noise_correlation_time, h, np.random.default_rng([run.seed, 13]))
        if world.noise_std > 0 and world.noise_correlation_time > 0
        else None
    )
    integrator = Integrator(plant)
    disturbance = ArmDisturbance(world, h, np.random.default_rng([run.seed, 17]))
    balance = run.kind in ("balance", "played_balance")
    starts = {"balance": 0.03, "hanging": math.pi + 0.1, "played_balance": 0.0}
    x = plant.initial(starts.get(run.kind, math.pi) if run.start is None else run.start)
    gain = discrete_lqr(rig) if run.kind == "balance" else played_gain
    reference = square_reference(times, run.reference_amplitude, run.reference_period)
    if run.kind == "played_balance":
        reference = np.zeros_like(times)
    velocity = VelocityFilter(h, cutoff=VELOCITY_CUTOFF)
    measured, commands, states = np.zeros((times.size, 2)), np.zeros(times.size), np.zeros((times.size, 4))
    for k in range(times.size):
        y = encoder(
            plant.sensed(x) + np.array(world.encoder_offset),
            world.encoder_counts,
            world.noise_std,
            rng,
            correlated.next() if correlated else None,
        )
        rates = velocity.update(y)
        u = excitation[k]
        if controller is not None:
            u += controller(y)
        elif balance:
            error = np.array([y[0], y[1] - reference[k], rates[0], rates[1]])
            u -= float((gain @ error)[0])
        u = min(max(u, -rig.command_limit), rig.command_limit)
        measured[k], commands[k], states[k] = y, u, x[:4]
        plant.disturbance = disturbance.next()
        x = integrator.step(x, chain.applied(u), h)
    return RunLog(times, measured, commands, states, "torque" if rig.motor is None else "voltage")


def window_divergence(rig: Rig, log: RunLog, window: float = 0.1) -> float:
    """Size of an effect's dynamic signature in ``log`` [encoder counts of the rig]: the RMS over consecutive
    ``window`` [s] windows of the true angles minus the NOMINAL rig's prediction started from the true state at
    each window's start and driven by the logged commands (0 for a sensor-only effect)."""
    plant = Plant(World(rig))
    integrator, h = Integrator(plant), rig.sample_period
    steps = max(1, round(window / h))
    errors = []
    for start in range(0, log.time.size - steps, steps):
        x = log.state[start].copy()
        for k in range(start, start + steps):
            errors.append(log.state[k, :2] - x[:2])
            x = integrator.step(x, log.command[k], h)
    return float(np.sqrt(np.mean(np.square(errors))) / (2 * math.pi / rig.counts_per_rev))


def sensor_error(rig: Rig, log: RunLog) -> float:
    """RMS of measured minus true angles [encoder counts of the rig] (0.29 for a perfect rounding encoder)."""
    return float(np.sqrt(np.mean(np.square(log.measured - log.state[:, :2]))) / (2 * math.pi / rig.counts_per_rev))


def write_log(log: RunLog, path: Path) -> None:
    """The diagnosis log format: ``time,theta,phi,torque`` (or ``voltage``), 9 significant digits."""
    table = np.column_stack([log.time, log.measured, log.command])
    np.savetxt(path, table, delimiter=",", header=f"time,theta,phi,{log.command_name}", comments="", fmt="%.9g")


def write_rig_file(rig: Rig, path: Path, encoder: str = "arm") -> None:
    """The NOMINAL rig file (no effect) in furuta_drake's rig YAML; a geared rig's drive section says where the
    arm's ``encoder`` sits (arm or motor)."""
    from furuta_drake.rig import DriveParameters, MotorParameters, RigParameters
    from furuta_drake.yamlio import dump_yaml_dataclass

    bd = rig.bodies
    drive = (
        None
        if rig.rotor_inertia == 0
        else DriveParameters(gear_ratio=rig.gear_ratio, rotor_inertia=rig.rotor_inertia, encoder=encoder)
    )
    motor = (
        None
        if rig.motor is None
        else MotorParameters(
            resistance=rig.motor.resistance,
            torque_constant=rig.motor.torque_constant,
            backemf_constant=rig.motor.backemf_constant,
        )
    )
    params = RigParameters(
        arm_inertia=float(f"{bd.arm_inertia - rig.rotor_inertia * rig.gear_ratio**2:.12g}"),  # the rotor stated apart
        arm_length=bd.arm_length,
        pendulum_mass=bd.pendulum_mass,
        pendulum_com=bd.pendulum_com,
        pendulum_inertia=bd.pendulum_inertia,
        gravity=bd.gravity,
        counts_per_rev=rig.counts_per_rev,
        sample_period=rig.sample_period,
        torque_limit=rig.torque_limit,
        theta_direction=1,
        motor=motor,
        drive=drive,
    )
    path.write_text(dump_yaml_dataclass(params))


# --- self-checks ----------------------------------------------------------------------------------------------


def check_energy(rig: Rig, seconds: float = 5.0) -> float:
    """Energy drift [m g l] of a free swing (no friction, no motor, no input) from a large angle over
    ``seconds``."""
    plant = Plant(World(dataclasses.replace(rig, motor=None)))
    x0 = np.array([2.0, 0.0, 1.0, 3.0])
    sol = solve_ivp(lambda t, y: plant.rhs(y, 0.0), (0, seconds), x0, method="DOP853", rtol=1e-11, atol=1e-12)
    e = [energy(rig.bodies, sol.y[:, i]) for i in range(sol.t.size)]
    return (max(e) - min(e)) / (abs(rig.bodies.d) + 1e-12)


def check_linearization(rig: Rig) -> float:
    """Largest difference between a finite-difference Jacobian of the nonlinear ODE at the upright and
    ``furuta_drake.rig.linearized_upright`` (arm-torque column), relative to the largest entry."""
    from furuta_drake.rig import RigParameters, linearized_upright

    bd = rig.bodies
    theirs_A, theirs_B = linearized_upright(
        RigParameters(
            arm_inertia=bd.arm_inertia,
            arm_length=bd.arm_length,
            pendulum_mass=bd.pendulum_mass,
            pendulum_com=bd.pendulum_com,
            pendulum_inertia=bd.pendulum_inertia,
            gravity=bd.gravity,
        )
    )
    plant, eps = Plant(World(dataclasses.replace(rig, motor=None))), 1e-6
    ours = np.zeros((4, 5))
    for j in range(5):
        x, u = np.zeros(4), 0.0
        if j < 4:
            x[j] = eps
        else:
            u = eps
        plus = np.array(plant.rhs(x, u))
        x, u = -x, -u
        ours[:, j] = (plus - np.array(plant.rhs(x, u))) / (2 * eps)
    theirs = np.column_stack([theirs_A, theirs_B[:, 1]])
    return float(np.max(np.abs(ours - theirs)) / np.max(np.abs(theirs)))


def check_signs(rig: Rig) -> tuple[float, float]:
    """theta_ddot [rad/s^2] for a positive arm torque at rest, upright and hanging (must be < 0 and > 0)."""
    bd, tau = rig.bodies, 0.1 * rig.torque_limit
    return accelerations(bd, 0.0, 0.0, 0.0, 0.0, tau)[0], accelerations(bd, math.pi, 0.0, 0.0, 0.0, tau)[0]


def check_stick_slip(rig: Rig, form: str) -> tuple[float, float]:
    """Arm travel [rad] in 0.5 s from rest, hanging, under a constant torque of 0.9 and 1.1 times the breakaway
    level of a hybrid friction law (Karnopp, breakaway 1.25 x Coulomb; or sign_band, breakaway = Coulomb): the
    first must stay (nearly: sign_band creeps at its band's edge), the second move."""
    level = 0.05 * rig.bodies.d
    friction = ArmFriction(form, level, level, smoothing=0.002 if form == "sign_band" else 0.0, breakaway=1.25 * level)
    limit = friction.breakaway if form == "karnopp" else level
    travel = []
    for factor in (0.9, 1.1):
        world = World(dataclasses.replace(rig, motor=None), arm_friction=friction)
        integrator, x = Integrator(Plant(world)), Plant(world).initial(math.pi)
        for _ in range(round(0.5 / rig.sample_period)):
            x = integrator.step(x, factor * limit, rig.sample_period)
        travel.append(abs(x[1]))
    return travel[0], travel[1]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="run the simulator's own checks and print them")
    parser.add_argument("--duration", type=float, default=8.0, help="balancing run length for the check [s]")
    args = parser.parse_args(argv)
    if not args.check:
        parser.print_help()
        return 0
    for name, make in RIGS.items():
        rig = make()
        upright, hanging = check_signs(rig)
        print(
            f"{name}: energy drift {check_energy(rig):.2e} of m g l; linearisation vs furuta_drake "
            f"{check_linearization(rig):.2e}; theta_ddot for +tau upright {upright:+.2f}, hanging {hanging:+.2f}"
        )
        for form in ("karnopp", "sign_band"):
            held, moved = check_stick_slip(rig, form)
            print(f"  {form}: arm travel in 0.5 s at 0.9 x breakaway {held:.2e} rad, at 1.1 x {moved:.2e} rad")
        for run in (balance_run(args.duration, 1), hanging_run(args.duration, 2)):
            start = time.perf_counter()
            log = simulate(World(rig), run)
            centre = 0.0 if run.kind == "balance" else math.pi
            print(
                f"  {run.kind}: |theta - {centre:.2f}| max {np.max(np.abs(log.state[:, 0] - centre)):.3f} rad, "
                f"|phi| max {np.max(np.abs(log.state[:, 1])):.2f} rad, "
                f"command RMS {np.sqrt(np.mean(log.command**2)):.4f}"
                f"{', fell ' + str(log.fell) if run.kind == 'balance' else ''}, {time.perf_counter() - start:.1f} s"
            )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
