"""A linear observer as a small Drake Diagram: a ``Multiplexer`` of its named inputs feeding the exact
zero-order-hold discretisation (Drake's ``DiscreteTimeApproximation``, the matrix exponential of the continuous
dynamics with the inputs held over each period) of its continuous dynamics, and, for several outputs, a
``Demultiplexer`` splitting the output into named ports.

C++ blocks only, so a 1 kHz observer costs almost nothing in a closed loop; the continuous ``LinearSystem``
stays available (``.continuous``) for the analysis (:mod:`furuta_drake.analysis`).
"""

from __future__ import annotations

import numpy as np
from pydrake.systems.analysis import DiscreteTimeApproximation
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import Demultiplexer, LinearSystem, Multiplexer

from furuta_drake.rig import RigParameters, linearized_upright

ANGLES = np.hstack([np.eye(2), np.zeros((2, 2))])  # C of Eq. 2: the encoders measure [theta, phi]


def model_matrices(rig_or_AB) -> tuple[np.ndarray, np.ndarray]:
    """A (4x4) and B_F (4x2) of Eq. 1-2 from a :class:`RigParameters` (its upright linearization) or an
    (A, B_F) pair in the paper's order."""
    if isinstance(rig_or_AB, RigParameters):
        return linearized_upright(rig_or_AB)
    A, B_F = (np.asarray(m, dtype=float) for m in rig_or_AB)
    if A.shape != (4, 4) or B_F.shape != (4, 2):
        raise ValueError(f"expected A 4x4 and B_F 4x2 (paper order), got {A.shape} and {B_F.shape}")
    return A, B_F


class DiscreteLinearObserver(Diagram):
    """``continuous`` (input = the stacked ``inputs``, output = the stacked ``outputs``) sampled at ``period``
    [s] with its inputs held over each period. ``inputs``/``outputs``: [(port name, size)]. The state is the
    ``discrete`` ``LinearSystem``'s; its output is the state, so the Diagram has no direct feedthrough."""

    def __init__(self, continuous: LinearSystem, period: float, inputs, outputs, name: str):
        Diagram.__init__(self)
        self.continuous = continuous
        self.discrete = DiscreteTimeApproximation(continuous, period)
        builder = DiagramBuilder()
        mux = builder.AddNamedSystem("inputs", Multiplexer([size for _, size in inputs]))
        system = builder.AddNamedSystem("discrete_observer", self.discrete)
        builder.Connect(mux.get_output_port(), system.get_input_port())
        for i, (port_name, _) in enumerate(inputs):
            builder.ExportInput(mux.get_input_port(i), port_name)
        if len(outputs) == 1:
            builder.ExportOutput(system.get_output_port(), outputs[0][0])
        else:
            demux = builder.AddNamedSystem("outputs", Demultiplexer([size for _, size in outputs]))
            builder.Connect(system.get_output_port(), demux.get_input_port())
            for i, (port_name, _) in enumerate(outputs):
                builder.ExportOutput(demux.get_output_port(i), port_name)
        builder.BuildInto(self)
        self.set_name(name)
