"""K_sigma adaptation (paper Eq. 16-18, Sec. V-C): direction of adaptation, branches, activation conditions,
convergence with a Dahl observer to the gain that makes F_hat the true friction."""

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Adder, ConstantVectorSource, Gain, LogVectorOutput, Multiplexer

from furuta_drake.adaptation import KSigmaAdaptationParameters, KSigmaAdapter, KSigmaDahlObserver
from furuta_drake.errors import ConfigError
from furuta_drake.observers.dahl import DahlFrictionObserver, DahlObserverParameters

PERIOD = 1e-3
SIGMA0 = 10.0  # [N m/rad]


def adapter_with_inputs(params: KSigmaAdaptationParameters, *, velocity: float, friction_error: float,
                        bristle: float):
    """The adapter with fixed inputs; returns it, its context and a function advancing n periods."""
    adapter = KSigmaAdapter(params, sigma0=SIGMA0)
    context = adapter.CreateDefaultContext()
    adapter.GetInputPort("arm_velocity_estimate_rad_per_s").FixValue(context, [velocity])
    adapter.GetInputPort("friction_error_estimate_Nm").FixValue(context, [0.0, friction_error])
    adapter.GetInputPort("bristle_state_rad").FixValue(context, [bristle])

    def advance(steps: int) -> np.ndarray:
        for _ in range(steps):
            context.SetDiscreteState(adapter.EvalUniquePeriodicDiscreteUpdate(context).value())
            context.SetTime(context.get_time() + PERIOD)
        return adapter.GetOutputPort("K_sigma_branches").Eval(context).copy()
    return adapter, context, advance


# Sliding at v = +-0.5 rad/s the Dahl observer's z_hat = Fc sign(v) / sigma0 with its own (wrong) Fc. The true
# friction is -0.012 N m for v > 0 and +0.018 N m for v < 0 (Sec. V-D); eps_hat_F = F - F_hat.
CASES = {  # name: (v, true friction, observer's Fc, branch that must move, direction)
    "underestimated, v > 0": (0.5, -0.012, 0.008, 0, +1),
    "overestimated, v > 0": (0.5, -0.012, 0.016, 0, -1),
    "underestimated, v < 0": (-0.5, 0.018, 0.012, 1, +1),
    "overestimated, v < 0": (-0.5, 0.018, 0.024, 1, -1),
}


@pytest.mark.parametrize("name", CASES)
def test_k_sigma_rises_when_friction_is_underestimated_and_falls_when_overestimated(name):
    """Eq. 18 at constant inputs: K(t) = 1 - gamma eps_hat_F sigma0 z_hat t on the branch of v's sign, the
    other branch untouched."""
    v, friction, observer_level, branch, direction = CASES[name]
    z_hat = math.copysign(observer_level, v) / SIGMA0
    error = friction - (-SIGMA0 * z_hat)  # F - F_hat with K_sigma = 1
    params = KSigmaAdaptationParameters(gamma=5000.0)
    _, _, advance = adapter_with_inputs(params, velocity=v, friction_error=error, bristle=z_hat)
    branches = advance(200)
    expected = 1.0 - 5000.0 * error * SIGMA0 * z_hat * 200 * PERIOD
    assert np.sign(branches[branch] - 1.0) == direction
    assert branches[branch] == pytest.approx(expected, rel=1e-9)
    assert branches[1 - branch] == 1.0


def test_frozen_below_the_velocity_threshold():
    params = KSigmaAdaptationParameters(velocity_threshold=0.1)
    for v in (0.05, -0.1, 0.0):
        _, _, advance = adapter_with_inputs(params, velocity=v, friction_error=-0.004, bristle=0.0008)
        np.testing.assert_array_equal(advance(300), [1.0, 1.0])


def test_frozen_before_the_enable_time_and_adapting_after():
    """Enabled at t = 0.1 s: K_sigma+ is 1 for the first 100 periods, then moves at Eq. 18's rate."""
    params = KSigmaAdaptationParameters(gamma=5000.0, enable_time=0.1)
    _, _, advance = adapter_with_inputs(params, velocity=0.5, friction_error=-0.004, bristle=0.0008)
    np.testing.assert_array_equal(advance(100), [1.0, 1.0])
    rate = -5000.0 * -0.004 * SIGMA0 * 0.0008
    assert advance(50)[0] == pytest.approx(1.0 + rate * 50 * PERIOD, rel=1e-9)


@pytest.mark.parametrize("v, branch", [(0.3, 0), (-0.3, 1), (0.0, 1)])
def test_k_sigma_output_is_the_branch_of_the_velocity_sign(v, branch):
    adapter, context, _ = adapter_with_inputs(KSigmaAdaptationParameters(), velocity=v, friction_error=0.0,
                                              bristle=0.0)
    context.SetDiscreteState([1.3, 1.8])
    assert adapter.GetOutputPort("K_sigma").Eval(context)[0] == [1.3, 1.8][branch]


