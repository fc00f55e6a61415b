"""The simulated Franka Hand under grasp force: its width stays within its stroke, an
object grasped stays grasped (libfranka's epsilon window), on nothing and on the cube.

In process (every tick of the hand's core over the MuJoCo fingers) and through
libfranka's Gripper (the states a client receives)."""

from __future__ import annotations

import numpy as np
import pytest

from panda_py import libfranka as lf
from panda_py.fci.gripper import GripperStatus
from panda_py.robots.mjcf import CUBE_POSITION, CUBE_SIZE
from panda_py.robots.params import FRANKA_HAND, START_POSE, get_robot
from panda_py.sim import Simulator, free_loopback_host
from panda_py.sim.gripper import GripperCore
from panda_py.sim.physics import Physics

pytestmark = pytest.mark.timeout(120)

# Grasp forces across the hand's range [N]: up to its 70 N continuous and 140 N peak.
FORCES = (5.0, 20.0, 60.0, 70.0, FRANKA_HAND.peak_force)
EPS = 0.005  # [m] libfranka's default epsilon_inner and epsilon_outer
# [m] how far the simulated fingers may yield past their closed stop under 140 N
STOP_YIELD = 1e-4


def tcp_at_cube(above: float = 0.0) -> np.ndarray:
    """The TCP pose with the fingers around the scene's cube, 5 mm above its centre (the
    pads then keep off the table), pointing down as at the start pose; ``above`` [m]
    higher."""
    T = np.diag([1.0, -1.0, -1.0, 1.0])
    T[:3, 3] = CUBE_POSITION
    T[2, 3] += 0.005 + above
    return T


def q_at_cube(physics: Physics, above: float = 0.0) -> np.ndarray:
    """Joint positions placing the TCP at :func:`tcp_at_cube` (the simulator's own IK,
    walked there from the start pose in 1 cm steps)."""
    O_T_F = tcp_at_cube(above) @ np.linalg.inv(physics.F_T_NE)
    q = np.array(START_POSE)
    start = physics.flange_pose_at(q)[:3, 3]
    T = O_T_F.copy()
    for s in np.linspace(0.0, 1.0, 50):
        T[:3, 3] = start + s * (O_T_F[:3, 3] - start)
        q = physics.solve_ik(T, q, None)
    for _ in range(10):
        q = physics.solve_ik(O_T_F, q, None)
    T = physics.flange_pose_at(q)
    assert np.linalg.norm(T[:3, 3] - O_T_F[:3, 3]) < 1e-6, "IK to the cube did not converge"
    return q


class Hand:
    """The hand's core on its own physics, the arm held still at ``q``."""

    def __init__(self, at_cube: bool) -> None:
        self.physics = Physics(get_robot("fer"), scene=True)
        self.q = q_at_cube(self.physics) if at_cube else np.array(START_POSE)
        self.physics.reset(self.q)
        self.core = GripperCore(self.physics)
        self.reported: list[float] = []  # the width the hand reports, every tick
        self.simulated: list[float] = []  # the MuJoCo fingers' width, every tick
        self.grasped: list[bool] = []

    def run(self, ticks: int, to: np.ndarray | None = None) -> None:
        """``ticks`` ms, the arm moving on a straight joint-space line to ``to`` if given."""
        zero = np.zeros(7)
        ph, core = self.physics, self.core
        q0 = self.q
        for i in range(ticks):
            core.tick()
            if to is not None:
                s = (i + 1) / ticks
                self.q = q0 + (to - q0) * (3 * s * s - 2 * s * s * s)  # smooth start, stop
            ph.step(ph.joint_tracking_torque(self.q, zero, zero, np.ones(7)), core.force)
            self.reported.append(core.width)
            self.simulated.append(ph.gripper_width())
            self.grasped.append(core.is_grasped)

    def grasp(self, width: float, force: float) -> GripperStatus:
        assert self.core.grasp_object(7, width, EPS, EPS, 0.1, force) is None
        for _ in range(3000):
            self.run(1)
            if self.core.completed:
                (cid, status), = self.core.completed  # fmt: skip
                assert cid == 7
                return status
        raise AssertionError("the grasp did not finish within 3 s")


