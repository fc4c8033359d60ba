"""Blind-validation suite for the diagnosis: "real" logs recorded from Drake simulations with one hidden effect.

Each case is a folder with the nominal ``rig.yaml`` (the spec's format), two train and two held-out logs (a
balancing run under LQR with a seeded excitation, and a hanging run under an open-loop multisine), and
nothing else; the answers are written apart, in ``answers.json`` at the suite's root, so the diagnosis can be
run blind on the case folders.

The hidden effects are realised with the project's *true-world* blocks, not with the diagnosis' candidate
models: arm Coulomb friction is Dahl friction (presliding included), Stribeck friction is LuGre, the delay is a
Drake ``DiscreteTimeDelay`` inside the loop. Magnitudes scale with the rig (fractions of m g l, of the
control period, ...), so the same suite definition serves the Lund rig and the QUBE-Servo 2.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from furuta_drake.config import ExcitationConfig, MonitorConfig, SimulationConfig
from furuta_drake.friction import JointFrictionParameters
from furuta_drake.rig import RIGS, RigParameters
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import dump_yaml_dataclass

VOCABULARY = (
    "arm_coulomb_friction",
    "arm_viscous_friction",
    "arm_stribeck",
    "friction_asymmetry",
    "pendulum_friction",
    "encoder_quantization",
    "measurement_noise",
    "input_delay",
    "torque_gain_error",
    "actuator_deadzone",
    "actuator_lag",
    "actuator_saturation",
    "arm_spring",
    "inertia_mismatch",
)
OUTSIDE_VOCABULARY = "cogging_torque"


@dataclass(frozen=True)
class CaseSpec:
    """One suite case: a rig, the hidden effect(s) at a magnitude level (1 moderate, 2 strong), a seed."""

    rig: str
    effects: tuple[str, ...]
    level: int
    seed: int

    @property
    def name(self) -> str:
        effect = "+".join(self.effects) if self.effects else "none"
        return f"{self.rig}__{effect}__L{self.level}__s{self.seed}"

    @property
    def expected_verdict(self) -> str:
        """``none``, ``unexplained`` (an effect outside the vocabulary), or the effect; for a pair, the
        verdict is right when the report's ``effects`` hold both (the spec's verdict names one of them)."""
        if not self.effects:
            return "none"
        if OUTSIDE_VOCABULARY in self.effects:
            return "unexplained"
        return self.effects[0] if len(self.effects) == 1 else "+".join(sorted(self.effects))


def verdict_is_right(answer: dict, report: dict) -> bool:
    """Score one case: the verdict for a single effect, ``none`` or ``unexplained``; both effects for a pair."""
    expected = answer["expected_verdict"]
    if "+" in expected:
        return sorted(report["effects"]) == sorted(expected.split("+"))
    return report["verdict"] == expected


def _with_arm_friction(config: SimulationConfig, arm: JointFrictionParameters) -> SimulationConfig:
    """``config`` with ``arm`` as the arm joint's friction law."""
    return dataclasses.replace(config, friction=dataclasses.replace(config.friction, arm=arm))


def _with_actuator(config: SimulationConfig, **changes) -> SimulationConfig:
    """``config`` with the actuator's fields in ``changes`` replaced."""
    return dataclasses.replace(config, actuator=dataclasses.replace(config.actuator, **changes))


def _with_encoder(config: SimulationConfig, **changes) -> SimulationConfig:
    """``config`` with the encoder's fields in ``changes`` replaced."""
    return dataclasses.replace(config, encoder=dataclasses.replace(config.encoder, **changes))


def _with_disturbance(config: SimulationConfig, **changes) -> SimulationConfig:
    """``config`` with the disturbance's fields in ``changes`` replaced."""
    return dataclasses.replace(config, disturbance=dataclasses.replace(config.disturbance, **changes))


def _arm_coulomb_friction(config: SimulationConfig, k: float) -> SimulationConfig:
    """Dahl friction on the arm (presliding included) at 0.05 k m g l."""
    level_Nm = 0.05 * k * config.rig.gravity_torque
    return _with_arm_friction(
        config,
        JointFrictionParameters(model="dahl", coulomb_pos=level_Nm, coulomb_neg=level_Nm, sigma0=400.0 * level_Nm),
    )


def _arm_viscous_friction(config: SimulationConfig, k: float) -> SimulationConfig:
    """Extra arm viscous damping: the arm's velocity decays at 0.8 k 1/s."""
    arm = config.friction.arm
    damping = 0.8 * k * config.rig.arm_inertia_total
    return _with_arm_friction(
        config,
        dataclasses.replace(arm, model="static" if arm.model == "none" else arm.model, viscous=arm.viscous + damping),
    )


