"""One control period: every sampled block runs at the rig's sample period; a config that states another is an
error naming both keys, and a config that states the same one loads and runs as one that states none."""

import dataclasses

import numpy as np
import pytest

from furuta_drake.config import SimulationConfig, dump_config
from furuta_drake.diagram import build_furuta_diagram
from furuta_drake.errors import ConfigError
from furuta_drake.simulate import simulate
from furuta_drake.yamlio import loads_yaml_dataclass


def qube_with_every_observer() -> SimulationConfig:
    config = SimulationConfig.from_rig("qube_servo2")
    return dataclasses.replace(
        config,
        duration=0.2,
        observers=dataclasses.replace(config.observers, run=["hg", "vfe"]),
        controller=dataclasses.replace(config.controller, velocity_source="hg", friction_compensation=True),
    )


def test_every_sampled_block_of_the_qube_diagram_runs_at_its_2_ms_period():
    """Encoder, LQR, HG, VFE, both Dahl observers and the samplers of the log: one period (Drake finds a unique
    period of discrete updates only when every one of them shares it)."""
    built = build_furuta_diagram(qube_with_every_observer())
    unique = built.diagram.GetUniquePeriodicDiscreteUpdateAttribute()
    assert unique is not None and unique.period_sec() == 0.002


@pytest.mark.parametrize(
    "key, line",
    [
        ("encoder:\n  sample_period", 4),
        ("controller:\n  lqr:\n    period", 5),
        ("observers:\n  hg:\n    period", 5),
        ("observers:\n  vfe:\n    period", 5),
        ("observers:\n  dahl:\n    period", 5),
    ],
)
def test_a_config_stating_another_period_is_an_error_naming_both_keys(key, line):
    from furuta_drake.rig import qube_servo2_rig
    from furuta_drake.yamlio import dump_yaml_dataclass

    rig = "".join(
        f"  {row}\n"
        for row in dump_yaml_dataclass(qube_servo2_rig()).splitlines()
        if not row.startswith("sample_period")
    )  # every required key of the rig, at the top
    line += len(rig.splitlines())
    text = f"rig:\n{rig}  sample_period: 0.002\n{key}: 0.001\n"
    dotted = ".".join(part.strip().rstrip(":") for part in key.split("\n"))
    with pytest.raises(
        ConfigError,
        match=rf"config.yaml:{line}: {dotted} = 0.001 differs from the control period "
        rf"rig.sample_period = 0.002",
    ):
        loads_yaml_dataclass(text, SimulationConfig, source="config.yaml")


def test_a_config_stating_the_control_period_everywhere_runs_as_one_stating_it_nowhere():
    """A config written out with every period stated (as earlier configs were) loads and gives the same run."""
    config = qube_with_every_observer()
    stated = dataclasses.replace(
        config,
        encoder=dataclasses.replace(config.encoder, sample_period=0.002),
        controller=dataclasses.replace(config.controller, lqr=dataclasses.replace(config.controller.lqr, period=0.002)),
        observers=dataclasses.replace(
            config.observers,
            **{
                name: dataclasses.replace(getattr(config.observers, name), period=0.002)
                for name in ("hg", "vfe", "dahl")
            },
        ),
    )
    loaded = loads_yaml_dataclass(dump_config(stated), SimulationConfig)
    assert loaded == stated
    first, second = simulate(config), simulate(loaded)
    np.testing.assert_array_equal(first.state, second.state)
    np.testing.assert_array_equal(first.estimates["vfe"], second.estimates["vfe"])
