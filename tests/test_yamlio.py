"""The strict YAML loader: errors name file, line and key; round trips are exact."""

import dataclasses
import math
import re

import pytest
import yaml
from conftest import QUBE_DATA
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.config import SimulationConfig
from furuta_drake.errors import ConfigError
from furuta_drake.rig import MotorParameters, RigParameters
from furuta_drake.yamlio import dump_yaml_dataclass, load_yaml_dataclass, loads_yaml_dataclass, locate, locate_in_file

QUBE_RIG = QUBE_DATA / "rig.yaml"
REQUIRED = [f.name for f in dataclasses.fields(RigParameters) if f.metadata.get("required")]


def with_required(text: str) -> str:
    """``text`` followed by the Lund rig's value of every required key it does not set (its line numbers kept)."""
    lund = RigParameters()
    return text + "".join(
        f"{name}: {getattr(lund, name)}\n" for name in REQUIRED if not re.search(rf"^{name}:", text, re.MULTILINE)
    )


def test_misspelt_key_names_file_line_and_key(tmp_path):
    path = tmp_path / "rig.yaml"
    path.write_text("arm_inertia: 1.0e-3\narm_lenght: 0.25\n")
    with pytest.raises(ConfigError, match=r"rig\.yaml:2: arm_lenght unknown key 'arm_lenght'"):
        load_yaml_dataclass(path, RigParameters)


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("arm_inertia: abc\n", ":1: arm_inertia expected a number"),
        ("counts_per_rev: 10.5\n", ":1: counts_per_rev expected an integer"),
        ("counts_per_rev: .inf\n", ":1: counts_per_rev expected an integer, got inf"),
        ("sample_period: '1e-3'\n", ":1: sample_period expected a number, got '1e-3'"),
        ("motor: 3\n", ":1: motor expected a mapping"),
        ("arm_inertia: .nan\n", "must be finite"),
        ("arm_inertia: [1, 2\n", "not valid YAML"),
        ("pendulum_mass: -0.1\n", "pendulum_mass must be a positive"),
        ("theta_direction: 2\n", "theta_direction must be 1 or -1"),
        ("arm_inertia: 1\narm_inertia: 2\n", "duplicate key"),
    ],
)
def test_bad_values_are_named(text, fragment):
    with pytest.raises(ConfigError, match=fragment.replace(".", r"\.").replace("[", r"\[")):
        loads_yaml_dataclass(with_required(text), RigParameters, source="rig.yaml")


def test_exponent_without_a_dot_is_a_number_as_in_yaml_1_2():
    rig = loads_yaml_dataclass(
        with_required("sample_period: 1e-3\ncounts_per_rev: 4e3\narm_inertia: +2E-3\n"), RigParameters
    )
    assert (rig.sample_period, rig.counts_per_rev, rig.arm_inertia) == (0.001, 4000, 0.002)


def test_empty_file_and_directory_are_refused(tmp_path):
    empty = tmp_path / "empty.yaml"
    empty.write_text("")
    with pytest.raises(ConfigError, match="empty YAML"):
        load_yaml_dataclass(empty, RigParameters)
    with pytest.raises(ConfigError, match="is a directory"):
        load_yaml_dataclass(tmp_path, RigParameters)


def test_the_shipped_qube_rig_file_loads():
    rig = load_yaml_dataclass(QUBE_RIG, RigParameters)
    assert rig.theta_direction == -1
    assert rig.motor == MotorParameters(8.4, 0.042, 0.042)
    assert rig.counts_per_rev == 2048


positive = st.floats(min_value=1e-6, max_value=1e3, allow_nan=False, allow_infinity=False)


@settings(max_examples=25, deadline=None)
@given(
    arm_inertia=positive,
    pendulum_mass=positive,
    counts=st.integers(4, 1 << 20),
    direction=st.sampled_from([1, -1]),
    coulomb=st.floats(0, 1),
    with_motor=st.booleans(),
)
def test_round_trip_is_exact(arm_inertia, pendulum_mass, counts, direction, coulomb, with_motor):
    rig = RigParameters(
        arm_inertia=arm_inertia,
        pendulum_mass=pendulum_mass,
        counts_per_rev=counts,
        theta_direction=direction,
        arm_coulomb=coulomb,
        motor=MotorParameters() if with_motor else None,
    )
    back = loads_yaml_dataclass(dump_yaml_dataclass(rig), RigParameters)
    assert back == rig
    assert math.isclose(back.arm_inertia, arm_inertia, rel_tol=0, abs_tol=0)


