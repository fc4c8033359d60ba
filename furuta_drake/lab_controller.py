"""The balancing controller of a simulate config as a lab runs it: the measured angles of each sample in, the command
of that sample out, from the same Drake blocks that close the loop in ``simulate``.

:class:`LabController` builds the controller's part of :func:`~furuta_drake.diagram.build_furuta_diagram`: the
observers of ``config`` (:func:`~furuta_drake.diagram.add_observers`: HG, or VFE with the Dahl observer and its
K_sigma adaptation), the LQR with its friction compensation and torque limit
(:class:`~furuta_drake.controllers.lqr.LqrController`), wired as there
(:func:`~furuta_drake.diagram.connect_estimates`). The rig's encoder is replaced by a ``ZeroOrderHold`` at the
control period, which holds each sample as the encoder's discrete state does, so the map from the measured samples
to the commands is the simulated loop's, sample for sample: the command applied over [t_k, t_k+1) is computed from
the observer's estimate of the previous period, which has read the samples up to t_k-1 (Drake's discrete blocks
update together, each reading the others' values from before the tick).

A lab's controller starts with what it can know: the observers at the first measured angles and zero velocities
(the simulated loop starts them at the true initial state), the Dahl observer's bristle state at 0 and K_sigma at
its initial value. Calling the controller with the angles of sample k (k = 0, 1, ...) returns the command of sample
k [N m] (torque-equivalent on a motor rig: kt V / R). Useful to run a tuned controller against another simulator or
a rig's I/O loop.
"""

from __future__ import annotations

import dataclasses

import numpy as np
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder
from pydrake.systems.primitives import ZeroOrderHold

from furuta_drake.config import SimulationConfig
from furuta_drake.controllers.lqr import LqrController
from furuta_drake.diagram import add_observers, connect_estimates, controller_gain
from furuta_drake.errors import ConfigError
from furuta_drake.plant import make_furuta_plant

SOURCES = ("hg", "vfe", "derivative", "filtered_derivative")  # velocity sources a lab's controller can run


class LabController:
    """``config``'s balancing controller (``controller.mode`` 'lqr'), stepped one sample at a time (module
    docstring): ``controller(measured)`` with the sample's [theta, phi] [rad] returns its command [N m]."""

    def __init__(self, config: SimulationConfig):
        config.validate()
        control = config.controller
        if control.mode != "lqr" or control.velocity_source not in SOURCES:
            raise ConfigError(
                f"controller: a lab controller runs mode 'lqr' on one of {list(SOURCES)}, got mode "
                f"{control.mode!r} on {control.velocity_source!r}"
            )
        self.config = config
        self.period = config.control_period
        self.gain = controller_gain(make_furuta_plant(config.rig), config)
        self._simulator = None
        self._input = None
        self._output = None
        self._samples = 0

    def _start(self, measured: np.ndarray) -> None:
        """Build the controller with its observers started at the first sample ``measured`` at rest."""
        config = dataclasses.replace(
            self.config,
            initial_state=[float(measured[0]), float(measured[1]), 0.0, 0.0],
            observers=dataclasses.replace(self.config.observers, start_at_initial_state=True),
        )
        control, period = config.controller, self.period
        builder = DiagramBuilder()
        hold = builder.AddNamedSystem("encoder_hold", ZeroOrderHold(period, 2))
        builder.ExportInput(hold.get_input_port(), "measured_angles_rad")
        lqr = builder.AddNamedSystem(
            "lqr",
            LqrController(
                self.gain,
                period=period,
                torque_limit=control.lqr.torque_limit,
                friction_compensation=control.friction_compensation,
            ),
        )
        torque = lqr.GetOutputPort("arm_torque_Nm")
        observers = add_observers(builder, config, true_state=None, measured=hold.get_output_port(), command=torque)
        connect_estimates(builder, config, lqr, observers)
        builder.ExportOutput(torque, "arm_torque_Nm")
        diagram = builder.Build()
        self._simulator = Simulator(diagram)
        context = self._simulator.get_mutable_context()
        hold.SetVectorState(hold.GetMyMutableContextFromRoot(context), np.asarray(measured, dtype=float))
        self._input = diagram.get_input_port(0)
        self._output = diagram.get_output_port(0)
        self._simulator.Initialize()

    def __call__(self, measured) -> float:
        measured = np.asarray(measured, dtype=float).ravel()
        if self._simulator is None:
            self._start(measured)
        context = self._simulator.get_mutable_context()
        self._input.FixValue(context, measured)
        # Half a period past the sample: its updates are done (they read this sample), the next ones are not.
        self._simulator.AdvanceTo((self._samples + 0.5) * self.period)
        self._samples += 1
        return float(self._output.Eval(context)[0])


__all__ = ["LabController", "SOURCES"]
