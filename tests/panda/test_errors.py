"""Bad input is refused in the user's process before anything reaches the control process;
a reflex during a move is reported and recovered from; no robot at the address is a clear
NetworkException."""

from __future__ import annotations

import threading
import time

import numpy as np
import pytest

import panda_py
from panda_py import constants, controllers
from panda_py.libfranka import ControlException, NetworkException
from panda_py.rt.shm import HEADER
from panda_py.sim import Simulator
from panda_py.sim.api import free_loopback_host

pytestmark = pytest.mark.timeout(120)

NAN7 = np.full(7, np.nan)


def _requests_sent(panda: panda_py.Panda) -> int:
    return next(panda._proc._ids)  # the next request id: counts what was sent


@pytest.mark.parametrize(
    ("call", "match"),
    [
        (lambda p: p.move_to_joint_position(NAN7), "waypoints"),
        (lambda p: p.move_to_joint_position(np.zeros(6)), "waypoints"),
        (lambda p: p.move_to_joint_position(np.full(7, 3.5)), "outside"),
        (
            lambda p: p.move_to_joint_position(constants.JOINT_POSITION_START, speed_factor=0),
            "speed_factor",
        ),
        (
            lambda p: p.move_to_joint_position(
                constants.JOINT_POSITION_START, stiffness=[np.inf] * 7
            ),
            "stiffness",
        ),
        (lambda p: p.move_to_pose(np.eye(4) * 2), "pose|rigid|homogeneous"),
        (lambda p: p.move_to_pose(np.full((4, 4), np.nan)), "finite"),
        (lambda p: p.move_to_pose([0.3, 0.0, 0.5], [0, 0, 0, 0]), "quaternion"),
        (lambda p: p.move_to_pose([3.0, 0.0, 0.5], [1, 0, 0, 0]), "out of reach"),
        (lambda p: p.move_to_pose([0.3, 0.0], [1, 0, 0, 0]), "positions"),
        (lambda p: p.enable_logging(0), "buffer_size"),
        (lambda p: p.enable_logging(2.5), "buffer_size"),
        (lambda p: p.enable_logging(float("nan")), "buffer_size"),
        (lambda p: p.get_robot().set_joint_impedance([np.nan] * 7), "K_theta"),
        (lambda p: p.get_robot().set_cartesian_impedance([1, 2, 3]), "K_x"),
        (lambda p: p.get_robot().set_ee(np.eye(4) * 3), "rigid"),
        (lambda p: p.get_robot().set_load(-1.0, [0, 0, 0], np.eye(3)), "load_mass"),
        (lambda p: p.get_robot().set_collision_behavior([1] * 7, [1] * 7, [1] * 6), "4 or 8"),
        (lambda p: p.start_controller("not a controller"), "TorqueController"),
        (lambda p: p.create_context(0), "frequency"),
    ],
)
def test_bad_input_is_refused_before_it_is_sent(shared_panda: panda_py.Panda, call, match) -> None:
    panda = shared_panda  # each refusal leaves it as it was: the asserts below hold that
    sent = _requests_sent(panda)
    q = panda.q
    with pytest.raises(ValueError, match=match):
        call(panda)
    assert _requests_sent(panda) == sent + 1  # nothing sent in between
    assert not panda.is_moving()
    assert np.allclose(panda.q, q, atol=1e-6)


@pytest.mark.parametrize(
    "make",
    [
        lambda c: c.set_control([np.nan, 0, 0], [0, 0, 0, 1]),
        lambda c: c.set_control([0, 0, 0], [0, 0, 0, 2]),
        lambda c: c.set_control([0, 0, 0, 1], [0, 0, 0, 1]),
        lambda c: c.set_control([0, 0, 0], [0, 0, 0, 1], [0] * 6),
        lambda c: c.set_impedance(-np.eye(6)),
        lambda c: c.set_impedance(np.ones((6, 5))),
        lambda c: c.set_damping_ratio(float("inf")),
        lambda c: c.set_nullspace_stiffness(-1),
        lambda c: c.set_filter(0.0),
        lambda c: c.set_filter(1.5),
    ],
)
def test_controller_inputs_are_checked(make) -> None:
    ctrl = controllers.CartesianImpedance()
    before = ctrl._values.copy()
    with pytest.raises(ValueError):
        make(ctrl)
    assert np.array_equal(ctrl._values, before, equal_nan=True)  # nothing half-applied