def test_validation_errors_name_the_line_of_their_key_without_a_root_prefix(tmp_path):
    path = tmp_path / "rig.yaml"
    motor = "motor:\n  resistance: 8.4\n  torque_constant: -0.04\n  backemf_constant: 0.04\n"
    path.write_text(with_required("arm_inertia: 1.0e-3\n# the pendulum\npendulum_mass: -0.1\n" + motor))
    with pytest.raises(ConfigError) as err:
        load_yaml_dataclass(path, RigParameters)
    assert str(err.value) == f"{path}:3: pendulum_mass must be a positive finite number, got -0.1"
    path.write_text(with_required(motor))
    with pytest.raises(ConfigError, match=r"rig\.yaml:3: motor\.torque_constant must be a positive"):
        load_yaml_dataclass(path, RigParameters)


def test_a_list_item_and_a_key_left_at_its_default_are_located():
    text = (
        "controller:\n  velocity_source: vfe\nobservers:\n  vfe:\n    eigenvalues:\n      - -20.0\n      - -23.0\n"
        "      - 26.0\n      - -29.0\n      - -32.0\n      - -35.0\n"
    )
    with pytest.raises(ConfigError, match=r"^sim\.yaml:8: observers\.vfe\.eigenvalues\[2\] must be a negative real"):
        loads_yaml_dataclass(text, SimulationConfig, source="sim.yaml")
    # open_loop needs an excitation the file does not give: the error is at the key that asks for it.
    with pytest.raises(ConfigError, match=r"^sim\.yaml:2: controller\.mode 'open_loop' needs an excitation"):
        loads_yaml_dataclass("duration: 1.0\ncontroller: {mode: open_loop}\n", SimulationConfig, source="sim.yaml")


def test_an_error_found_after_loading_is_located_in_its_file(tmp_path):
    path = tmp_path / "sim.yaml"
    path.write_text("duration: 1.0\ncontroller:\n  gain: [0, 0, 0, 0]\n")
    located = locate_in_file(path, ConfigError("controller.gain [0.0, 0.0, 0.0, 0.0] does not stabilise"))
    assert str(located) == f"{path}:3: controller.gain [0.0, 0.0, 0.0, 0.0] does not stabilise"
    # A prefix of a longer key is not that key.
    assert locate("controller_gain is odd", "f.yaml", {"controller": 2}) == "f.yaml: controller_gain is odd"


FIELD_NAMES = sorted(
    {f.name for tp in (SimulationConfig, RigParameters, MotorParameters) for f in dataclasses.fields(tp)}
    | {"hg", "vfe", "lqr", "arm", "eigenvalues", "gain"}
)
yaml_scalars = st.one_of(
    st.none(),
    st.booleans(),
    st.integers(-(10**6), 10**6),
    st.floats(allow_nan=True),
    st.text(max_size=8),
    st.sampled_from(["lqr", "vfe", "hg", "dahl", "open_loop", ".nan"]),
)
yaml_trees = st.recursive(
    yaml_scalars,
    lambda children: st.one_of(
        st.lists(children, max_size=5), st.dictionaries(st.sampled_from(FIELD_NAMES), children, max_size=5)
    ),
    max_leaves=12,
)


@settings(max_examples=25, deadline=None)
@given(
    tree=st.dictionaries(st.sampled_from(FIELD_NAMES), yaml_trees, max_size=6),
    schema=st.sampled_from([SimulationConfig, RigParameters]),
)
def test_any_yaml_tree_loads_or_raises_config_error(tree, schema):
    text = yaml.safe_dump(tree)
    try:
        loaded = loads_yaml_dataclass(text, schema, source="f.yaml")
    except ConfigError as err:
        assert str(err).startswith("f.yaml")
    else:
        assert isinstance(loaded, schema)


@settings(max_examples=25, deadline=None)
@given(text=st.text(alphabet=st.sampled_from(list("abc_:-[]{},.#&*!|>'\"%@` \n\t0123456789")), max_size=80))
def test_any_text_loads_or_raises_config_error(text):
    try:
        loads_yaml_dataclass(text, SimulationConfig, source="f.yaml")
    except ConfigError as err:
        assert str(err).startswith("f.yaml")
