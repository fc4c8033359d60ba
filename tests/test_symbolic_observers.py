"""The C++ (symbolic) discrete systems against the Python float evaluation of the same laws: the Dahl observer
(Eq. 8-9, 16) in its variants, the K_sigma adapter (Eq. 18) and the encoder's quantisation, driven by the same
random input sequences, give the same states and outputs to 1e-12 relative. The float reference is the update
the Python LeafSystems made at every sample (:func:`dahl_step`, :func:`k_sigma_update`, Python's round)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ConstantVectorSource, Integrator

from furuta_drake.encoder import Encoder, EncoderParameters, quantise
from furuta_drake.observers.dahl import (
    DahlAdaptation,
    DahlFrictionObserver,
    DahlObserverParameters,
    dahl_step,
    injection,
    model_torque,
    observer_model,
)
from furuta_drake.observers.k_sigma import KSigmaAdaptationParameters, KSigmaAdapter, active_gain, k_sigma_update
from furuta_drake.observers.parameter_adaptation import ParameterAdaptationParameters

PERIOD = 1e-3
STEPS = 400
RTOL = 1e-12


def velocities(rng: np.random.Generator) -> np.ndarray:
    """Arm velocity estimates [rad/s]: sliding both ways, reversals, small values and exact zeros (the v = 0
    limit of the exact step)."""
    v = rng.normal(0.0, 0.6, STEPS) * (rng.random(STEPS) < 0.8)
    v[rng.random(STEPS) < 0.1] *= 1e-6
    return v


def run(system, context, inputs: dict, steps: int, outputs: list[str]) -> tuple[np.ndarray, dict]:
    """Advance ``system`` ``steps`` periods with ``inputs[port][k]`` fixed at step k; the state after each step
    and each output port's value after it."""
    states, values = [], {name: [] for name in outputs}
    for k in range(steps):
        context.SetTime(k * PERIOD)
        for port, sequence in inputs.items():
            system.GetInputPort(port).FixValue(context, np.atleast_1d(sequence[k]))
        context.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(context))
        states.append(context.get_discrete_state_vector().CopyToVector())
        for name in outputs:
            values[name].append(system.GetOutputPort(name).Eval(context).copy())
    return np.array(states), {name: np.array(value) for name, value in values.items()}


def assert_same(actual: np.ndarray, expected: np.ndarray) -> None:
    scale = np.max(np.abs(expected)) or 1.0
    np.testing.assert_allclose(actual, expected, rtol=RTOL, atol=RTOL * scale)


ARM_VARIANTS = {
    "paper Dahl": DahlObserverParameters(),
    "reversed injection": DahlObserverParameters(injection_sign=-1),
    "printed sigma1 sign": DahlObserverParameters(sigma1=0.05, sigma1_sign=1, rho=50.0, rho2=0.2),
    "LuGre": DahlObserverParameters(
        static_pos=0.02, static_neg=0.03, stribeck_velocity=0.1, sigma1=0.1, sigma2=0.002, sigma1_sign=-1
    ),
    "no injection": DahlObserverParameters(rho=None),
    "stiff": DahlObserverParameters(sigma0=1000.0),
    "K_sigma": DahlObserverParameters(adaptation=DahlAdaptation(k_sigma=KSigmaAdaptationParameters())),
    "Fc and sigma0": DahlObserverParameters(adaptation=DahlAdaptation(parameters=ParameterAdaptationParameters())),
}


