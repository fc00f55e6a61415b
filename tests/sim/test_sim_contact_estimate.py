"""The robot's estimate of external torques and wrench, judged from the client's side as
libfranka defines it (include/franka/robot_state.h): ``tau_ext_hat_filtered`` is "the error
between tau_J and the expected torques given by the robot model", low-pass filtered, and
``O_F_ext_hat_K`` the wrench at K that explains it. A torque controller presses the hand
onto the table with a known force: the estimate at rest reads that force; and through the
impact and the press, tick by tick, the estimate is what the published ``tau_J``, ``q``,
``dq`` and the client's own model (``Model.mass``, ``coriolis``, ``gravity``) say, through
a first-order filter of the simulator's observer gain."""

from __future__ import annotations

import itertools
from typing import Any

import numpy as np
import pytest

import panda_py
from panda_py import libfranka as lf
from panda_py.robots.params import START_POSE
from panda_py.sim.state import OBSERVER_GAIN

pytestmark = pytest.mark.timeout(180)

DT = 1e-3  # [s] one tick
PRESS = 1500  # [ticks] the press, from 1 cm above the table: impact, then rest
# The estimate at rest against the force the controller applies: the joints' dry friction
# (up to 1.1 Nm a joint on the FER) holds part of the commanded torque on an arm at rest
# (seen: 1.3 N of 30, 2.0 N of 50).
REST_TOLERANCE = 1.0  # [N] and ...
REST_RELATIVE = 0.05  # ... this fraction of the force
# The client's model against the simulated robot's: the plant's fingers (30 g) are bodies
# of their own beside Desk's hand, which the client's model holds (seen: 0.19 Nm).
MODEL_TOLERANCE = 0.25  # [Nm]


def _above_table(q_init: np.ndarray) -> np.ndarray:
    """Joint positions putting the end effector 1 cm above the table, pointing down, away
    from the cube."""
    pose = panda_py.fk(q_init)
    pose[:3, 3] = (0.45, 0.25, 0.01)
    q = panda_py.ik(pose, q_init)
    assert np.isfinite(q).all()
    return q


def press(sim: Any, force: float) -> tuple[list[dict[str, np.ndarray]], lf.Model]:
    """Press the hand down on the table with ``force`` [N] (J^T F and a little joint
    damping) for PRESS ticks; every tick's state and the client's model."""
    sim.set_joint_positions(_above_table(np.array(START_POSE)).tolist())
    seen: list[dict[str, np.ndarray]] = []
    with lf.Robot(sim.host) as robot:
        model = robot.load_model()
        robot.set_collision_behavior([100.0] * 7, [100.0] * 7, [100.0] * 6, [100.0] * 6)

        def law(state: lf.RobotState, dt: lf.Duration) -> lf.Torques:
            seen.append({name: np.array(getattr(state, name)) for name in (
                "q", "dq", "tau_J", "tau_ext_hat_filtered", "O_F_ext_hat_K", "K_F_ext_hat_K",
                "I_total", "m_total", "F_x_Ctotal",
            )})  # fmt: skip
            J = model.zero_jacobian(lf.Frame.kEndEffector, state).reshape(7, 6).T
            F = np.array([0.0, 0.0, -force, 0.0, 0.0, 0.0])  # the robot pushes down
            tau = lf.Torques(J.T @ F - 5.0 * np.asarray(state.dq))
            return tau if len(seen) < PRESS else lf.motion_finished(tau)

        robot.control(law)
        return seen, model


@pytest.mark.parametrize("force", [10.0, 30.0])
def test_pressing_with_a_known_force_reads_that_force(panda_sim: Any, force: float) -> None:
    seen, _ = press(panda_sim, force)
    last = seen[-1]
    assert np.abs(last["dq"]).max() < 1e-3  # at rest on the table
    tolerance = REST_TOLERANCE + REST_RELATIVE * force
    O_F = last["O_F_ext_hat_K"]
    np.testing.assert_allclose(O_F[:3], [0.0, 0.0, -force], atol=tolerance)
    # the stiffness frame K is the end effector's (z down): the push along its +z
    assert abs(last["K_F_ext_hat_K"][2] - force) < tolerance


def test_the_estimate_is_the_models_residual_filtered(panda_sim: Any) -> None:
    seen, model = press(panda_sim, 12.0)
    alpha = OBSERVER_GAIN * DT
    r = np.zeros(7)
    worst = 0.0
    peak = 0.0
    for before, now in itertools.pairwise(seen):
        # the model at the step's start, its acceleration from the velocities around it
        q, dq = before["q"], before["dq"]
        load = before["I_total"], before["m_total"], before["F_x_Ctotal"]
        ddq = (now["dq"] - dq) / DT
        M = model.mass(q, *load).reshape(7, 7, order="F")
        expected = M @ ddq + model.coriolis(q, dq, *load) + model.gravity(q, *load[1:])
        r += alpha * (now["tau_J"] - expected - r)
        worst = max(worst, float(np.abs(r - now["tau_ext_hat_filtered"]).max()))
        peak = max(peak, float(np.abs(now["tau_ext_hat_filtered"]).max()))
    assert peak > 2.0  # it did press (the check below is not on zeros)
    assert worst < MODEL_TOLERANCE, worst
