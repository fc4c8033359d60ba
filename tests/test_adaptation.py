"""K_sigma adaptation (paper Eq. 16-18, Sec. V-C), the K_sigma adapter beside the Dahl observer: direction of
adaptation, branches, activation conditions, the active gain, convergence to the gain that makes F_hat the true
friction; one way to switch it on."""

import math

import numpy as np
import pytest
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import Adder, ConstantVectorSource, Gain, LogVectorOutput, Multiplexer

from furuta_drake.config import ObserverConfig
from furuta_drake.errors import ConfigError
from furuta_drake.observers.dahl import (
    DahlAdaptation,
    DahlFrictionObserver,
    DahlObserverParameters,
    adapting_dahl_observer,
)
from furuta_drake.observers.k_sigma import KSigmaAdaptationParameters, KSigmaAdapter
from furuta_drake.observers.parameter_adaptation import ParameterAdaptationParameters

PERIOD = 1e-3
SIGMA0 = 10.0  # [N m/rad]


def k_sigma_adapter(params: KSigmaAdaptationParameters, *, velocity: float, friction_error: float, bristle: float):
    """The K_sigma adapter with fixed inputs: the Dahl observer's z_hat held at ``bristle`` (its sliding steady
    state), v and eps_hat_F constant; returns it, its context and a function advancing n periods to the
    branches."""
    adapter = KSigmaAdapter(params, period=PERIOD, sigma0=SIGMA0)
    context = adapter.CreateDefaultContext()
    adapter.GetInputPort("arm_velocity_estimate_rad_per_s").FixValue(context, [velocity])
    adapter.GetInputPort("bristle_state_rad").FixValue(context, [bristle])
    adapter.GetInputPort("friction_error_estimate_Nm").FixValue(context, [0.0, friction_error])

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
    adapter, context, advance = k_sigma_adapter(params, velocity=v, friction_error=error, bristle=z_hat)
    branches = advance(200)
    expected = 1.0 - 5000.0 * error * SIGMA0 * z_hat * 200 * PERIOD
    assert np.sign(branches[branch] - 1.0) == direction
    assert branches[branch] == pytest.approx(expected, rel=1e-9)
    assert branches[1 - branch] == 1.0
    assert adapter.GetOutputPort("K_sigma").Eval(context)[0] == branches[branch]  # the gain of v's sign


def test_frozen_below_the_velocity_threshold():
    params = KSigmaAdaptationParameters(velocity_threshold=0.1)
    for v in (0.05, -0.1):
        _, _, advance = k_sigma_adapter(params, velocity=v, friction_error=-0.004, bristle=math.copysign(8e-4, v))
        np.testing.assert_array_equal(advance(300), [1.0, 1.0])


def test_frozen_before_the_enable_time_and_adapting_after():
    """Enabled at t = 0.1 s: K_sigma+ is 1 for the first 100 periods, then moves at Eq. 18's rate."""
    params = KSigmaAdaptationParameters(gamma=5000.0, enable_time=0.1)
    z_hat = 0.008 / SIGMA0
    _, _, advance = k_sigma_adapter(params, velocity=0.5, friction_error=-0.004, bristle=z_hat)
    np.testing.assert_array_equal(advance(100), [1.0, 1.0])
    rate = -5000.0 * -0.004 * SIGMA0 * z_hat
    assert advance(50)[0] == pytest.approx(1.0 + rate * 50 * PERIOD, rel=1e-9)


@pytest.mark.parametrize("v, branch", [(0.3, 0), (-0.3, 1)])
def test_the_estimate_uses_the_k_sigma_of_the_velocity_sign(v, branch):
    """F_hat = -K_sigma sigma0 z_hat (Eq. 16) with K_sigma+ while v > 0 and K_sigma- otherwise: the adapter's
    branches [1.3, 1.8] through its K_sigma output into the Dahl observer, wired as the diagram wires them."""
    dahl = DahlObserverParameters(
        coulomb_pos=0.012,
        coulomb_neg=0.012,
        sigma0=SIGMA0,
        adaptation=DahlAdaptation(k_sigma=KSigmaAdaptationParameters()),
    )
    diagram, observer, adapter = adapting_dahl_observer(dahl, period=PERIOD)
    context = diagram.CreateDefaultContext()
    diagram.GetInputPort("arm_velocity_estimate_rad_per_s").FixValue(context, [v])
    diagram.GetInputPort("measured_angles_rad").FixValue(context, [0.0, 0.0])
    z_hat = math.copysign(0.012, v) / SIGMA0
    observer.GetMyMutableContextFromRoot(context).SetDiscreteState([z_hat])
    adapter.GetMyMutableContextFromRoot(context).SetDiscreteState([1.3, 1.8])
    assert diagram.GetOutputPort("friction_estimate_Nm").Eval(context)[0] == -[1.3, 1.8][branch] * SIGMA0 * z_hat


