"""The adaptation laws as their own systems of the diagram (the K_sigma adapter, Eq. 16-18; the Fc and sigma0
adapter, Sec. VII), wired to the Dahl observer in the balancing loop of diagram (iii) (VFE + Dahl + adaptation):
found by name, and adapting towards the rig's friction while the loop balances. The laws' own dynamics are unit
tested in test_adaptation.py and test_parameter_adaptation.py.
"""

import dataclasses

import numpy as np
import pytest

from furuta_drake.config import SimulationConfig
from furuta_drake.diagram import build_furuta_diagram
from furuta_drake.friction import FrictionParameters, JointFrictionParameters
from furuta_drake.observers.dahl import DahlAdaptation
from furuta_drake.observers.k_sigma import KSigmaAdaptationParameters, KSigmaAdapter
from furuta_drake.observers.parameter_adaptation import DahlParameterAdapter, ParameterAdaptationParameters
from furuta_drake.simulate import simulate

LAWS = {
    "k_sigma": (DahlAdaptation(k_sigma=KSigmaAdaptationParameters(enable_time=0.5, gamma=20000.0)), "K_sigma"),
    "parameters": (DahlAdaptation(parameters=ParameterAdaptationParameters(enable_time=0.5)), "dahl_parameters"),
}
ADAPTERS = {
    "k_sigma": ("vfe_k_sigma_adapter", KSigmaAdapter),
    "parameters": ("vfe_parameter_adapter", DahlParameterAdapter),
}


def adaptive_config(adaptation: DahlAdaptation) -> SimulationConfig:
    """The Lund rig balancing from theta = 0.05 rad for 2 s on VFE estimates with the Dahl observer adapting as
    ``adaptation`` says, against Dahl friction of 0.015 / 0.02 N m on the arm."""
    config = SimulationConfig.from_rig("lund")
    arm = JointFrictionParameters(model="dahl", coulomb_pos=0.015, coulomb_neg=0.02, sigma0=10.0)
    config = dataclasses.replace(
        config, friction=FrictionParameters(arm=arm), duration=2.0, initial_state=[0.05, 0.0, 0.0, 0.0]
    )
    dahl = dataclasses.replace(config.observers.dahl, adaptation=adaptation)
    return dataclasses.replace(
        config,
        observers=dataclasses.replace(config.observers, dahl=dahl),
        controller=dataclasses.replace(config.controller, velocity_source="vfe"),
    )


@pytest.mark.parametrize("law", LAWS)
def test_the_adapter_raises_the_positive_branch_towards_the_rigs_friction_while_balancing(law):
    """The rig's arm friction (0.015 N m for phi_dot > 0) is above the observer's model (0.012 N m): the K_sigma
    of that branch rises above 1 (the true ratio is 1.25), or the adapted Fc+ above 0.012 N m; the loop balances
    (|theta| within 0.02 rad after the first second)."""
    adaptation, signal = LAWS[law]
    result = simulate(adaptive_config(adaptation))
    adapted = result.signals[signal]
    assert adapted[0, 0] == pytest.approx(1.0 if law == "k_sigma" else 0.012)
    assert adapted[-1, 0] > adapted[0, 0] * 1.05
    assert np.max(np.abs(result.state[result.time > 1.0, 0])) < 0.02


@pytest.mark.parametrize("law", LAWS)
def test_each_adapter_is_its_own_named_system_of_the_diagram(law):
    """A notebook finds the adapter by name to log, plot or replace it."""
    name, kind = ADAPTERS[law]
    built = build_furuta_diagram(adaptive_config(LAWS[law][0]))
    assert isinstance(built.diagram.GetSubsystemByName(name), kind)
