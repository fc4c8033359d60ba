"""Dahl friction observer (paper Eq. 8-9, 16): the closed-form solution of the Dahl equation at constant
velocity, the K_z injection's steady state and sign, stability of the exact step at stiff settings."""

import dataclasses
import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.errors import ConfigError
from furuta_drake.observers.dahl import DahlAdaptation, DahlFrictionObserver, DahlObserverParameters
from furuta_drake.observers.k_sigma import KSigmaAdaptationParameters

PERIOD = 1e-3


def stepper(
    params: DahlObserverParameters,
    *,
    velocity: float,
    phi: float = 0.0,
    reference=None,
    k_sigma: float | None = None,
    z0: float = 0.0,
):
    """The observer with fixed inputs; returns a function advancing n periods and returning (z_hat, F_hat).
    ``reference``: [phi_ref, v_ref] (None: the upright's zero); ``k_sigma``: the observer's K_sigma input held at
    that value (an adapting observer); None: no adaptation (K_sigma = 1)."""
    if k_sigma is not None:
        params = dataclasses.replace(params, adaptation=DahlAdaptation(k_sigma=KSigmaAdaptationParameters()))
    system = DahlFrictionObserver(params, period=PERIOD)
    context = system.CreateDefaultContext()
    system.GetInputPort("arm_velocity_estimate_rad_per_s").FixValue(context, [velocity])
    system.GetInputPort("measured_angles_rad").FixValue(context, [0.0, phi])
    system.GetInputPort("arm_reference_rad").FixValue(context, list(reference or (0.0, 0.0)))
    if k_sigma is not None:
        system.GetInputPort("K_sigma").FixValue(context, [k_sigma])
    context.SetDiscreteState([z0])

    def advance(steps: int):
        for _ in range(steps):
            context.SetDiscreteState(system.EvalUniquePeriodicDiscreteUpdate(context).value())
        return (
            system.GetOutputPort("bristle_state_rad").Eval(context)[0],
            system.GetOutputPort("friction_estimate_Nm").Eval(context)[0],
        )

    return advance


@settings(max_examples=25, deadline=None)
@given(speed=st.floats(0.1, 10.0), positive=st.booleans(), sigma0=st.floats(5.0, 1000.0), k_sigma=st.floats(0.5, 3.0))
def test_constant_velocity_follows_the_dahl_solution_and_settles_to_minus_k_sigma_fc(speed, positive, sigma0, k_sigma):
    """With no tracking error (phi = phi_ref, v = v_ref, so K_z = 0) Eq. 8 at constant v is linear:
    z(t) = z_ss (1 - exp(-sigma0 |v| t / Fc)), z_ss = Fc sign(v) / sigma0, so F_hat = -K_sigma sigma0 z tends to
    -K_sigma Fc sign(v), with the level of v's direction (0.012 N m for v > 0, 0.018 for v < 0)."""
    params = DahlObserverParameters(coulomb_pos=0.012, coulomb_neg=0.018, sigma0=sigma0)
    v = speed if positive else -speed
    level = 0.012 if positive else 0.018
    advance = stepper(params, velocity=v, reference=(0.0, v), k_sigma=k_sigma)
    rate = sigma0 * speed / level
    z_ss = math.copysign(level, v) / sigma0
    elapsed = 0
    for steps in (1, 9, 90):
        z, _ = advance(steps)
        elapsed += steps
        assert z == pytest.approx(z_ss * -math.expm1(-rate * elapsed * PERIOD), rel=1e-9, abs=1e-15)
    z, friction = advance(math.ceil(40.0 / (rate * PERIOD)))  # 40 time constants: settled to e^-40
    assert friction == pytest.approx(-k_sigma * math.copysign(level, v), rel=1e-9)


def test_zero_velocity_holds_the_state():
    """v = 0 and no tracking error: dz/dt = 0, z_hat and F_hat hold (a Dahl element at rest keeps its force)."""
    params = DahlObserverParameters()
    advance = stepper(params, velocity=0.0, z0=0.0009)
    z, friction = advance(500)
    assert z == 0.0009
    assert friction == pytest.approx(-params.sigma0 * 0.0009)


