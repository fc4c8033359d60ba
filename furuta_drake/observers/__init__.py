"""The paper's observers: high-gain (Eq. 4-6), Dahl friction (Eq. 8-9, 16) with its optional adaptation (the
K_sigma law of Eq. 16-18, or Fc and sigma0 of Sec. VII), velocity and friction error (Eq. 11-13).

HG and VFE are linear, so each is a Drake Diagram of C++ blocks (:mod:`.linear`); the Dahl observer (an exact
exponential step) and its K_sigma adapter (:class:`.k_sigma.KSigmaAdapter`) are symbolic expressions evaluated in
C++ (:mod:`furuta_drake.symbolic_system`); the Fc and sigma0 adapter
(:class:`.parameter_adaptation.DahlParameterAdapter`) is a Python LeafSystem. All are discrete at the control
period.
"""

from furuta_drake.observers.dahl import (
    DahlAdaptation,
    DahlFrictionObserver,
    DahlObserverParameters,
    adapting_dahl_observer,
    add_dahl_adaptation,
)
from furuta_drake.observers.hg import (
    HighGainObserver,
    HighGainParameters,
    high_gain_eigenvalues,
    high_gain_error_matrix,
)
from furuta_drake.observers.k_sigma import KSigmaAdaptationParameters, KSigmaAdapter
from furuta_drake.observers.parameter_adaptation import DahlParameterAdapter, ParameterAdaptationParameters
from furuta_drake.observers.vfe import VfeObserver, VfeParameters, vfe_error_matrix, vfe_gains

__all__ = [
    "DahlAdaptation",
    "DahlParameterAdapter",
    "adapting_dahl_observer",
    "add_dahl_adaptation",
    "DahlFrictionObserver",
    "DahlObserverParameters",
    "HighGainObserver",
    "HighGainParameters",
    "high_gain_eigenvalues",
    "high_gain_error_matrix",
    "KSigmaAdaptationParameters",
    "KSigmaAdapter",
    "ParameterAdaptationParameters",
    "VfeObserver",
    "VfeParameters",
    "vfe_error_matrix",
    "vfe_gains",
]
