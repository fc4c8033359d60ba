"""The strict YAML loader: errors name file, line and key; round trips are exact."""

import math

import pytest
from hypothesis import given, settings, strategies as st

from furuta_drake.errors import ConfigError
from furuta_drake.rig import MotorParameters, RigParameters
from conftest import QUBE_DATA
from furuta_drake.yamlio import dump_yaml_dataclass, load_yaml_dataclass, loads_yaml_dataclass

SHARED_RIG = QUBE_DATA / "rig.yaml"


def test_misspelt_key_names_file_line_and_key(tmp_path):
    path = tmp_path / "rig.yaml"
    path.write_text("arm_inertia: 1.0e-3\narm_lenght: 0.25\n")
    with pytest.raises(ConfigError, match=r"rig\.yaml:2: arm_lenght unknown key 'arm_lenght'"):
        load_yaml_dataclass(path, RigParameters)


@pytest.mark.parametrize("text, fragment", [
    ("arm_inertia: abc\n", ":1: arm_inertia expected a number"),
    ("counts_per_rev: 10.5\n", ":1: counts_per_rev expected an integer"),
    ("motor: 3\n", ":1: motor expected a mapping"),
    ("arm_inertia: .nan\n", "must be finite"),
    ("arm_inertia: [1, 2\n", "not valid YAML"),
    ("pendulum_mass: -0.1\n", "pendulum_mass must be a positive"),
    ("theta_direction: 2\n", "theta_direction must be 1 or -1"),
    ("arm_inertia: 1\narm_inertia: 2\n", "duplicate key"),
])
def test_bad_values_are_named(text, fragment):
    with pytest.raises(ConfigError, match=fragment.replace(".", r"\.").replace("[", r"\[")):
        loads_yaml_dataclass(text, RigParameters, source="rig.yaml")


def test_empty_file_and_directory_are_refused(tmp_path):
    empty = tmp_path / "empty.yaml"
    empty.write_text("")
    with pytest.raises(ConfigError, match="empty YAML"):
        load_yaml_dataclass(empty, RigParameters)
    with pytest.raises(ConfigError, match="is a directory"):
        load_yaml_dataclass(tmp_path, RigParameters)


def test_the_shared_qube_rig_file_loads():
    rig = load_yaml_dataclass(SHARED_RIG, RigParameters)
    assert rig.theta_direction == -1
    assert rig.motor == MotorParameters(8.4, 0.042, 0.042)
    assert rig.counts_per_rev == 2048


positive = st.floats(min_value=1e-6, max_value=1e3, allow_nan=False, allow_infinity=False)


@settings(max_examples=25, deadline=None)
@given(arm_inertia=positive, pendulum_mass=positive, counts=st.integers(4, 1 << 20), direction=st.sampled_from([1, -1]),
       coulomb=st.floats(0, 1), with_motor=st.booleans())
def test_round_trip_is_exact(arm_inertia, pendulum_mass, counts, direction, coulomb, with_motor):
    rig = RigParameters(arm_inertia=arm_inertia, pendulum_mass=pendulum_mass, counts_per_rev=counts,
                        theta_direction=direction, arm_coulomb=coulomb,
                        motor=MotorParameters() if with_motor else None)
    back = loads_yaml_dataclass(dump_yaml_dataclass(rig), RigParameters)
    assert back == rig
    assert math.isclose(back.arm_inertia, arm_inertia, rel_tol=0, abs_tol=0)