@pytest.mark.parametrize("variant", ARM_VARIANTS)
def test_arm_dahl_observer_is_the_python_update(variant):
    params = ARM_VARIANTS[variant]
    rng = np.random.default_rng(list(ARM_VARIANTS).index(variant))
    v = velocities(rng)
    angles = rng.normal(0.0, 0.05, (STEPS, 2))
    reference = np.column_stack([rng.normal(0.0, 0.02, STEPS), rng.normal(0.0, 0.1, STEPS)])
    inputs = {"arm_velocity_estimate_rad_per_s": v, "measured_angles_rad": angles, "arm_reference_rad": reference}
    adapted = None
    if params.adaptation is not None and params.adaptation.k_sigma is not None:
        inputs["K_sigma"] = rng.uniform(0.5, 2.0, STEPS)
    elif params.adaptation is not None:
        adapted = np.column_stack(
            [rng.uniform(0.008, 0.016, STEPS), rng.uniform(0.012, 0.024, STEPS), rng.uniform(5.0, 20.0, STEPS)]
        )
        inputs["dahl_parameters"] = adapted
    system = DahlFrictionObserver(params, period=PERIOD)
    outputs = [system.get_output_port(i).get_name() for i in range(system.num_output_ports())]
    states, values = run(system, system.CreateDefaultContext(), inputs, STEPS, outputs)

    z, expected = 0.0, {name: [] for name in outputs}
    for k in range(STEPS):
        vk = float(v[k])
        parameters = None if adapted is None else adapted[k].tolist()
        sigma0, level = observer_model(params, vk, parameters)
        eps, eps_v = float(angles[k, 1] - reference[k, 0]), vk - float(reference[k, 1])
        z = dahl_step(params, PERIOD, z, vk, sigma0, level, eps, eps_v)
        assert states[k, 0] == pytest.approx(z, rel=RTOL, abs=1e-18)
        # The outputs after the step read the inputs of that step (they are held until the next one).
        torque = model_torque(params, z, vk, sigma0)
        expected["friction_estimate_Nm"].append(torque * float(inputs["K_sigma"][k]) if "K_sigma" in inputs else torque)
        expected["bristle_state_rad"].append(z)
        if "bristle_injection_rad_per_s" in expected:
            expected["bristle_injection_rad_per_s"].append(injection(params, sigma0, vk, level, eps, eps_v))
    for name in outputs:
        assert_same(values[name][:, 0], np.array(expected[name]))


def test_pendulum_observer_without_injection_is_the_python_update():
    params = DahlObserverParameters(coulomb_pos=0.003, coulomb_neg=0.004, sigma0=2.0, rho=None)
    rng = np.random.default_rng(7)
    v = velocities(rng)
    system = DahlFrictionObserver(params, period=PERIOD, joint="pendulum")
    inputs = {"pendulum_velocity_estimate_rad_per_s": v, "measured_angles_rad": rng.normal(0.0, 0.05, (STEPS, 2))}
    states, values = run(system, system.CreateDefaultContext(), inputs, STEPS, ["friction_estimate_Nm"])
    z = 0.0
    for k in range(STEPS):
        sigma0, level = observer_model(params, float(v[k]))
        z = dahl_step(params, PERIOD, z, float(v[k]), sigma0, level, 0.0, 0.0)
        assert states[k, 0] == pytest.approx(z, rel=RTOL, abs=1e-18)
        assert values["friction_estimate_Nm"][k, 0] == pytest.approx(-params.sigma0 * z, rel=RTOL, abs=1e-18)


def test_k_sigma_adapter_is_the_python_update():
    """Both branches, the threshold and the enable time (crossed mid-run) against :func:`k_sigma_update`."""
    params = KSigmaAdaptationParameters(gamma=4.0e4, velocity_threshold=0.1, enable_time=0.1, initial=1.2)
    rng = np.random.default_rng(3)
    v = velocities(rng)
    bristle = rng.normal(0.0, 1e-3, STEPS)
    error = rng.normal(0.0, 5e-3, (STEPS, 2))
    adapter = KSigmaAdapter(params, period=PERIOD, sigma0=10.0)
    inputs = {"arm_velocity_estimate_rad_per_s": v, "bristle_state_rad": bristle, "friction_error_estimate_Nm": error}
    states, values = run(adapter, adapter.CreateDefaultContext(), inputs, STEPS, ["K_sigma", "K_sigma_branches"])
    gains = [params.initial, params.initial]
    for k in range(STEPS):
        gains = k_sigma_update(
            params,
            PERIOD,
            10.0,
            time=k * PERIOD,
            v=float(v[k]),
            friction_error=float(error[k, 1]),
            bristle=float(bristle[k]),
            gains=gains,
        )
        assert_same(states[k], np.array(gains))
        assert_same(values["K_sigma_branches"][k], np.array(gains))
        assert values["K_sigma"][k, 0] == active_gain(float(v[k]), gains)
    assert np.ptp(states[:, 0]) > 0 and np.ptp(states[:, 1]) > 0  # both branches moved


