"""The simulated robot refuses absurd settings as a robot does: the setter answers
"rejected: invalid argument" and nothing changes (sim/settings.py holds the ranges)."""

from __future__ import annotations

import numpy as np
import pytest

from panda_py import libfranka as lf
from panda_py.sim import Simulator, free_loopback_host

pytestmark = pytest.mark.timeout(60)

REJECTED = "command rejected: invalid argument"


@pytest.fixture(scope="module")
def sim():
    with Simulator(free_loopback_host(), robot="fr3", lockstep=True) as s:
        yield s


@pytest.fixture
def robot(sim):
    with lf.Robot(sim.host, version=10) as r:
        yield r


def _translation(x: float) -> np.ndarray:
    T = np.eye(4)
    T[0, 3] = x
    return T


@pytest.mark.parametrize("K", [[1e9] * 7, [1e30] * 7, [-1.0] + [3000.0] * 6, [10001.0] * 7])
def test_absurd_joint_stiffness_is_refused_and_nothing_changes(sim, robot, K):
    before = sim.state()
    with pytest.raises(lf.CommandException, match=f"Set Joint Impedance {REJECTED}"):
        robot.set_joint_impedance(K)
    robot.set_joint_impedance([10000.0] * 7)  # the top of the range is fine
    robot.set_joint_impedance([3000, 3000, 3000, 2500, 2500, 2000, 2000])
    # the arm held where it was (to the 1e-14 rad that MuJoCo's friction constraint lets
    # a held joint wander between ticks)
    np.testing.assert_allclose(sim.state()["q"], before["q"], rtol=0, atol=1e-9)


@pytest.mark.parametrize("K", [[5.0, 3000, 3000, 300, 300, 300], [3000, 3000, 3001, 300, 300, 300],
                               [3000, 3000, 3000, 0.5, 300, 300], [1e9] * 6])  # fmt: skip
def test_cartesian_stiffness_outside_the_documented_range_is_refused(robot, K):
    with pytest.raises(lf.CommandException, match=f"Set Cartesian Impedance {REJECTED}"):
        robot.set_cartesian_impedance(K)
    robot.set_cartesian_impedance([10, 10, 10, 1, 1, 1])
    robot.set_cartesian_impedance([3000, 3000, 3000, 300, 300, 300])


@pytest.mark.parametrize("setter", ["set_ee", "set_k"])
@pytest.mark.parametrize("offset", [1e300, 1e3, 1.01])
def test_far_frames_are_refused_and_the_state_keeps_its_frames(robot, setter, offset):
    before = robot.read_once()
    with pytest.raises(lf.CommandException, match=REJECTED):
        getattr(robot, setter)(_translation(offset))
    after = robot.read_once()
    assert np.all(np.isfinite(after.O_T_EE))
    np.testing.assert_array_equal(after.NE_T_EE, before.NE_T_EE)
    np.testing.assert_array_equal(after.EE_T_K, before.EE_T_K)
    getattr(robot, setter)(_translation(0.5))  # within a metre: fine
    getattr(robot, setter)(np.eye(4))


@pytest.mark.parametrize("mass, center, inertia", [
    (3.5, [0, 0, 0.1], np.eye(3) * 1e-3),  # above the 3 kg payload
    (1.0, [0, 0, 2.0], np.eye(3) * 1e-3),  # center of mass 2 m from the flange
    (1.0, [0, 0, 0.1], -np.eye(3) * 1e-3),  # negative moments
    (1.0, [0, 0, 0.1], np.diag([1e-3, 1e-3, 5e-3])),  # violates the triangle inequality
    (1.0, [0, 0, 0.1], np.eye(3) * 10.0),  # 10 kg m^2
])  # fmt: skip
def test_unphysical_loads_are_refused_and_the_load_is_kept(robot, mass, center, inertia):
    robot.set_load(0.25, [0.0, 0.0, 0.05], np.eye(3) * 1e-3)
    with pytest.raises(lf.CommandException, match=f"Set Load {REJECTED}"):
        robot.set_load(mass, center, inertia)
    state = robot.read_once()
    assert state.m_load == pytest.approx(0.25)
    robot.set_load(0.0, [0.0, 0.0, 0.0], np.zeros((3, 3)))


def test_collision_thresholds_must_be_ordered_and_non_negative(robot):
    with pytest.raises(lf.CommandException, match=REJECTED):
        robot.set_collision_behavior([30.0] * 7, [20.0] * 7, [20.0] * 6, [30.0] * 6)
    with pytest.raises(lf.CommandException, match=REJECTED):
        robot.set_collision_behavior([-1.0] * 7, [20.0] * 7, [20.0] * 6, [30.0] * 6)
    robot.set_collision_behavior([20.0] * 7, [1e4] * 7, [20.0] * 6, [1e4] * 6)  # high: fine