def _arm_stribeck(config: SimulationConfig, k: float) -> SimulationConfig:
    """LuGre friction on the arm: Coulomb 0.04 m g l, static (1 + k) times that, Stribeck velocity 0.1 rad/s."""
    level_Nm = 0.04 * config.rig.gravity_torque
    return _with_arm_friction(
        config,
        JointFrictionParameters(
            model="lugre",
            coulomb_pos=level_Nm,
            coulomb_neg=level_Nm,
            static_pos=(1.0 + 1.0 * k) * level_Nm,
            static_neg=(1.0 + 1.0 * k) * level_Nm,
            stribeck_velocity=0.1,
            sigma0=400.0 * level_Nm,
            sigma1=0.0,
        ),
    )


def _friction_asymmetry(config: SimulationConfig, k: float) -> SimulationConfig:
    """Dahl friction on the arm, 0.03 m g l one way and (1 + 0.75 k) times that the other."""
    low = 0.03 * config.rig.gravity_torque
    return _with_arm_friction(
        config,
        JointFrictionParameters(model="dahl", coulomb_pos=low, coulomb_neg=low * (1.0 + 0.75 * k), sigma0=400.0 * low),
    )


def _pendulum_friction(config: SimulationConfig, k: float) -> SimulationConfig:
    """Static friction on the pendulum: Coulomb 0.004 k m g l, and its swing decays at 0.3 k 1/s."""
    damping = 0.3 * k * config.rig.pendulum_inertia_total
    level_Nm = 0.004 * k * config.rig.gravity_torque
    pendulum = JointFrictionParameters(model="static", coulomb_pos=level_Nm, coulomb_neg=level_Nm, viscous=damping)
    return dataclasses.replace(config, friction=dataclasses.replace(config.friction, pendulum=pendulum))


