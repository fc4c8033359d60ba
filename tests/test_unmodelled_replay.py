"""The unmodelled torque through the diagnosis' Drake side: the replay of a model with a torque, the simulate config
the diagnosis writes for it (``fitted_model.yaml``) and the rig file it writes (``fitted_rig.yaml``)."""

import dataclasses

import numpy as np
import pytest

from furuta_drake.config import ExcitationConfig, SimulationConfig
from furuta_drake.diagnosis.gap.replay import WindowReplayer
from furuta_drake.diagram import build_furuta_diagram
from furuta_drake.effects.corrected import fitted_rig, model_config
from furuta_drake.effects.surrogate import Model
from furuta_drake.plant import plant_to_paper_permutation
from furuta_drake.rig import qube_servo2_rig
from furuta_drake.unmodelled import UnmodelledTorqueParameters
from furuta_drake.yamlio import dump_yaml_dataclass, loads_yaml_dataclass

RIG = qube_servo2_rig()
TORQUE = UnmodelledTorqueParameters(arm="0.002*sin(7*phi) - 3e-4*tanh(phi_dot/0.02)", pendulum="1e-4*cos(theta)")


def replay_derivatives(torque: UnmodelledTorqueParameters | None, x: np.ndarray, command: float):
    """d/dt [theta, phi, theta_dot, phi_dot] of the replay diagram of the QUBE's nominal model at ``x``, and the
    plant's mass matrix there in q = [theta, phi]."""
    time = np.arange(50) * RIG.sample_period
    replayer = WindowReplayer(Model.from_rig(RIG), RIG, time, np.full(time.size, command), unmodelled_torque=torque)
    replayer.context.SetTime(0.01)
    replayer.context.get_mutable_continuous_state_vector().SetFromVector(replayer.P.T @ x)
    order = [int(np.argmax(row)) for row in replayer.P[:2]]  # plant q index of theta, of phi
    M = replayer.plant.CalcMassMatrix(replayer.plant_context)[np.ix_(order, order)]
    return replayer.P @ replayer.diagram.EvalTimeDerivatives(replayer.context).CopyToVector(), M


@pytest.mark.parametrize("seed", range(3))
def test_the_replay_adds_the_torque_as_the_mass_matrix_says(seed):
    """With and without the torque, the accelerations differ by M(q)^-1 tau(x), M the plant's mass matrix (at
    theta = 0 it is paper Eq. 1's [[J_p + m l^2, m l r], [m l r, J_arm + m r^2]], checked first)."""
    rng = np.random.default_rng(seed)
    x = rng.uniform([-3.0, -2.0, -10.0, -10.0], [3.0, 2.0, 10.0, 10.0])
    command = rng.uniform(-0.02, 0.02)
    theta, phi, _, phi_dot = x
    tau = np.array([1e-4 * np.cos(theta), 0.002 * np.sin(7 * phi) - 3e-4 * np.tanh(phi_dot / 0.02)])
    _, upright = replay_derivatives(None, np.zeros(4), 0.0)
    lumped = [[RIG.pendulum_inertia_total, RIG.coupling], [RIG.coupling, RIG.arm_inertia_total]]
    assert upright == pytest.approx(np.array(lumped), rel=1e-12)
    with_torque, M = replay_derivatives(TORQUE, x, command)
    difference = with_torque - replay_derivatives(None, x, command)[0]
    assert difference[:2] == pytest.approx([0.0, 0.0], abs=1e-15)
    assert difference[2:] == pytest.approx(np.linalg.solve(M, tau), rel=1e-9)


def test_the_fitted_config_simulates_the_replays_dynamics():
    """The simulate diagram of the config written for a model with a torque has the replay's time derivatives."""
    model = Model.from_rig(RIG)
    config = model_config(RIG, model, TORQUE)
    assert config.unmodelled_torque == TORQUE
    config = dataclasses.replace(
        config,
        excitation=ExcitationConfig(command=[0.0]),
        controller=dataclasses.replace(config.controller, mode="open_loop"),
    )
    x = np.array([0.4, -1.1, 2.0, -6.0])
    built = build_furuta_diagram(config)
    context = built.diagram.CreateDefaultContext()
    plant_context = built.plant.GetMyMutableContextFromRoot(context)
    built.plant.SetPositionsAndVelocities(plant_context, plant_to_paper_permutation(built.plant).T @ x)
    simulated = plant_to_paper_permutation(built.plant) @ built.diagram.EvalTimeDerivatives(context).CopyToVector()
    assert simulated == pytest.approx(replay_derivatives(TORQUE, x, 0.0)[0], rel=1e-12, abs=1e-12)
    assert model_config(RIG, model).unmodelled_torque.is_empty


def test_the_fitted_rig_carries_the_torque_to_a_further_simulate():
    rig = fitted_rig(RIG, {}, Model.from_rig(RIG), TORQUE)
    assert rig.unmodelled_torque == TORQUE
    back = loads_yaml_dataclass(dump_yaml_dataclass(rig), type(rig), source="fitted_rig.yaml")
    assert SimulationConfig.from_rig(back).unmodelled_torque == TORQUE
    # Without a new torque the rig file's own stays; an empty one removes it.
    assert fitted_rig(rig, {}, Model.from_rig(RIG)).unmodelled_torque == TORQUE
    assert fitted_rig(rig, {}, Model.from_rig(RIG), UnmodelledTorqueParameters()).unmodelled_torque is None
