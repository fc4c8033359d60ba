"""The torque beyond the vocabulary: its expressions against numpy's formulas, the refused tokens, and the Drake
system against the plant's mass matrix (the generalised force a torque gives, the acceleration it causes)."""

import math
import re
import warnings

import numpy as np
import pytest
from hypothesis import example, given, settings
from hypothesis import strategies as st
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from furuta_drake.actuator import UnmodelledTorque
from furuta_drake.errors import ConfigError, SimulationDiverged
from furuta_drake.plant import joint_indices, make_furuta_plant
from furuta_drake.rig import lund_rig, qube_servo2_rig
from furuta_drake.unmodelled import UnmodelledTorqueParameters, compile_torque
from furuta_drake.world import add_furuta_world

angles = st.floats(-10.0, 10.0)
speeds = st.floats(-50.0, 50.0)


@settings(max_examples=50, deadline=None)
@given(theta=angles, phi=angles, theta_dot=speeds, phi_dot=speeds)
def test_every_function_and_operator_gives_the_formulas_value(theta, phi, theta_dot, phi_dot):
    expression = (
        "0.002*sin(7*phi) - 1e-3*cos(theta)**2 + tanh(phi_dot/0.1)*abs(theta_dot)/(1 + exp(-theta))"
        " + sign(phi_dot)*sqrt(abs(phi)) + 2*pi*log(1 + theta**2) - tan(theta/100) + -(+phi)"
    )
    expected = (
        0.002 * math.sin(7 * phi)
        - 1e-3 * math.cos(theta) ** 2
        + math.tanh(phi_dot / 0.1) * abs(theta_dot) / (1 + math.exp(-theta))
        + ((phi_dot > 0) - (phi_dot < 0)) * math.sqrt(abs(phi))
        + 2 * math.pi * math.log(1 + theta**2)
        - math.tan(theta / 100)
        - phi
    )
    assert float(compile_torque(expression, "t")(theta, phi, theta_dot, phi_dot)) == pytest.approx(expected, rel=1e-12)


@settings(max_examples=25, deadline=None)
@given(st.lists(st.tuples(angles, angles, speeds, speeds), min_size=1, max_size=20))
def test_arrays_give_the_torque_of_each_state(states):
    torque = compile_torque("0.002*sin(7*phi) + 1e-4*theta_dot*cos(phi) - 3e-4*sign(phi_dot)", "t")
    x = np.array(states)
    vectorised = torque(*x.T)
    assert vectorised.shape == (len(states),)
    assert vectorised == pytest.approx([float(torque(*row)) for row in states], rel=0, abs=0)
    # A constant expression is broadcast over the states too.
    assert compile_torque("-2.5e-3", "t")(*x.T) == pytest.approx(np.full(len(states), -2.5e-3))


def test_a_value_outside_a_functions_domain_is_nan_or_inf_for_the_user_to_detect():
    torque = compile_torque("log(phi) + 1/theta", "t")
    assert np.isnan(torque(1.0, -1.0, 0.0, 0.0)) and np.isinf(torque(0.0, 1.0, 0.0, 0.0))
    assert np.isinf(compile_torque("10.0**400", "t")(0.0, 0.0, 0.0, 0.0))


@pytest.mark.parametrize(
    "expression, token",
    [
        ("__import__('os').system('ls')", "__import__"),
        ("0.002*sin(7*psi)", "'psi'"),
        ("open('/etc/passwd').read()", "open"),
        ("np.sin(phi)", "'np.sin'"),
        ("phi.real", "'phi.real'"),
        ("[phi][0]", "[phi][0]"),
        ("(lambda: phi)()", "lambda"),
        ("'phi'", "'phi'"),
        ("phi if theta else 0", "phi if theta else 0"),
        ("phi % 2", "Mod"),
        ("True*phi", "'True'"),
        ("1j*phi", "'1j'"),
        ("1e400*phi", "'1e400' is not a finite float"),
        ("1" + "0" * 400 + "*phi", "is not a finite float"),
        ("sin(phi, 2)", "sin takes one argument"),
        ("sin(x=phi)", "sin takes one argument"),
        ("sin", "'sin'"),
        ("pi(2)", "'pi'"),
        ("phi_dot > 0", "phi_dot > 0"),
        ("0.002*sin(7*phi", "not a valid expression"),
        ("", "expected a torque expression"),
    ],
)
def test_anything_else_is_refused_naming_the_key_and_the_token(expression, token):
    with pytest.raises(ConfigError) as err:
        compile_torque(expression, "unmodelled_torque.arm")
    assert str(err.value).startswith("unmodelled_torque.arm:") and token in str(err.value)