@pytest.mark.parametrize("v, level", [(0.5, 0.012), (-0.5, 0.018)])
def test_adaptation_with_a_dahl_observer_converges_to_the_true_gain(v, level):
    """A Dahl observer adapting K_sigma and a 'true' Dahl friction K_true = 1.7 times larger on the same v (a
    Dahl observer with K_sigma held at 1.7: gamma = 0): eps_hat_F = F - F_hat = -(K_true - K) sigma0 z_hat, so
    Eq. 18 is dK/dt = -gamma (sigma0 z_hat)^2 (K - K_true), and z_hat = z_ss (1 - exp(-r t)) (Eq. 8,
    r = sigma0 |v| / Fc): K - K_true = (1 - K_true) exp(-gamma Fc^2 int_0^t (1 - e^(-r s))^2 ds), about
    exp(-gamma Fc^2 t) once the bristle has settled. gamma = 40000 / ((N m)^2 s): rate a = gamma Fc^2 = 5.8
    (Fc = 0.012) or 13 (0.018) 1/s. Tolerance 5 %: the explicit Euler step, (1 - a h)^n against exp(-a n h),
    drifts by n (a h)^2 / 2 <= 3.4 %."""
    k_true, gamma, duration = 1.7, 40000.0, 0.4
    builder = DiagramBuilder()
    velocity = builder.AddSystem(ConstantVectorSource([v]))
    angles = builder.AddSystem(ConstantVectorSource([0.0, 0.0]))
    reference = builder.AddSystem(ConstantVectorSource([0.0, v]))  # no tracking error: K_z = 0
    truth, observer = (
        builder.AddSystem(
            adapting_dahl_observer(
                DahlObserverParameters(
                    coulomb_pos=0.012, coulomb_neg=0.018, sigma0=SIGMA0, adaptation=DahlAdaptation(k_sigma=law)
                ),
                period=PERIOD,
            )[0]
        )
        for law in (KSigmaAdaptationParameters(gamma=0.0, initial=k_true), KSigmaAdaptationParameters(gamma=gamma))
    )
    negate = builder.AddSystem(Gain(-1.0, 1))
    error = builder.AddSystem(Adder(2, 1))
    no_error = builder.AddSystem(ConstantVectorSource([0.0, 0.0]))
    no_pendulum_error = builder.AddSystem(ConstantVectorSource([0.0]))
    errors = builder.AddSystem(Multiplexer([1, 1]))
    for dahl in (observer, truth):
        builder.Connect(velocity.get_output_port(), dahl.GetInputPort("arm_velocity_estimate_rad_per_s"))
        builder.Connect(angles.get_output_port(), dahl.GetInputPort("measured_angles_rad"))
        builder.Connect(reference.get_output_port(), dahl.GetInputPort("arm_reference_rad"))
    builder.Connect(no_error.get_output_port(), truth.GetInputPort("friction_error_estimate_Nm"))
    builder.Connect(truth.GetOutputPort("friction_estimate_Nm"), error.get_input_port(0))
    builder.Connect(observer.GetOutputPort("friction_estimate_Nm"), negate.get_input_port())
    builder.Connect(negate.get_output_port(), error.get_input_port(1))
    builder.Connect(no_pendulum_error.get_output_port(), errors.get_input_port(0))
    builder.Connect(error.get_output_port(), errors.get_input_port(1))
    builder.Connect(errors.get_output_port(), observer.GetInputPort("friction_error_estimate_Nm"))
    log = LogVectorOutput(observer.GetOutputPort("K_sigma_branches"), builder, PERIOD)
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


@pytest.mark.parametrize(
    "field, value",
    [
        ("gamma", -1.0),
        ("velocity_threshold", -0.1),
        ("enable_time", -1.0),
        ("initial", 0.0),
        ("gamma", float("nan")),
    ],
)
def test_invalid_parameters_are_rejected_naming_the_field(field, value):
    adaptation = DahlAdaptation(k_sigma=KSigmaAdaptationParameters(**{field: value}))
    with pytest.raises(ConfigError, match=rf"observers\.dahl\.adaptation\.k_sigma\.{field}"):
        DahlFrictionObserver(DahlObserverParameters(adaptation=adaptation), period=PERIOD)


@pytest.mark.parametrize(
    "adaptation",
    [
        DahlAdaptation(),
        DahlAdaptation(k_sigma=KSigmaAdaptationParameters(), parameters=ParameterAdaptationParameters()),
    ],
    ids=["neither law", "both laws"],
)
def test_adaptation_section_takes_exactly_one_law(adaptation):
    with pytest.raises(ConfigError, match=r"observers\.dahl\.adaptation must give exactly one"):
        DahlObserverParameters(adaptation=adaptation).validate()


def test_only_the_arm_observer_adapts_and_the_parameter_law_needs_a_dahl_model():
    k_sigma = DahlAdaptation(k_sigma=KSigmaAdaptationParameters())
    pendulum = DahlObserverParameters(rho=None, adaptation=k_sigma)
    with pytest.raises(ConfigError, match=r"observers\.pendulum_friction\.adaptation must be null"):
        ObserverConfig(pendulum_friction=pendulum).validate()
    with pytest.raises(ConfigError, match="only the arm's observer adapts"):
        DahlFrictionObserver(pendulum, period=PERIOD, joint="pendulum")
    lugre = DahlObserverParameters(sigma1=0.1, adaptation=DahlAdaptation(parameters=ParameterAdaptationParameters()))
    with pytest.raises(ConfigError, match=r"observers\.dahl\.adaptation\.parameters adapts a Dahl model"):
        lugre.validate()