def test_without_adaptation_k_sigma_is_one_and_k_sigma_scales_only_the_output():
    params = DahlObserverParameters()
    _, unit = stepper(params, velocity=0.3, reference=(0.0, 0.3))(50)
    z, scaled = stepper(params, velocity=0.3, reference=(0.0, 0.3), k_sigma=1.6)(50)
    assert scaled == pytest.approx(1.6 * unit)
    assert unit == pytest.approx(-params.sigma0 * z)


def test_position_error_at_rest_ramps_the_estimate_so_compensation_pushes_back():
    """v = 0, eps_phi = phi - phi_ref = 0.02 rad: Eq. 8-9 reduce to dz/dt = K_z = -(sigma0/rho) eps_phi, so F_hat
    grows at K_sigma sigma0^2 eps_phi / rho; a controller u = u_LQ - F_hat then pushes the arm back to phi_ref."""
    params = DahlObserverParameters(sigma0=10.0, rho=100.0)
    z, friction = stepper(params, velocity=0.0, phi=0.05, reference=(0.03, 0.0), k_sigma=1.5)(1000)
    assert friction == pytest.approx(1.5 * 10.0**2 * 0.02 / 100.0 * 1.0, rel=1e-9)  # after 1 s
    assert friction > 0


@pytest.mark.parametrize("sigma1_sign", [1, -1])
@pytest.mark.parametrize("v", [0.4, -0.7])
def test_sliding_steady_state_includes_the_injection(sigma1_sign, v):
    """Constant v with constant tracking errors: setting dz/dt = 0 in Eq. 8 gives
    z_ss = Fc (v + K_z) / (sigma0 |v|), K_z = -(sigma0/rho) (1 + s1 sigma1 |v| / Fc) (eps_phi + rho2 eps_v)."""
    params = DahlObserverParameters(sigma0=10.0, sigma1=0.01, sigma1_sign=sigma1_sign, rho=50.0, rho2=0.2)
    level = params.coulomb_pos if v > 0 else params.coulomb_neg
    eps_phi, v_ref = 0.03, 0.1
    k_z = -(10.0 / 50.0) * (1 + sigma1_sign * 0.01 * abs(v) / level) * (eps_phi + 0.2 * (v - v_ref))
    z, _ = stepper(params, velocity=v, phi=eps_phi, reference=(0.0, v_ref))(2000)
    assert z == pytest.approx(level * (v + k_z) / (10.0 * abs(v)), rel=1e-9)


def test_exact_step_is_stable_and_monotone_at_stiff_settings():
    """sigma0 = 1000 N m/rad at 5 rad/s with Fc = 0.012 N m: the Dahl rate sigma0 |v| / Fc = 4.2e5 1/s, 417
    times the sampling rate (an explicit Euler step would diverge beyond 2). The exact step lands on the steady
    state -Fc without overshoot and stays there."""
    params = DahlObserverParameters(sigma0=1000.0, coulomb_pos=0.012)
    advance = stepper(params, velocity=5.0, reference=(0.0, 5.0))
    estimates = [advance(1)[1] for _ in range(20)]
    np.testing.assert_allclose(estimates, -0.012, rtol=1e-12)


@pytest.mark.parametrize(
    "field, value",
    [
        ("coulomb_pos", 0.0),
        ("coulomb_neg", -0.01),
        ("sigma0", 0.0),
        ("sigma0", float("nan")),
        ("rho", 0.0),
        ("sigma1", -1.0),
        ("rho2", -0.1),
        ("sigma1_sign", 0),
        ("period", 0.0),
    ],
)
def test_invalid_parameters_are_rejected_naming_the_field(field, value):
    with pytest.raises(ConfigError, match=rf"observers\.dahl\.{field}"):
        DahlFrictionObserver(DahlObserverParameters(**{field: value}), period=PERIOD)
