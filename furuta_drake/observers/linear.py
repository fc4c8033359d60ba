"""A linear observer as a small Drake Diagram: a ``Multiplexer`` of its named inputs feeding the exact
zero-order-hold discretisation (Drake's ``DiscreteTimeApproximation``) of its continuous dynamics, and a
``Demultiplexer`` splitting its output into named ports.

C++ blocks only, so a 1 kHz observer costs almost nothing in a closed loop; the continuous ``LinearSystem``
stays available (``.continuous``) for the analysis (:mod:`furuta_drake.analysis`).
"""

from __future__ import annotations

from pydrake.systems.analysis import DiscreteTimeApproximation
from pydrake.systems.framework import Diagram, DiagramBuilder
from pydrake.systems.primitives import Demultiplexer, LinearSystem, Multiplexer


class DiscreteLinearObserver(Diagram):
    """``continuous`` (input = the stacked ``inputs``, output = the stacked ``outputs``) sampled at ``period``
    with its inputs held over each period. ``inputs``/``outputs``: [(port name, size)]."""

    def __init__(self, continuous: LinearSystem, period: float, inputs, outputs, name: str):
        Diagram.__init__(self)
        self.continuous = continuous
        self.discrete = DiscreteTimeApproximation(continuous, period)
        builder = DiagramBuilder()
        mux = builder.AddSystem(Multiplexer([size for _, size in inputs]))
        system = builder.AddSystem(self.discrete)
        demux = builder.AddSystem(Demultiplexer([size for _, size in outputs]))
        builder.Connect(mux.get_output_port(), system.get_input_port())
        builder.Connect(system.get_output_port(), demux.get_input_port())
        for i, (port_name, _) in enumerate(inputs):
            builder.ExportInput(mux.get_input_port(i), port_name)
        for i, (port_name, _) in enumerate(outputs):
            builder.ExportOutput(demux.get_output_port(i), port_name)
        builder.BuildInto(self)
        self.set_name(name)
