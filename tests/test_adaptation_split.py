"""The adaptation laws as their own systems (the K_sigma adapter, Eq. 16-18; the Fc and sigma0 adapter, Sec. VII)
give the closed loop the code gave while the laws ran inside the Dahl observer, to 1e-12.

``data/adaptation_reference.npz`` holds the states, F_hat and adapted values of two 2 s balancing runs of the Lund
rig under diagram (iii) (VFE + Dahl + adaptation, Dahl friction on the arm), every fifth sample (``EVERY``),
written with that code (commit cb891d7) by the same configuration as :func:`adaptive_config` below.
"""

import dataclasses
from pathlib import Path

import numpy as np
import pytest

from furuta_drake.config import SimulationConfig
from furuta_drake.diagram import build_furuta_diagram
from furuta_drake.friction import FrictionParameters, JointFrictionParameters
from furuta_drake.observers.dahl import DahlAdaptation
from furuta_drake.observers.k_sigma import KSigmaAdaptationParameters, KSigmaAdapter
from furuta_drake.observers.parameter_adaptation import DahlParameterAdapter, ParameterAdaptationParameters
from furuta_drake.simulate import simulate

REFERENCE = np.load(Path(__file__).parent / "data" / "adaptation_reference.npz")
EVERY = 5  # the reference keeps every fifth sample of the runs
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
def test_adapter_systems_reproduce_the_closed_loop_to_1e_12(law):
    adaptation, signal = LAWS[law]
    result = simulate(adaptive_config(adaptation))
    np.testing.assert_allclose(result.state[::EVERY], REFERENCE[f"{law}_state"], rtol=0, atol=1e-12)
    np.testing.assert_allclose(
        result.signals["friction_estimate"][::EVERY], REFERENCE[f"{law}_friction_estimate"], rtol=0, atol=1e-12
    )
    np.testing.assert_allclose(result.signals[signal][::EVERY], REFERENCE[f"{law}_adapted"], rtol=0, atol=1e-12)
    assert np.ptp(result.signals[signal][:, 0]) > 0  # the law did adapt in this run


@pytest.mark.parametrize("law", LAWS)
def test_each_adapter_is_its_own_named_system_of_the_diagram(law):
    """A notebook finds the adapter by name to log, plot or replace it."""
    name, kind = ADAPTERS[law]
    built = build_furuta_diagram(adaptive_config(LAWS[law][0]))
    assert isinstance(built.diagram.GetSubsystemByName(name), kind)
