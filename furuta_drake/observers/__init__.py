"""The paper's observers: high-gain (Eq. 4-6), Dahl friction (Eq. 8-9, 16), velocity and friction error (Eq. 11-13).

HG and VFE are linear, so each is a Drake Diagram of C++ blocks (:mod:`.linear`); the Dahl observer is a Python
LeafSystem with an exact exponential step. All are discrete at the control period (1 kHz on the rig).
"""

from furuta_drake.observers.dahl import DahlFrictionObserver, DahlObserverParameters
from furuta_drake.observers.hg import (
    HighGainObserver, HighGainParameters, high_gain_eigenvalues, high_gain_error_matrix,
)
from furuta_drake.observers.vfe import VfeObserver, VfeParameters, vfe_error_matrix, vfe_gains

__all__ = [
    "DahlFrictionObserver", "DahlObserverParameters", "HighGainObserver", "HighGainParameters",
    "high_gain_eigenvalues", "high_gain_error_matrix", "VfeObserver", "VfeParameters", "vfe_error_matrix", "vfe_gains",
]