def test_the_parameters_name_the_joint_whose_expression_is_bad():
    UnmodelledTorqueParameters().validate()
    UnmodelledTorqueParameters(arm="0.002*sin(7*phi)", pendulum="-1e-4*theta_dot").validate()
    with pytest.raises(ConfigError, match=r"^rig\.unmodelled_torque\.pendulum: 'x'"):
        UnmodelledTorqueParameters(arm="phi", pendulum="x").validate("rig.unmodelled_torque")
    with pytest.raises(ConfigError, match=r"^unmodelled_torque\.arm must be an expression"):
        UnmodelledTorqueParameters(arm=0.002).validate()
    assert UnmodelledTorqueParameters(arm=" ").is_empty and not UnmodelledTorqueParameters(arm=0.002).is_empty


def torque_system(params, rig=None):
    """The system on a plant of ``rig``, with a fixable state input; returns (system, context, plant)."""
    plant = make_furuta_plant(rig or lund_rig())
    system = UnmodelledTorque(plant, params)
    return system, system.CreateDefaultContext(), plant


@pytest.mark.parametrize("phi", [0.0, 0.1, -0.7, 2.0])
def test_a_cogging_expression_gives_its_torque_on_the_arm_joint_alone(phi):
    system, context, plant = torque_system(UnmodelledTorqueParameters(arm="0.002*sin(7*phi)"))
    theta_v, phi_v = joint_indices(plant)
    system.get_input_port().FixValue(context, [0.3, phi, -1.0, 2.0])
    force = system.GetOutputPort("generalized_force_Nm").Eval(context)
    assert force[phi_v] == pytest.approx(0.002 * math.sin(7 * phi), abs=1e-15)
    assert force[theta_v] == 0.0


def test_a_pendulum_expression_reads_the_paper_order_state():
    system, context, plant = torque_system(UnmodelledTorqueParameters(pendulum="-3e-4*theta_dot + 1e-3*theta"))
    theta_v, phi_v = joint_indices(plant)
    system.get_input_port().FixValue(context, [0.2, 5.0, -4.0, 7.0])
    force = system.GetOutputPort("generalized_force_Nm").Eval(context)
    assert force[theta_v] == pytest.approx(-3e-4 * -4.0 + 1e-3 * 0.2) and force[phi_v] == 0.0


def test_a_non_finite_torque_is_a_diverged_simulation_naming_the_key_and_the_state():
    system, context, _ = torque_system(UnmodelledTorqueParameters(arm="log(phi)"))
    system.get_input_port().FixValue(context, [0.0, -0.5, 0.0, 0.0])
    with pytest.raises(SimulationDiverged, match=r"unmodelled_torque\.arm gave a non-finite torque .* phi = -0\.5"):
        system.get_output_port().Eval(context)


@pytest.mark.parametrize("rig", [lund_rig(), qube_servo2_rig()], ids=["lund", "qube"])
def test_a_constant_torque_accelerates_the_world_as_the_mass_matrix_says(rig):
    """From rest upright (no gravity torque, no Coriolis), tau = M(0) a with the mass matrix of paper Eq. 1 at
    theta = 0: [[J_p + m l^2, m l r], [m l r, J_arm + m r^2]] in q = [theta, phi]."""
    tau = np.array([-4e-4, 2e-3])  # [pendulum, arm] [N m]
    builder = DiagramBuilder()
    world = add_furuta_world(
        builder,
        rig=rig,
        control_period=rig.sample_period,
        back_emf_damping=0.0,
        unmodelled_torque=UnmodelledTorqueParameters(arm=repr(float(tau[1])), pendulum=repr(float(tau[0]))),
    )
    builder.ExportInput(world.arm_torque_input)
    diagram = builder.Build()
    simulator = Simulator(diagram)
    context = simulator.get_mutable_context()
    diagram.get_input_port().FixValue(context, [0.0])
    M = np.array([[rig.pendulum_inertia_total, rig.coupling], [rig.coupling, rig.arm_inertia_total]])
    expected = np.linalg.solve(M, tau)  # [theta_ddot, phi_ddot]
    P = world.to_paper
    derivatives = diagram.EvalTimeDerivatives(context).CopyToVector()
    assert (P @ derivatives)[2:] == pytest.approx(expected, rel=1e-9)
    # Integrated for 2 ms: v = a t while the pendulum's gravity torque m g l theta ~ m g l a t^2 / 2 stays small.
    t = 2e-3
    simulator.AdvanceTo(t)
    state = P @ world.plant.GetPositionsAndVelocities(world.plant.GetMyContextFromRoot(context))
    assert state[2:] == pytest.approx(expected * t, rel=1e-3)
    assert state[:2] == pytest.approx(expected * t**2 / 2, rel=1e-3)