@pytest.mark.parametrize("force", FORCES)
@pytest.mark.parametrize("on", ["nothing", "cube"])
def test_width_stays_in_the_stroke_and_the_grasp_holds(on: str, force: float) -> None:
    hand = Hand(at_cube=on == "cube")
    # nothing between the fingers: they close fully, 0 lies within [5 - 5, 5 + 5] mm
    width = CUBE_SIZE if on == "cube" else 0.005
    assert hand.grasp(width, force) is GripperStatus.SUCCESS
    done = len(hand.grasped)
    hand.run(2000)  # squeezing for 2 s
    reported = np.array(hand.reported)
    assert reported.min() >= 0.0 and reported.max() <= FRANKA_HAND.max_width
    # the fingers themselves stop at their closed stop (not a clamped reading only)
    assert min(hand.simulated) > -STOP_YIELD, min(hand.simulated)
    assert all(hand.grasped[done:]), "is_grasped dropped while squeezing"
    held = reported[done:]
    assert np.all(np.abs(held - width) <= EPS)
    if on == "cube":  # the pads squeeze the cube without sinking into it
        assert held.min() > CUBE_SIZE - 0.5e-3, held.min()


def test_a_weak_grasp_lets_the_cube_go() -> None:
    """The cube is held by friction alone: at 0.3 N per pad it slides out of the fingers
    when the arm moves up (friction 2 x 0.3 N < its 0.98 N weight)."""
    hand = Hand(at_cube=True)
    assert hand.grasp(CUBE_SIZE, 0.3) is GripperStatus.SUCCESS
    cube = hand.physics.model.body("cube").id
    z0 = float(hand.physics.data.xpos[cube][2])
    hand.run(1500, to=q_at_cube(hand.physics, above=0.1))  # lift by 10 cm in 1.5 s
    hand.run(500)
    assert float(hand.physics.data.xpos[cube][2]) < z0 + 0.005  # left behind on the table
    assert not hand.core.is_grasped  # the fingers closed on nothing


# -- through libfranka's Gripper ------------------------------------------------------------


@pytest.fixture(scope="module")
def sim():
    with Simulator(free_loopback_host(), robot="fer", lockstep=True) as s:
        yield s


def _states(gripper: lf.Gripper, n: int) -> list[lf.GripperState]:
    gripper.read_once()  # a state queued before the command ended may still be waiting
    return [gripper.read_once() for _ in range(n)]


@pytest.mark.parametrize("force", (5.0, 20.0, 60.0, 70.0))
def test_a_client_sees_the_grasp_hold_on_nothing(sim: Simulator, force: float) -> None:
    """pylibfranka's move_gripper example, in-tree: grasp(0.005, 0.1, 60) with the fingers
    closing fully, then is_grasped stays true (the hand was read at -5.2 mm, "Object lost")."""
    with lf.Gripper(sim.host) as gripper:
        assert gripper.homing() is True
        assert gripper.grasp(0.005, 0.1, force) is True
        states = _states(gripper, 50)  # 0.5 s of squeezing
        assert all(0.0 <= s.width <= s.max_width for s in states), [s.width for s in states]
        assert all(s.is_grasped for s in states)
        assert gripper.stop() is True
        assert gripper.move(FRANKA_HAND.max_width, 0.1) is True


@pytest.mark.parametrize("force", (5.0, 70.0))
def test_a_client_sees_the_cube_grasped(sim: Simulator, force: float) -> None:
    physics = Physics(get_robot("fer"), scene=False)
    sim.set_joint_positions(q_at_cube(physics).tolist())
    try:
        with lf.Gripper(sim.host) as gripper:
            assert gripper.move(FRANKA_HAND.max_width, 0.1) is True
            assert gripper.grasp(CUBE_SIZE, 0.05, force) is True
            states = _states(gripper, 50)
            widths = [s.width for s in states]
            assert all(CUBE_SIZE - 0.5e-3 < w <= CUBE_SIZE for w in widths), widths
            assert all(s.is_grasped for s in states)
            assert gripper.move(FRANKA_HAND.max_width, 0.1) is True
            assert not gripper.read_once().is_grasped
    finally:
        sim.set_joint_positions(START_POSE)