def encoder_samples(encoder, angles: np.ndarray) -> np.ndarray:
    """The encoder's output after each periodic sample of ``angles`` (theta, phi) [rad]."""
    context = encoder.CreateDefaultContext()
    samples = []
    for k, (theta, phi) in enumerate(angles):
        context.SetTime(k * PERIOD)
        encoder.GetInputPort("true_state").FixValue(context, [theta, phi, 0.0, 0.0])
        context.SetDiscreteState(encoder.EvalUniquePeriodicDiscreteUpdate(context))
        samples.append(encoder.GetOutputPort("measured_angles_rad").Eval(context).copy())
    return np.array(samples)


def test_encoder_quantisation_is_pythons_round_half_to_even():
    """Random angles, and angles exactly half a count from two counts (ties go to the even count)."""
    params = EncoderParameters(counts_per_rev=4096)
    q = params.encoder_resolution
    rng = np.random.default_rng(5)
    ties = (np.arange(-40, 40) + 0.5) * q
    angles = np.concatenate([rng.uniform(-30.0, 30.0, (200, 2)), np.column_stack([ties, -ties])])
    expected = np.vectorize(lambda a: quantise(float(a), q))(angles)
    np.testing.assert_array_equal(encoder_samples(Encoder(params, period=PERIOD), angles), expected)


def test_encoder_output_is_the_initialization_sample_until_the_first_periodic_one():
    """Simulated from a moving state, the output before the t = 0 update is the sample taken at
    initialization, not zero, and the encoder has no direct feedthrough."""
    builder = DiagramBuilder()
    ramp = builder.AddSystem(Integrator(4))
    speed = builder.AddSystem(ConstantVectorSource([2.0, -3.0, 0.0, 0.0]))
    params = EncoderParameters(counts_per_rev=4096)
    encoder = builder.AddSystem(Encoder(params, period=PERIOD))
    builder.Connect(speed.get_output_port(), ramp.get_input_port())
    builder.Connect(ramp.get_output_port(), encoder.GetInputPort("true_state"))
    diagram = builder.Build()
    assert not encoder.HasAnyDirectFeedthrough()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    ramp.set_integral_value(ramp.GetMyMutableContextFromRoot(context), [0.3, -1.0, 0.0, 0.0])
    simulator.Initialize()
    measured = encoder.GetOutputPort("measured_angles_rad").Eval(encoder.GetMyContextFromRoot(context))
    np.testing.assert_array_equal(
        measured, [quantise(0.3, params.encoder_resolution), quantise(-1.0, params.encoder_resolution)]
    )


def test_observers_in_a_continuous_diagram_simulate():
    """The C++ systems run beside continuous states (the plant's): a discrete SymbolicVectorSystem alone could
    not, its time derivatives abort."""
    params = dataclasses.replace(ARM_VARIANTS["K_sigma"])
    builder = DiagramBuilder()
    motion = builder.AddSystem(Integrator(1))
    builder.Connect(builder.AddSystem(ConstantVectorSource([0.5])).get_output_port(), motion.get_input_port())
    dahl = builder.AddSystem(DahlFrictionObserver(params, period=PERIOD))
    adapter = builder.AddSystem(KSigmaAdapter(params.adaptation.k_sigma, period=PERIOD, sigma0=params.sigma0))
    builder.Connect(motion.get_output_port(), dahl.GetInputPort("arm_velocity_estimate_rad_per_s"))
    builder.Connect(motion.get_output_port(), adapter.GetInputPort("arm_velocity_estimate_rad_per_s"))
    zeros = builder.AddSystem(ConstantVectorSource([0.0, 0.0]))
    for port in ("measured_angles_rad", "arm_reference_rad"):
        builder.Connect(zeros.get_output_port(), dahl.GetInputPort(port))
    builder.Connect(zeros.get_output_port(), adapter.GetInputPort("friction_error_estimate_Nm"))
    builder.Connect(dahl.GetOutputPort("bristle_state_rad"), adapter.GetInputPort("bristle_state_rad"))
    builder.Connect(adapter.GetOutputPort("K_sigma"), dahl.GetInputPort("K_sigma"))
    simulator = Simulator(builder.Build())
    simulator.AdvanceTo(0.2)
    z = dahl.GetOutputPort("bristle_state_rad").Eval(dahl.GetMyContextFromRoot(simulator.get_context()))[0]
    assert 0.0 < z < params.coulomb_pos / params.sigma0