@settings(max_examples=200, deadline=None)
@given(
    st.text(
        alphabet=st.sampled_from(list("thetaphi_dotsincoxgqr()[]{}.,:;'\"=<>!%&|^~@#$ +-*/0123456789e\n")), max_size=40
    )
)
@example("1if 1 else 2")  # parses with a SyntaxWarning on stderr
def test_any_text_compiles_to_a_torque_or_is_refused_with_a_config_error(text):
    """A compiled torque, or one ConfigError line and nothing else on stderr (no warning either)."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            torque = compile_torque(text, "unmodelled_torque.arm")
        except ConfigError as err:
            assert str(err).startswith("unmodelled_torque.arm")
            torque = None
    assert not caught, [str(w.message) for w in caught]
    if torque is None:
        return
    value = torque(np.array([0.0, 0.3]), 1.5, -2.0, 0.0)  # never an exception: nan or inf where undefined
    assert value.shape == (2,) and value.dtype == float


leaves = st.sampled_from(["theta", "phi", "theta_dot", "phi_dot", "pi", "2", "0.5", "1e-3"])


def _extend(children):
    binary = st.tuples(children, st.sampled_from(["+", "-", "*", "/", "**"]), children).map(
        lambda t: f"({t[0]} {t[1]} {t[2]})"
    )
    calls = st.tuples(st.sampled_from(["sin", "cos", "tan", "tanh", "exp", "log", "abs", "sign", "sqrt"]), children)
    return binary | calls.map(lambda t: f"{t[0]}({t[1]})") | children.map(lambda c: f"-{c}")


@settings(max_examples=100, deadline=None)
@given(st.recursive(leaves, _extend, max_leaves=12), st.tuples(angles, angles, speeds, speeds))
def test_a_generated_expression_evaluates_as_numpy_does(expression, state):
    """The reference: the same text evaluated by Python over numpy's functions (trusted text, made here)."""
    names = dict(zip(("theta", "phi", "theta_dot", "phi_dot"), map(np.float64, state)))
    names.update({name: getattr(np, name) for name in ("sin", "cos", "tan", "tanh", "exp", "log", "abs", "sign")})
    names.update(sqrt=np.sqrt, pi=np.float64(np.pi))
    numpy_numbers = re.sub(r"(?<![\w.])(\d+(?:\.\d*)?(?:e-?\d+)?)", r"np.float64(\1)", expression)
    with np.errstate(all="ignore"):
        expected = float(eval(numpy_numbers, {"__builtins__": {}, "np": np}, names))
    torque = compile_torque(expression, "t")
    assert float(torque(*state)) == pytest.approx(expected, rel=1e-12, nan_ok=True)
    # The Drake system's per-state path (math on floats, numpy where math raises) agrees, nan and inf included.
    assert torque.at(np.array(state)) == pytest.approx(expected, rel=1e-9, nan_ok=True)


def test_a_sum_of_many_terms_compiles_and_a_deeper_nesting_is_refused():
    terms = [f"1e-4*sin({k}*phi)" for k in range(1, 151)]
    torque = compile_torque(" + ".join(terms), "t")
    assert float(torque(0.0, 0.3, 0.0, 0.0)) == pytest.approx(sum(1e-4 * math.sin(k * 0.3) for k in range(1, 151)))
    with pytest.raises(ConfigError, match=r"^t: expression nested deeper than 200"):
        compile_torque("-" * 250 + "phi", "t")