@pytest.mark.parametrize(
    ("factory", "bad"),
    [
        (controllers.JointPosition, lambda c: c.set_control(NAN7)),
        (controllers.JointPosition, lambda c: c.set_control(np.zeros(7), np.zeros(8))),
        (controllers.IntegratedVelocity, lambda c: c.set_control([1j] * 7)),
        (controllers.AppliedTorque, lambda c: c.set_damping([-1.0] * 7)),
        (controllers.AppliedForce, lambda c: c.set_control(np.zeros(7))),
        (controllers.Force, lambda c: c.set_integral_gain(np.nan)),
        (lambda: controllers.JointPosition(stiffness=[1, 2]), None),
        (lambda: controllers.CartesianImpedance(impedance=np.eye(5)), None),
        (lambda: controllers.Force(threshold=-1), None),
    ],
)
def test_every_controller_checks_its_arguments(factory, bad) -> None:
    with pytest.raises(ValueError):
        ctrl = factory()
        bad(ctrl)


def test_reflex_during_a_move(reset_panda: panda_py.Panda, shared_sim: Simulator) -> None:
    panda, sim = reset_panda, shared_sim
    panda.move_to_start()
    target = constants.JOINT_POSITION_START + np.array([0.4, 0, 0, 0, 0, 0, 0])

    def inject() -> None:
        header = panda._proc.block.header
        deadline = time.monotonic() + 20
        while not header[HEADER.RUNNING] and time.monotonic() < deadline:
            time.sleep(0.001)
        time.sleep(0.05)
        sim.inject_reflex("joint_reflex", "power_limit_violation")

    thread = threading.Thread(target=inject)
    thread.start()
    with pytest.raises(ControlException) as raised:
        try:
            assert panda.move_to_joint_position(target) is False
        finally:
            thread.join()
        panda.raise_error()
    assert "joint_reflex" in raised.value.reflex_reason
    assert panda.get_state().robot_mode == panda_py.libfranka.RobotMode.kReflex
    panda.recover()
    assert panda.move_to_joint_position(target)  # usable again
    assert np.abs(panda.q - target).max() < 0.01


def test_no_robot_at_the_address() -> None:
    start = time.monotonic()
    with pytest.raises(NetworkException):
        panda_py.Panda(free_loopback_host())
    assert time.monotonic() - start < 10.0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"realtime_config": 7}, "realtime_config"),
        ({"name": 3}, "name"),
        ({"hostname": ""}, "hostname"),
    ],
)
def test_bad_constructor_arguments_start_no_process(kwargs: dict, match: str) -> None:
    args = {"hostname": "127.0.0.1", **kwargs}
    with pytest.raises(ValueError, match=match):
        panda_py.Panda(**args)


def test_the_robot_proxy_binds_arguments_as_robot_does() -> None:
    """``panda.get_robot()`` has ``libfranka.Robot``'s signature for every method they
    share, so named arguments work through it (``set_filters`` lost them once)."""
    import inspect

    from panda_py.libfranka import Robot
    from panda_py.panda.proxy import RobotProxy

    shared = [n for n in dir(RobotProxy) if not n.startswith("_") and hasattr(Robot, n)]
    assert "set_filters" in shared and "set_load" in shared
    for name in shared:
        ours = inspect.signature(getattr(RobotProxy, name)).parameters
        theirs = inspect.signature(getattr(Robot, name)).parameters
        assert list(ours) == list(theirs), name


def test_named_filter_frequencies_reach_the_robot(reset_panda: panda_py.Panda) -> None:
    panda = reset_panda
    robot = panda.get_robot()  # a FER on protocol 5, which has SetFilters
    robot.set_filters(
        joint_position_filter_frequency=100.0, joint_velocity_filter_frequency=100.0,
        cartesian_position_filter_frequency=100.0, cartesian_velocity_filter_frequency=100.0,
        controller_filter_frequency=100.0,
    )  # fmt: skip
    robot.set_filters(1000.0, 1000.0, 1000.0, 1000.0, 1000.0)
    with pytest.raises(ValueError, match=r"1\.\.1000 Hz"):
        robot.set_filters(0.5, 1000.0, 1000.0, 1000.0, 1000.0)
    robot.set_load(load_mass=0.0, F_x_Cload=[0.0, 0.0, 0.0], load_inertia=np.zeros(9))