def _encoder_quantization(config: SimulationConfig, k: float) -> SimulationConfig:
    """Coarser encoders: the counts per revolution divided by round(4 k), at least 2."""
    return _with_encoder(config, counts_per_rev=config.encoder.counts_per_rev // max(2, round(4 * k)))


def _measurement_noise(config: SimulationConfig, k: float) -> SimulationConfig:
    """White angle noise of 1.5 k encoder resolutions."""
    return _with_encoder(config, noise_std=1.5 * k * config.rig.encoder_resolution)


def _input_delay(config: SimulationConfig, k: float) -> SimulationConfig:
    """An input delay of 1.5 + 1.5 k control periods (3 and 4.5 at the suite's levels)."""
    return _with_actuator(config, delay=(1.5 + 1.5 * k) * config.encoder.sample_period)


def _torque_gain_error(config: SimulationConfig, k: float) -> SimulationConfig:
    """A torque gain of 1 - 0.2 k up to level 1, 1 + 0.35 (k - 1) above it."""
    return _with_actuator(config, gain=1.0 - 0.2 * k if k <= 1.0 else 1.0 + 0.35 * (k - 1.0))


def _actuator_deadzone(config: SimulationConfig, k: float) -> SimulationConfig:
    """An actuator deadzone of 0.03 k m g l."""
    return _with_actuator(config, deadzone=0.03 * k * config.rig.gravity_torque)


def _actuator_lag(config: SimulationConfig, k: float) -> SimulationConfig:
    """A first-order actuator lag of time constant 6 k ms."""
    return _with_actuator(config, lag_time_constant=0.006 * k)


def _actuator_saturation(config: SimulationConfig, k: float) -> SimulationConfig:
    """A torque saturation at max(0.7 - 0.2 k, 0.1) times the LQR's torque limit."""
    return _with_actuator(config, saturation=config.controller.lqr.torque_limit * max(0.7 - 0.2 * k, 0.1))


def _arm_spring(config: SimulationConfig, k: float) -> SimulationConfig:
    """A cable that pulls the arm back to 0.05 rad with 0.25 k m g l per radian."""
    stiffness = 0.25 * k * config.rig.gravity_torque
    return _with_disturbance(config, arm_spring_stiffness=stiffness, arm_spring_equilibrium=0.05)


def _inertia_mismatch(config: SimulationConfig, k: float) -> SimulationConfig:
    """A pendulum mass (1 + 0.2 k) times and an arm inertia (1 - 0.15 k) times the nominal ones."""
    rig = config.rig
    true_rig = dataclasses.replace(
        rig, pendulum_mass=rig.pendulum_mass * (1.0 + 0.2 * k), arm_inertia=rig.arm_inertia * (1.0 - 0.15 * k)
    )
    return dataclasses.replace(config, rig=true_rig)


def _cogging_torque(config: SimulationConfig, k: float) -> SimulationConfig:
    """Cogging torque of amplitude 0.04 k m g l and 12 periods per turn (outside the vocabulary)."""
    return _with_disturbance(config, cogging_amplitude=0.04 * k * config.rig.gravity_torque, cogging_periods=12)


# The true-world realisation of each effect: a function of the config and the magnitude level.
REALISATIONS = {
    "arm_coulomb_friction": _arm_coulomb_friction,
    "arm_viscous_friction": _arm_viscous_friction,
    "arm_stribeck": _arm_stribeck,
    "friction_asymmetry": _friction_asymmetry,
    "pendulum_friction": _pendulum_friction,
    "encoder_quantization": _encoder_quantization,
    "measurement_noise": _measurement_noise,
    "input_delay": _input_delay,
    "torque_gain_error": _torque_gain_error,
    "actuator_deadzone": _actuator_deadzone,
    "actuator_lag": _actuator_lag,
    "actuator_saturation": _actuator_saturation,
    "arm_spring": _arm_spring,
    "inertia_mismatch": _inertia_mismatch,
    OUTSIDE_VOCABULARY: _cogging_torque,
}


def with_effect(config: SimulationConfig, effect: str, level: float) -> SimulationConfig:
    """``config`` with the true-world realisation of ``effect`` at magnitude ``level``: the suite's 1 (moderate)
    and 2 (strong), or any level in (0, 3] (the property checks draw them; the gain error is a loss up to level
    1 and a gain above it)."""
    if effect not in REALISATIONS:
        raise ValueError(f"unknown effect {effect!r}")
    return REALISATIONS[effect](config, float(level))


def run_configs(rig: RigParameters, seed: int, duration: float) -> dict[str, SimulationConfig]:
    """The two runs of a log pair: balancing under LQR with a seeded multisine and arm square wave, and hanging
    under an open-loop multisine."""
    base = SimulationConfig.from_rig(rig)
    scale = rig.gravity_torque
    balance = dataclasses.replace(
        base,
        duration=duration,
        seed=seed,
        initial_state=[0.05, 0.0, 0.0, 0.0],
        excitation=ExcitationConfig(
            torque_rms=0.08 * scale,
            frequency_min=0.3,
            frequency_max=6.0,
            arm_reference_amplitude=0.3,
            arm_reference_period=3.0,
        ),
        monitor=MonitorConfig(theta_bound=1.2),
    )
    hanging = dataclasses.replace(
        base,
        duration=duration,
        seed=seed + 1000,
        initial_state=[np.pi, 0.0, 0.0, 0.0],
        controller=dataclasses.replace(base.controller, mode="open_loop"),
        excitation=ExcitationConfig(torque_rms=0.25 * scale, frequency_min=0.3, frequency_max=5.0),
        monitor=MonitorConfig(theta_bound=None),
    )
    return {"balance": balance, "hanging": hanging}


# Effects that act together on one rig (every one must be named): friction beside an actuator effect, and three.
SEVERAL_EFFECTS = (
    ("arm_coulomb_friction", "input_delay"),
    ("arm_coulomb_friction", "actuator_lag"),
    ("arm_viscous_friction", "input_delay"),
    ("inertia_mismatch", "input_delay"),
    ("arm_coulomb_friction", "actuator_deadzone"),
    ("arm_coulomb_friction", "arm_spring"),
    ("arm_coulomb_friction", "input_delay", "inertia_mismatch"),
    ("arm_viscous_friction", "actuator_lag", "inertia_mismatch"),
    ("arm_coulomb_friction", "actuator_lag", "arm_spring"),
)


SUITE_RIGS = ("lund", "qube_servo2")  # the rigs the suite's effects are sized and its controllers tuned for


def default_cases(rigs=SUITE_RIGS, seeds=(1,), levels=(1, 2), several: bool = True) -> list[CaseSpec]:
    """Every vocabulary effect at each level on each rig and seed, plus none, cogging and (``several``) the
    combinations of :data:`SEVERAL_EFFECTS` at the strong level."""
    cases = []
    for rig in rigs:
        for seed in seeds:
            cases.append(CaseSpec(rig, (), 0, seed))
            cases.append(CaseSpec(rig, (), 0, seed + 100))
            for effect in VOCABULARY:
                for level in levels:
                    cases.append(CaseSpec(rig, (effect,), level, seed))
            cases.append(CaseSpec(rig, (OUTSIDE_VOCABULARY,), 2, seed))
            if several:
                cases += [CaseSpec(rig, effects, 2, seed) for effects in SEVERAL_EFFECTS]
    return cases


def write_case(case: CaseSpec, directory: Path, duration: float = 8.0) -> dict:
    """Simulate ``case`` and write its folder (rig.yaml, train_*.csv, heldout_*.csv); return its answer."""
    from furuta_drake.results import write_log_csv

    rig = RIGS[case.rig]()
    directory.mkdir(parents=True, exist_ok=True)
    nominal = dataclasses.replace(rig)
    (directory / "rig.yaml").write_text(dump_yaml_dataclass(nominal))
    files = {}
    for split, seed in (("train", case.seed), ("heldout", case.seed + 500)):
        for run, config in run_configs(rig, seed, duration).items():
            for effect in case.effects:
                config = with_effect(config, effect, case.level)
            result = simulate(config)
            path = directory / f"{split}_{run}.csv"
            write_log_csv(result, path)
            files.setdefault(split, []).append(path.name)
    truth = {effect: true_params(rig, effect, case.level) for effect in case.effects}
    return {
        "case": case.name,
        "rig": case.rig,
        "effects": list(case.effects),
        "level": case.level,
        "seed": case.seed,
        "expected_verdict": case.expected_verdict,
        "files": files,
        "truth": truth,
    }


def write_suite(out: Path, cases: list[CaseSpec], duration: float = 8.0, progress=None) -> Path:
    """Write every case folder under ``out/cases`` and the answers to ``out/answers.json``."""
    out = Path(out)
    answers = []
    for case in cases:
        answers.append(write_case(case, out / "cases" / case.name, duration))
        if progress is not None:
            progress(case)
    path = out / "answers.json"
    path.write_text(json.dumps(answers, indent=2, sort_keys=True) + "\n")
    return path


def true_params(rig: RigParameters, effect: str, level: int) -> dict[str, float]:
    """The hidden effect's parameters in the vocabulary's names and units (as a report's ranking lists them),
    read from its true-world realisation; cogging, outside the vocabulary, as its amplitude and periods."""
    base = SimulationConfig.from_rig(rig)
    config = with_effect(base, effect, level)
    arm, pendulum, actuator = config.friction.arm, config.friction.pendulum, config.actuator
    if effect in ("arm_coulomb_friction", "arm_stribeck", "friction_asymmetry"):
        params = {
            "arm_coulomb_friction": {"coulomb": arm.coulomb_pos},
            "arm_stribeck": {
                "coulomb": arm.coulomb_pos,
                "static": arm.static_levels[0],
                "stribeck_velocity": arm.stribeck_velocity,
            },
            "friction_asymmetry": {"coulomb_pos": arm.coulomb_pos, "coulomb_neg": arm.coulomb_neg},
        }[effect]
        return {**params, "presliding": arm.bristle_bound}
    if effect == "inertia_mismatch":
        true_rig, constants = config.rig, ("arm_inertia_total", "pendulum_inertia_total", "coupling", "gravity_torque")
        names = ("arm_inertia_scale", "pendulum_inertia_scale", "coupling_scale", "gravity_scale")
        return {name: getattr(true_rig, c) / getattr(rig, c) for name, c in zip(names, constants)}
    return {
        "arm_viscous_friction": lambda: {"viscous": arm.viscous},
        "pendulum_friction": lambda: {"coulomb": pendulum.coulomb_pos, "viscous": pendulum.viscous},
        "encoder_quantization": lambda: {"counts_per_rev": float(config.encoder.counts_per_rev)},
        "measurement_noise": lambda: {"noise_std": config.encoder.noise_std},
        "input_delay": lambda: {"delay": actuator.delay},
        "torque_gain_error": lambda: {"gain": actuator.gain},
        "actuator_deadzone": lambda: {"deadzone": actuator.deadzone},
        "actuator_lag": lambda: {"time_constant": actuator.lag_time_constant},
        "actuator_saturation": lambda: {"limit": actuator.saturation},
        "arm_spring": lambda: {
            "stiffness": config.disturbance.arm_spring_stiffness,
            "equilibrium": config.disturbance.arm_spring_equilibrium,
        },
        OUTSIDE_VOCABULARY: lambda: {
            "cogging_amplitude": config.disturbance.cogging_amplitude,
            "cogging_periods": float(config.disturbance.cogging_periods),
        },
    }[effect]()