@pytest.mark.parametrize("merged", [False, True], ids=["DahlFrictionObserver+KSigmaAdapter", "KSigmaDahlObserver"])
@pytest.mark.parametrize("v, level", [(0.5, 0.012), (-0.5, 0.018)])
def test_adaptation_with_a_dahl_observer_converges_to_the_true_gain(v, level, merged):
    """A Dahl observer with K_sigma from the adapter and a 'true' Dahl friction K_true = 1.7 times larger on the
    same v: eps_hat_F = F - F_hat = -(K_true - K) sigma0 z_hat, so Eq. 18 is
    dK/dt = -gamma (sigma0 z_hat)^2 (K - K_true), and z_hat = z_ss (1 - exp(-r t)) (Eq. 8, r = sigma0 |v| / Fc):
    K - K_true = (1 - K_true) exp(-gamma Fc^2 int_0^t (1 - e^(-r s))^2 ds), about exp(-gamma Fc^2 t) once the
    bristle has settled. gamma = 40000 / ((N m)^2 s): rate a = gamma Fc^2 = 5.8 (Fc = 0.012) or 13 (0.018) 1/s.
    Tolerance 5 %: the explicit Euler step, (1 - a h)^n against exp(-a n h), drifts by n (a h)^2 / 2 <= 3.4 %.
    The same with the adaptation inside the observer (KSigmaDahlObserver)."""
    k_true, gamma, duration = 1.7, 40000.0, 0.4
    dahl_params = DahlObserverParameters(coulomb_pos=0.012, coulomb_neg=0.018, sigma0=SIGMA0)
    builder = DiagramBuilder()
    velocity = builder.AddSystem(ConstantVectorSource([v]))
    angles = builder.AddSystem(ConstantVectorSource([0.0, 0.0]))
    reference = builder.AddSystem(ConstantVectorSource([0.0, v]))  # no tracking error: K_z = 0
    true_gain = builder.AddSystem(ConstantVectorSource([k_true]))
    truth = builder.AddSystem(DahlFrictionObserver(dahl_params))
    if merged:
        observer = adapter = builder.AddSystem(KSigmaDahlObserver(dahl_params, KSigmaAdaptationParameters(gamma=gamma)))
    else:
        observer = builder.AddSystem(DahlFrictionObserver(dahl_params))
        adapter = builder.AddSystem(KSigmaAdapter(KSigmaAdaptationParameters(gamma=gamma), sigma0=SIGMA0))
    negate = builder.AddSystem(Gain(-1.0, 1))
    error = builder.AddSystem(Adder(2, 1))
    no_pendulum_error = builder.AddSystem(ConstantVectorSource([0.0]))
    errors = builder.AddSystem(Multiplexer([1, 1]))
    for dahl in (observer, truth):
        builder.Connect(velocity.get_output_port(), dahl.GetInputPort("arm_velocity_estimate_rad_per_s"))
        builder.Connect(angles.get_output_port(), dahl.GetInputPort("measured_angles_rad"))
        builder.Connect(reference.get_output_port(), dahl.GetInputPort("arm_reference_rad"))
    builder.Connect(true_gain.get_output_port(), truth.GetInputPort("K_sigma"))
    builder.Connect(truth.GetOutputPort("friction_estimate_Nm"), error.get_input_port(0))
    builder.Connect(observer.GetOutputPort("friction_estimate_Nm"), negate.get_input_port())
    builder.Connect(negate.get_output_port(), error.get_input_port(1))
    builder.Connect(no_pendulum_error.get_output_port(), errors.get_input_port(0))
    builder.Connect(error.get_output_port(), errors.get_input_port(1))
    builder.Connect(errors.get_output_port(), adapter.GetInputPort("friction_error_estimate_Nm"))
    if not merged:
        builder.Connect(adapter.GetOutputPort("K_sigma"), observer.GetInputPort("K_sigma"))
        builder.Connect(velocity.get_output_port(), adapter.GetInputPort("arm_velocity_estimate_rad_per_s"))
        builder.Connect(observer.GetOutputPort("bristle_state_rad"), adapter.GetInputPort("bristle_state_rad"))
    log = LogVectorOutput(adapter.GetOutputPort("K_sigma_branches"), builder, PERIOD)
    diagram = builder.Build()
    context = diagram.CreateDefaultContext()
    Simulator(diagram, context).AdvanceTo(duration)
    t, k_sigma = log.FindLog(context).sample_times(), log.FindLog(context).data()[0 if v > 0 else 1]
    r = SIGMA0 * abs(v) / level
    settled_time = t - 2 * (1 - np.exp(-r * t)) / r + (1 - np.exp(-2 * r * t)) / (2 * r)
    expected = k_true + (1.0 - k_true) * np.exp(-gamma * level**2 * settled_time)
    assert np.all(np.diff(k_sigma) >= 0)  # monotone: the Euler step is far inside its stability bound
    np.testing.assert_allclose(k_sigma - k_true, expected - k_true, rtol=0.05)
    assert abs(k_sigma[-1] - k_true) < 0.2 * (k_true - 1.0)


@pytest.mark.parametrize("field, value", [
    ("gamma", -1.0), ("velocity_threshold", -0.1), ("enable_time", -1.0), ("initial", 0.0), ("period", 0.0),
    ("gamma", float("nan")),
])
def test_invalid_parameters_are_rejected_naming_the_field(field, value):
    with pytest.raises(ConfigError, match=rf"observers\.adaptation\.{field}"):
        KSigmaAdapter(KSigmaAdaptationParameters(**{field: value}), sigma0=SIGMA0)


def test_nonpositive_sigma0_is_rejected():
    with pytest.raises(ConfigError, match="sigma0"):
        KSigmaAdapter(KSigmaAdaptationParameters(), sigma0=0.0)
