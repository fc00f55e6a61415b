"""The simulated arm's joints have their drives' reflected rotor inertia and friction
(``robots.params.JointDrives``), while the robot's own model, as libfranka's, has only the
links: torque controllers feel what they feel on a robot."""

from __future__ import annotations

import math

import numpy as np
import pytest

from panda_py import libfranka as lf
from panda_py.robots.params import FRANKA_HAND, START_POSE, get_robot
from panda_py.sim.physics import Physics

pytestmark = pytest.mark.timeout(120)


@pytest.mark.parametrize("robot", ["fer", "fr3"])
def test_the_plant_has_the_armature_the_model_has_not(robot: str) -> None:
    spec = get_robot(robot)
    physics = Physics(spec, scene=True)
    physics.reset(np.array(START_POSE))
    plant = physics.mass_matrix().copy()
    model = lf.Model(spec)
    bare = np.asarray(model.mass(START_POSE, np.zeros(9), 0.0, np.zeros(3))).reshape(7, 7)
    assert bare[6, 6] < 0.01  # joint 7: the links' inertia only, as libfranka's model
    assert plant[6, 6] > 0.07  # the plant's wrist has its rotor too
    # like with like: the plant less its rotors is the model carrying the hand
    hand = FRANKA_HAND.inertial
    i = hand.inertia
    I_hand = np.array([[i[0], i[3], i[4]], [i[3], i[1], i[5]], [i[4], i[5], i[2]]])
    m_hand = hand.mass + 2 * FRANKA_HAND.finger_mass
    loaded = np.asarray(model.mass(START_POSE, I_hand.ravel(), m_hand, hand.com)).reshape(7, 7)
    np.testing.assert_allclose(plant - np.diag(spec.drives.armature), loaded, atol=2e-3)


def _wrist_run(sim, torque) -> tuple[np.ndarray, np.ndarray]:  # type: ignore[no-untyped-def]
    """Joint 7's positions and speeds under ``torque(k)`` [Nm] on joint 7 for its length."""
    qs, dqs = [], []
    with lf.Robot(sim.host) as robot:
        robot.set_collision_behavior([100.0] * 7, [100.0] * 7, [100.0] * 6, [100.0] * 6)
        k = 0

        def loop(state: lf.RobotState, dt: lf.Duration) -> lf.Torques:
            nonlocal k
            qs.append(state.q[6])
            dqs.append(state.dq[6])
            tau = np.zeros(7)
            tau[6], done = torque(k)
            k += 1
            return lf.motion_finished(lf.Torques(tau)) if done else lf.Torques(tau)

        robot.control(loop)
    return np.array(qs), np.array(dqs)


@pytest.mark.panda_sim(robot="fr3")
def test_frankys_gentle_wrist_sine_stays_within_the_velocity_limit(panda_sim) -> None:
    """franky's torque-control example: 0.5 Nm at 1 Hz on joint 7 (without the rotor and
    friction the wrist passed its velocity limit in 0.15 s)."""
    limit = get_robot("fr3").joints.dq_max[6]
    _, dq = _wrist_run(panda_sim, lambda k: (0.5 * math.sin(2 * math.pi * k / 1000), k >= 2000))
    assert np.abs(dq).max() < 0.5 * limit
    assert np.abs(dq).max() > 0.05  # it did move


@pytest.mark.panda_sim(robot="fr3")
def test_viscous_friction_slows_a_spinning_wrist(panda_sim) -> None:
    _, dq = _wrist_run(panda_sim, lambda k: (1.0 if k < 200 else 0.0, k >= 1200))
    spun = np.abs(dq[195:200]).mean()
    assert spun > 0.3  # spun up
    # and slows by itself once the torque ends: armature / viscous = 0.35 s (frictionless,
    # it kept its speed)
    assert np.abs(dq[-5:]).mean() < 0.2 * spun


@pytest.mark.panda_sim(robot="fr3")
def test_a_torque_within_the_dry_friction_leaves_the_wrist_at_rest(panda_sim) -> None:
    """Joint 7's Coulomb friction (0.248 Nm) holds it against 0.2 Nm of torque command;
    0.4 Nm turns it."""
    held, _ = _wrist_run(panda_sim, lambda k: (min(k, 100) * 0.002, k >= 600))
    assert abs(held[-1] - held[0]) < 1e-3
    turned, _ = _wrist_run(panda_sim, lambda k: (min(k, 100) * 0.004, k >= 600))
    assert turned[-1] - turned[0] > 0.02


@pytest.mark.panda_sim(robot="fr3")
def test_the_robots_own_motion_generators_compensate_friction(panda_sim) -> None:
    """A joint position motion under the robot's joint impedance ends where it was told,
    on every joint, despite the drives' dry friction (a robot's controllers compensate it;
    uncompensated, joint 7 stopped about 1 mrad short)."""
    with lf.Robot(panda_sim.host) as robot:
        q0 = np.array(robot.read_once().q)
        goal = q0 + np.array([0.1, -0.1, 0.1, 0.1, -0.1, 0.1, 0.1])
        n = 0

        def motion(state: lf.RobotState, dt: lf.Duration) -> lf.JointPositions:
            nonlocal n
            n += 1
            t = min(n / 1500, 1.0)
            s = t**3 * (10.0 - 15.0 * t + 6.0 * t * t)
            out = lf.JointPositions(q0 + s * (goal - q0))
            out.motion_finished = n >= 1700
            return out

        robot.control(motion, motion=lf.JointPositions)
        robot.read(lambda s: s.robot_mode != lf.RobotMode.kIdle)
        for _ in range(300):  # the robot holds the last target
            state = robot.read_once()
    np.testing.assert_allclose(state.q, goal, atol=2e-4)
