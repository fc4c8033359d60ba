"""The configuration tree of a simulation: one dataclass per block of the paper's diagram, YAML in and out.

Two kinds of blocks meet here. ``rig`` is the *nominal* model: the LQR and the observers are designed on it
(paper Eq. 1-2 come from its linearization) and the MultibodyPlant is built from it. ``friction``,
``actuator``, ``disturbance``, ``unmodelled_torque`` and ``encoder`` describe what the simulated world adds to
that model: friction on the joints, actuator imperfections, a cable spring or cogging, torques beyond the effect
vocabulary (expressions of the state, :mod:`furuta_drake.unmodelled`), and the encoder that measures the angles.
A fitted diagnosis writes exactly these sections, so ``furuta-drake simulate --config fitted_model.yaml``
runs the corrected model.

One clock drives every sampled block: the control period, ``rig.sample_period``. The encoder, the LQR and the
observers are given it when the diagram is built; their sections may state it (``encoder.sample_period``,
``controller.lqr.period``, ``observers.hg.period``, ...), and a stated period that differs is an error.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Literal

from furuta_drake.actuator import ActuatorParameters, DisturbanceParameters
from furuta_drake.controllers.lqr import LqrParameters
from furuta_drake.controllers.quanser_swingup import QuanserSwingUpParameters
from furuta_drake.controllers.swingup import SwingUpParameters
from furuta_drake.encoder import EncoderParameters
from furuta_drake.errors import ConfigError, require_control_period
from furuta_drake.friction import FrictionParameters, JointFrictionParameters
from furuta_drake.observers.dahl import DahlObserverParameters
from furuta_drake.observers.filtered_derivative import FilteredDerivativeParameters
from furuta_drake.observers.hg import HighGainParameters
from furuta_drake.observers.vfe import VfeParameters
from furuta_drake.rig import RIGS, RigParameters
from furuta_drake.unmodelled import UnmodelledTorqueParameters
from furuta_drake.yamlio import dump_yaml_dataclass, load_yaml_dataclass

VelocitySource = Literal["true", "derivative", "hg", "vfe", "kinematic_hg", "filtered_derivative"]


@dataclass
class ControllerConfig:
    """Sec. IV-A: LQR state feedback u = -K (x_hat - x_ref), optionally minus the friction estimate (Sec. IV-C).

    ``mode = "swingup"`` pumps the pendulum's energy up from hanging and hands over to the same LQR near the top
    (:mod:`furuta_drake.controllers.swingup`, parameters in ``swingup``); ``mode = "quanser_swingup"`` is Quanser's
    voltage swing-up and PD balance of the QUBE (:mod:`furuta_drake.controllers.quanser_swingup`, parameters in
    ``quanser_swingup``; the rig needs a ``motor``: the voltage reaches the arm as kt V / R); ``mode =
    "open_loop"`` applies only the excitation torque (hanging identification runs). ``velocity_source`` picks the
    state estimate the controller uses: the encoder angles with the true velocities (reference diagram (iv)), a
    discrete derivative of the encoder angles, the HG observer (Eq. 4, diagram (i)), the VFE observer with the Dahl
    friction observer (Eq. 8-13, diagrams (ii)-(iii)), (swing-up only) the high-gain observer on the kinematic
    model, or the filtered derivative of the encoder angles that Quanser's server computes
    (:mod:`furuta_drake.observers.filtered_derivative`, parameters in ``observers.filtered_derivative``).
    ``friction_compensation`` subtracts F_hat of the Dahl observer on the velocity source's arm velocity; the
    kinematic model has no friction, so with ``kinematic_hg`` F_hat is the VFE's Dahl observer's (``vfe`` must be
    in ``observers.run``). ``gain`` overrides the LQR design (checked to stabilise the nominal linearization).
    """

    mode: Literal["lqr", "swingup", "quanser_swingup", "open_loop"] = "lqr"
    velocity_source: VelocitySource = "true"
    friction_compensation: bool = False
    lqr: LqrParameters = field(default_factory=LqrParameters)
    gain: list[float] | None = None
    swingup: SwingUpParameters = field(default_factory=SwingUpParameters)
    quanser_swingup: QuanserSwingUpParameters = field(default_factory=QuanserSwingUpParameters)

    def validate(self, where: str = "controller") -> None:
        self.lqr.validate(f"{where}.lqr")
        self.swingup.validate(f"{where}.swingup")
        self.quanser_swingup.validate(f"{where}.quanser_swingup")
        if self.gain is not None:
            if len(self.gain) != 4 or not all(math.isfinite(g) for g in self.gain):
                raise ConfigError(
                    f"{where}.gain must be 4 finite numbers [theta, phi, theta_dot, phi_dot], got {self.gain!r}"
                )
        if self.friction_compensation and self.velocity_source not in ("hg", "vfe", "kinematic_hg"):
            raise ConfigError(
                f"{where}.friction_compensation needs the Dahl observer, which reads an observer's "
                f"arm velocity: set {where}.velocity_source to 'hg' or 'vfe'"
            )
        if self.velocity_source == "kinematic_hg" and self.mode != "swingup":
            raise ConfigError(
                f"{where}.velocity_source 'kinematic_hg' is the swing-up's observer: set {where}.mode "
                f"to 'swingup' or choose 'true', 'derivative', 'hg' or 'vfe'"
            )
        if self.mode == "quanser_swingup" and self.friction_compensation:
            raise ConfigError(
                f"{where}.friction_compensation: the quanser_swingup controller compensates no "
                f"friction; set it to false"
            )


@dataclass
class ObserverConfig:
    """The observers of Sec. III; the arm's Dahl observer adapts (Sec. V, VII) as its ``dahl.adaptation``
    section says. ``run`` lists observers that run side by side on the same measurements for comparison (the
    paper's Table II experiment); the one the controller uses always runs."""

    hg: HighGainParameters = field(default_factory=HighGainParameters)
    dahl: DahlObserverParameters = field(default_factory=DahlObserverParameters)
    vfe: VfeParameters = field(default_factory=VfeParameters)
    run: list[Literal["hg", "vfe"]] = field(default_factory=list)
    pendulum_friction: DahlObserverParameters | None = None  # a friction observer on the pendulum, feeding VFE
    filtered_derivative: FilteredDerivativeParameters = field(default_factory=FilteredDerivativeParameters)
    start_at_initial_state: bool = False  # the linear observers start at initial_state (else at x_hat = 0)
    # The rig file whose upright linearization (Eq. 1-2) the HG and VFE observers carry; None: ``rig``'s. A
    # controller designed on another rig file than the simulated one (a lab's rig file beside the corrected model).
    model: RigParameters | None = None

    def validate(self, where: str = "observers") -> None:
        if self.model is not None:
            self.model.validate(f"{where}.model")
        self.hg.validate(f"{where}.hg")
        self.dahl.validate(f"{where}.dahl")
        if self.pendulum_friction is not None:
            self.pendulum_friction.validate(f"{where}.pendulum_friction")
            if self.pendulum_friction.adaptation is not None:
                raise ConfigError(
                    f"{where}.pendulum_friction.adaptation must be null: nothing compensates the "
                    f"pendulum's friction, so its observer does not adapt"
                )
        self.vfe.validate(f"{where}.vfe")
        self.filtered_derivative.validate(f"{where}.filtered_derivative")


@dataclass
class ExcitationConfig:
    """Seeded excitation so that the arm keeps moving (the paper does not state its own).

    ``torque_*``: a multisine torque added to the controller's command, with ``torque_components`` sines of
    random phase spread log-uniformly over [frequency_min, frequency_max] and RMS ``torque_rms``.
    ``arm_reference_*``: a square-wave reference for the arm angle phi of the given amplitude and period
    (zero amplitude: balance at phi = 0). Both are generated from the config's seed.
    ``command``: a recorded torque command [N m], one value per control period from t = 0 and zero after its
    last (e.g. a designed experiment), added like the multisine.
    """

    torque_rms: float = 0.0  # [N m]
    torque_components: int = 12
    frequency_min: float = 0.2  # [Hz]
    frequency_max: float = 8.0  # [Hz]
    arm_reference_amplitude: float = 0.0  # [rad]
    arm_reference_period: float = 4.0  # [s]
    command: list[float] | None = None  # [N m] per control period

    def validate(self, where: str = "excitation") -> None:
        for name in ("torque_rms", "arm_reference_amplitude"):
            value = getattr(self, name)
            if not math.isfinite(value) or value < 0:
                raise ConfigError(f"{where}.{name} must be a non-negative finite number, got {value!r}")
        if self.torque_components < 1:
            raise ConfigError(f"{where}.torque_components must be >= 1, got {self.torque_components}")
        if not 0 < self.frequency_min < self.frequency_max:
            raise ConfigError(
                f"{where}: need 0 < frequency_min < frequency_max, got {self.frequency_min}, {self.frequency_max}"
            )
        if self.arm_reference_period <= 0:
            raise ConfigError(f"{where}.arm_reference_period must be > 0, got {self.arm_reference_period}")
        if self.command is not None and (not self.command or not all(math.isfinite(v) for v in self.command)):
            raise ConfigError(f"{where}.command must be a non-empty list of finite torques [N m]")


@dataclass
class IntegratorConfig:
    """Drake's ``SimulatorConfig`` fields that matter here (applied with ``ApplySimulatorConfig``)."""

    integration_scheme: str = "runge_kutta3"
    max_step_size: float = 1e-3  # [s]
    accuracy: float = 1e-4
    use_error_control: bool = True

    def validate(self, where: str = "simulator") -> None:
        schemes = (
            "runge_kutta2",
            "runge_kutta3",
            "runge_kutta5",
            "implicit_euler",
            "radau1",
            "radau3",
            "bogacki_shampine3",
            "explicit_euler",
            "semi_explicit_euler",
            "velocity_implicit_euler",
        )
        if self.integration_scheme not in schemes:
            raise ConfigError(
                f"{where}.integration_scheme must be one of {list(schemes)}, got {self.integration_scheme!r}"
            )
        if not self.max_step_size > 0:
            raise ConfigError(f"{where}.max_step_size must be > 0, got {self.max_step_size}")
        if not 0 < self.accuracy < 1:
            raise ConfigError(f"{where}.accuracy must be in (0, 1), got {self.accuracy}")


@dataclass
class MonitorConfig:
    """Stops a run that left its safe envelope (see :mod:`furuta_drake.simulate`). ``theta_bound`` None: no
    angle bound (swing-up and hanging runs)."""

    theta_bound: float | None = 1.0  # [rad] |theta| above this ends a balancing run as fallen
    speed_bound: float = 200.0  # [rad/s] any joint faster than this is a blow-up

    def validate(self, where: str = "monitor") -> None:
        if self.theta_bound is not None and not self.theta_bound > 0:
            raise ConfigError(f"{where}.theta_bound must be > 0 or null, got {self.theta_bound}")
        if not self.speed_bound > 0:
            raise ConfigError(f"{where}.speed_bound must be > 0, got {self.speed_bound}")


@dataclass
class SimulationConfig:
    """Everything a run needs; ``furuta-drake simulate --config`` reads it, every result writes it back."""

    rig: RigParameters = field(default_factory=RigParameters)
    friction: FrictionParameters = field(default_factory=FrictionParameters)
    actuator: ActuatorParameters = field(default_factory=ActuatorParameters)
    disturbance: DisturbanceParameters = field(default_factory=DisturbanceParameters)
    unmodelled_torque: UnmodelledTorqueParameters = field(default_factory=UnmodelledTorqueParameters)
    encoder: EncoderParameters = field(default_factory=EncoderParameters)
    controller: ControllerConfig = field(default_factory=ControllerConfig)
    observers: ObserverConfig = field(default_factory=ObserverConfig)
    excitation: ExcitationConfig = field(default_factory=ExcitationConfig)
    initial_state: list[float] = field(default_factory=lambda: [0.1, 0.0, 0.0, 0.0])  # [theta, phi, dtheta, dphi]
    duration: float = 10.0  # [s]
    seed: int = 0
    simulator: IntegratorConfig = field(default_factory=IntegratorConfig)
    monitor: MonitorConfig = field(default_factory=MonitorConfig)

    def validate(self, where: str = "") -> None:
        prefix = f"{where}." if where else ""
        self.rig.validate(f"{prefix}rig")
        for name in ("arm_coulomb", "arm_viscous", "pendulum_coulomb", "pendulum_viscous"):
            if getattr(self.rig, name) != 0:
                raise ConfigError(
                    f"{prefix}rig.{name}: in a simulate config, friction goes in the 'friction' "
                    f"section (SimulationConfig.from_rig converts a rig file)"
                )
        if self.rig.unmodelled_torque is not None:
            raise ConfigError(
                f"{prefix}rig.unmodelled_torque: in a simulate config, the torque goes in the 'unmodelled_torque' "
                f"section (SimulationConfig.from_rig converts a rig file)"
            )
        if self.rig.disturbance is not None:
            raise ConfigError(
                f"{prefix}rig.disturbance: in a simulate config, the ongoing torque goes in 'disturbance.arm_torque' "
                f"(SimulationConfig.from_rig converts a rig file)"
            )
        self.friction.validate(f"{prefix}friction")
        self.actuator.validate(f"{prefix}actuator")
        self.disturbance.validate(f"{prefix}disturbance")
        self.unmodelled_torque.validate(f"{prefix}unmodelled_torque")
        self.encoder.validate(f"{prefix}encoder")
        self.controller.validate(f"{prefix}controller")
        self.observers.validate(f"{prefix}observers")
        self.excitation.validate(f"{prefix}excitation")
        self.simulator.validate(f"{prefix}simulator")
        self.monitor.validate(f"{prefix}monitor")
        if len(self.initial_state) != 4 or not all(math.isfinite(v) for v in self.initial_state):
            raise ConfigError(
                f"{prefix}initial_state must be 4 finite numbers [theta, phi, theta_dot, phi_dot],"
                f" got {self.initial_state!r}"
            )
        if self.controller.mode == "open_loop" and self.excitation.torque_rms == 0 and self.excitation.command is None:
            raise ConfigError(
                f"{prefix}controller.mode 'open_loop' needs an excitation: set "
                f"{prefix}excitation.torque_rms > 0 or {prefix}excitation.command"
            )
        if (
            self.controller.friction_compensation
            and self.controller.velocity_source == "kinematic_hg"
            and "vfe" not in self.observers.run
        ):
            raise ConfigError(
                f"{prefix}controller.friction_compensation with the kinematic HG takes F_hat from the "
                f"VFE's Dahl observer: add 'vfe' to {prefix}observers.run"
            )
        if self.controller.mode == "quanser_swingup" and self.rig.motor is None:
            raise ConfigError(
                f"{prefix}rig.motor: controller.mode 'quanser_swingup' commands a voltage, which needs "
                f"the rig's DC motor (resistance, torque_constant, backemf_constant)"
            )
        if self.controller.mode in ("swingup", "quanser_swingup") and self.excitation.arm_reference_amplitude != 0:
            raise ConfigError(
                f"{prefix}controller.mode '{self.controller.mode}' follows no arm reference: set "
                f"{prefix}excitation.arm_reference_amplitude to 0"
            )
        if not (math.isfinite(self.duration) and self.duration > 0):
            raise ConfigError(f"{prefix}duration must be a positive number of seconds, got {self.duration!r}")
        if isinstance(self.seed, bool) or not isinstance(self.seed, int) or not 0 <= self.seed < 2**32:
            raise ConfigError(f"{prefix}seed must be an integer in [0, 2^32), got {self.seed!r}")
        stated = {
            "encoder.sample_period": self.encoder.sample_period,
            "controller.lqr.period": self.controller.lqr.period,
            "observers.hg.period": self.observers.hg.period,
            "observers.dahl.period": self.observers.dahl.period,
            "observers.vfe.period": self.observers.vfe.period,
            "observers.filtered_derivative.period": self.observers.filtered_derivative.period,
        }
        if self.observers.pendulum_friction is not None:
            stated["observers.pendulum_friction.period"] = self.observers.pendulum_friction.period
        for key, period in stated.items():
            require_control_period(
                period, self.control_period, f"{prefix}{key}", f"the control period {prefix}rig.sample_period"
            )

    def with_arm_torque(self, arm_torque) -> SimulationConfig:
        """This config with its ongoing arm disturbance replaced by ``arm_torque`` (a
        :class:`~furuta_drake.torque_disturbance.TorqueDisturbance`, or None for none)."""
        return dataclasses.replace(self, disturbance=dataclasses.replace(self.disturbance, arm_torque=arm_torque))

    @property
    def control_period(self) -> float:
        """The period [s] of every sampled block (encoder, controller, observers, loggers): the rig's."""
        return self.rig.sample_period

    @classmethod
    def from_rig(cls, rig: RigParameters | str, **sections) -> SimulationConfig:
        """A config for ``rig`` (a RigParameters or a shipped name: 'lund', 'qube_servo2'): the rig file's
        nominal friction moves into the ``friction`` section, its unmodelled torque into ``unmodelled_torque``, its
        ongoing disturbance into ``disturbance.arm_torque``, its
        encoder (counts and sample period) into ``encoder``, its torque limit into ``controller``; ``sections``
        override whole sections."""
        if isinstance(rig, str):
            if rig not in RIGS:
                raise ConfigError(f"unknown rig {rig!r}; known: {sorted(RIGS)}")
            rig = RIGS[rig]()
        friction = FrictionParameters(
            arm=_static_friction(rig.arm_coulomb, rig.arm_viscous),
            pendulum=_static_friction(rig.pendulum_coulomb, rig.pendulum_viscous),
        )
        nominal_rig = dataclasses.replace(
            rig,
            arm_coulomb=0.0,
            arm_viscous=0.0,
            pendulum_coulomb=0.0,
            pendulum_viscous=0.0,
            unmodelled_torque=None,
            disturbance=None,
        )
        lqr = dataclasses.replace(LqrParameters(), torque_limit=rig.torque_limit)
        config = cls(
            rig=nominal_rig,
            friction=friction,
            unmodelled_torque=rig.unmodelled_torque or UnmodelledTorqueParameters(),
            disturbance=DisturbanceParameters(arm_torque=rig.disturbance),
            encoder=EncoderParameters(counts_per_rev=rig.counts_per_rev, sample_period=rig.sample_period),
            controller=ControllerConfig(lqr=lqr),
        )
        return dataclasses.replace(config, **sections)


def swingup_config(
    config_or_rig: SimulationConfig | RigParameters | str,
    *,
    duration: float = 10.0,
    theta0: float = math.pi,
    velocity_source: str = "kinematic_hg",
    params: SwingUpParameters | None = None,
) -> SimulationConfig:
    """``config_or_rig`` (a config, a RigParameters or a shipped rig's name) swinging up from rest at ``theta0``
    [rad] (hanging: pi) for ``duration`` [s]: the swing-up controller (``params``, or the config's own) fed by
    ``velocity_source``, the linear observers started at that state (a rig's observer initialised from its first
    sample), and no theta bound in the envelope monitor."""
    config = config_or_rig if isinstance(config_or_rig, SimulationConfig) else SimulationConfig.from_rig(config_or_rig)
    controller = dataclasses.replace(
        config.controller, mode="swingup", velocity_source=velocity_source, swingup=params or config.controller.swingup
    )
    return dataclasses.replace(
        config,
        controller=controller,
        initial_state=[theta0, 0.0, 0.0, 0.0],
        duration=duration,
        monitor=dataclasses.replace(config.monitor, theta_bound=None),
        observers=dataclasses.replace(config.observers, start_at_initial_state=True),
    )


def open_loop_config(
    config_or_rig: SimulationConfig | RigParameters | str,
    command,
    *,
    duration: float,
    seed: int = 0,
    theta0: float = math.pi,
) -> SimulationConfig:
    """``config_or_rig`` (a config, a RigParameters or a shipped rig's name) driven open loop by ``command`` (the
    torque [N m] of each control period, an :class:`ExcitationConfig` field) from rest at ``theta0`` [rad] (hanging:
    pi) for ``duration`` [s]: an identification run as a lab records one, with no theta bound in the envelope
    monitor."""
    config = config_or_rig if isinstance(config_or_rig, SimulationConfig) else SimulationConfig.from_rig(config_or_rig)
    return dataclasses.replace(
        config,
        duration=duration,
        seed=seed,
        initial_state=[theta0, 0.0, 0.0, 0.0],
        controller=dataclasses.replace(config.controller, mode="open_loop"),
        excitation=ExcitationConfig(command=[float(u) for u in command]),
        monitor=dataclasses.replace(config.monitor, theta_bound=None),
    )


def quanser_swingup_config(
    config_or_rig: SimulationConfig | RigParameters | str,
    *,
    initial_state,
    duration: float,
    params: QuanserSwingUpParameters | None = None,
    velocity_filter: FilteredDerivativeParameters | None = None,
) -> SimulationConfig:
    """``config_or_rig`` (a config, a RigParameters or a shipped rig's name, with a ``motor``) run by Quanser's
    swing-up and balance controller (``params``, or the config's own) from ``initial_state`` (paper order) for
    ``duration`` [s], its velocities from the filtered derivative (``velocity_filter``, or the config's own), and
    no theta bound in the envelope monitor."""
    config = config_or_rig if isinstance(config_or_rig, SimulationConfig) else SimulationConfig.from_rig(config_or_rig)
    controller = dataclasses.replace(
        config.controller,
        mode="quanser_swingup",
        velocity_source="filtered_derivative",
        friction_compensation=False,
        quanser_swingup=params or config.controller.quanser_swingup,
    )
    observers = dataclasses.replace(
        config.observers, filtered_derivative=velocity_filter or config.observers.filtered_derivative
    )
    return dataclasses.replace(
        config,
        controller=controller,
        observers=observers,
        initial_state=[float(v) for v in initial_state],
        duration=duration,
        monitor=dataclasses.replace(config.monitor, theta_bound=None),
    )


def _static_friction(coulomb: float, viscous: float) -> JointFrictionParameters:
    if coulomb == 0 and viscous == 0:
        return JointFrictionParameters()
    return JointFrictionParameters(model="static", coulomb_pos=coulomb, coulomb_neg=coulomb, viscous=viscous)


def load_config(path) -> SimulationConfig:
    """Read a simulate config YAML (errors name file, line and key)."""
    return load_yaml_dataclass(path, SimulationConfig)


def dump_config(config: SimulationConfig) -> str:
    """YAML text of a config; :func:`load_config` reads it back to an equal config."""
    return dump_yaml_dataclass(config)
