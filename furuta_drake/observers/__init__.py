"""The paper's observers: high-gain (Eq. 4-6), Dahl friction (Eq. 8-9, 16) with its optional adaptation (the
K_sigma law of Eq. 16-18, or Fc and sigma0 of Sec. VII), velocity and friction error (Eq. 11-13).

HG and VFE are linear, so each is a Drake Diagram of C++ blocks (:mod:`.linear`); the Dahl observer is a Python
LeafSystem with an exact exponential step, its adaptation laws (:mod:`.k_sigma`, :mod:`.parameter_adaptation`)
inside it. All are discrete at the control period.
"""

from furuta_drake.observers.dahl import DahlAdaptation, DahlFrictionObserver, DahlObserverParameters
from furuta_drake.observers.hg import (
    HighGainObserver,
    HighGainParameters,
    high_gain_eigenvalues,
    high_gain_error_matrix,
)
from furuta_drake.observers.k_sigma import KSigmaAdaptationParameters
from furuta_drake.observers.parameter_adaptation import ParameterAdaptationParameters
from furuta_drake.observers.vfe import VfeObserver, VfeParameters, vfe_error_matrix, vfe_gains

__all__ = [
    "DahlAdaptation",
    "DahlFrictionObserver",
    "DahlObserverParameters",
    "HighGainObserver",
    "HighGainParameters",
    "high_gain_eigenvalues",
    "high_gain_error_matrix",
    "KSigmaAdaptationParameters",
    "ParameterAdaptationParameters",
    "VfeObserver",
    "VfeParameters",
    "vfe_error_matrix",
    "vfe_gains",
]
