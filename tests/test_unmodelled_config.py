"""The unmodelled torque in files: the simulate config's ``unmodelled_torque`` and the rig file's, round trips,
errors naming file, line and key, and simulate running it (a constant arm torque as the expression moves the rig
as the same torque commanded does)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from furuta_drake.cli import main
from furuta_drake.config import ExcitationConfig, SimulationConfig, dump_config, load_config
from furuta_drake.diagnosis.logs import load_rig
from furuta_drake.errors import ConfigError
from furuta_drake.rig import lund_rig
from furuta_drake.simulate import simulate
from furuta_drake.unmodelled import UnmodelledTorqueParameters
from furuta_drake.yamlio import dump_yaml_dataclass, loads_yaml_dataclass

COGGING = UnmodelledTorqueParameters(arm="0.002*sin(7*phi)", pendulum="-1e-4*theta_dot")

coefficients = st.floats(-1.0, 1.0, allow_nan=False).filter(lambda c: c != 0)


@settings(max_examples=25, deadline=None)
@given(a=coefficients, k=st.integers(1, 24), b=coefficients, with_pendulum=st.booleans())
def test_a_config_with_an_unmodelled_torque_round_trips_exactly(a, k, b, with_pendulum):
    torque = UnmodelledTorqueParameters(arm=f"{a!r}*sin({k}*phi)", pendulum=f"{b!r}*theta_dot" if with_pendulum else "")
    config = SimulationConfig.from_rig("qube_servo2", unmodelled_torque=torque)
    back = loads_yaml_dataclass(dump_config(config), SimulationConfig)
    assert back == config and back.unmodelled_torque == torque


def test_a_rig_file_with_an_unmodelled_torque_round_trips_and_its_config_carries_it():
    rig = lund_rig().replace(unmodelled_torque=COGGING)
    assert loads_yaml_dataclass(dump_yaml_dataclass(rig), type(rig)) == rig
    config = SimulationConfig.from_rig(rig)
    assert config.unmodelled_torque == COGGING and config.rig.unmodelled_torque is None
    assert SimulationConfig.from_rig("lund").unmodelled_torque.is_empty


@pytest.mark.parametrize(
    "text, fragment",
    [
        ("unmodelled_torque:\n  arm: 0.002*sin(7*psi)\n", "sim.yaml:2: unmodelled_torque.arm: 'psi' is not allowed"),
        ("unmodelled_torque:\n  arm: ''\n  pendulum: open('x')\n", "sim.yaml:3: unmodelled_torque.pendulum: 'open'"),
        ("unmodelled_torque:\n  arm: 0.002\n", "sim.yaml:2: unmodelled_torque.arm expected a string, got 0.002"),
        ("unmodelled_torque:\n  cogging: sin(phi)\n", "sim.yaml:2: unmodelled_torque.cogging unknown key 'cogging'"),
        (
            "rig:\n  unmodelled_torque: {arm: sin(phi)}\n",
            "rig.unmodelled_torque: in a simulate config, the torque goes",
        ),
    ],
)
def test_a_bad_config_key_is_named_with_its_file_and_line(text, fragment):
    if text.startswith("rig:"):  # the rig section needs its required keys to reach the check
        text = dump_yaml_dataclass(SimulationConfig.from_rig("lund")).replace("  unmodelled_torque: null\n", text[5:])
    with pytest.raises(ConfigError) as err:
        loads_yaml_dataclass(text, SimulationConfig, source="sim.yaml")
    assert fragment in str(err.value)


def test_a_rig_files_bad_expression_is_named_without_the_rig_prefix(tmp_path):
    path = tmp_path / "rig.yaml"
    text = dump_yaml_dataclass(lund_rig()).replace("unmodelled_torque: null", "unmodelled_torque:\n  arm: phi[0]")
    path.write_text(text)
    line = text.splitlines().index("  arm: phi[0]") + 1
    with pytest.raises(ConfigError, match=rf"rig\.yaml:{line}: unmodelled_torque\.arm: 'phi\[0\]' is not allowed"):
        load_rig(path)


def test_the_templates_example_loads_when_uncommented(tmp_path, capsys):
    assert main(["rig", "--template", "qube_servo2"]) == 0
    text = capsys.readouterr().out
    assert "# unmodelled_torque: {arm: " in text and "optional" in text.split("unmodelled_torque")[0][-400:]
    path = tmp_path / "rig.yaml"
    path.write_text(text.replace("# unmodelled_torque:", "unmodelled_torque:"))
    assert load_rig(path).unmodelled_torque == UnmodelledTorqueParameters(
        arm="0.002*sin(7*phi)", pendulum="-1e-4*theta_dot"
    )


def open_loop(command: list[float], unmodelled: UnmodelledTorqueParameters) -> np.ndarray:
    """The true states of a 0.5 s open-loop run of the Lund rig from hanging, given a torque command."""
    config = SimulationConfig.from_rig(
        "lund",
        controller=dataclasses.replace(SimulationConfig().controller, mode="open_loop"),
        excitation=ExcitationConfig(command=command),
        unmodelled_torque=unmodelled,
        initial_state=[3.0, 0.0, 0.0, 0.0],
        duration=0.5,
    )
    config = dataclasses.replace(config, monitor=dataclasses.replace(config.monitor, theta_bound=None))
    return simulate(config).state


def test_a_constant_arm_torque_moves_the_rig_as_the_same_torque_commanded():
    n = 500  # control periods of the 0.5 s run
    commanded = open_loop([0.004] * n, UnmodelledTorqueParameters())
    unmodelled = open_loop([0.0] * n, UnmodelledTorqueParameters(arm="0.004"))
    assert np.abs(commanded[-1, 1]) > 0.1  # the arm has turned
    assert unmodelled == pytest.approx(commanded, abs=1e-6)


def test_simulate_from_a_rig_file_writes_the_torque_into_its_config(tmp_path, capsys):
    rig = tmp_path / "rig.yaml"
    rig.write_text(dump_yaml_dataclass(lund_rig().replace(unmodelled_torque=COGGING)))
    out = tmp_path / "run"
    assert main(["simulate", "--rig", str(rig), "--duration", "0.5", "--out", str(out)]) == 0
    assert load_config(out / "config.yaml").unmodelled_torque == COGGING


def test_a_non_finite_torque_at_run_time_exits_3_naming_the_key(tmp_path, capsys):
    config = tmp_path / "sim.yaml"
    config.write_text("duration: 1.0\nunmodelled_torque:\n  pendulum: 0.01*log(phi - 0.05)\n")
    out = tmp_path / "run"
    assert main(["simulate", "--config", str(config), "--out", str(out)]) == 3
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "diverged at t = 0.0000 s" in err[0] and "unmodelled_torque.pendulum" in err[0]
    assert "non-finite torque" in err[0] and not out.exists()
