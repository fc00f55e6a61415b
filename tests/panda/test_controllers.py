"""Each controller moves the simulated arm as its law says, its inputs changeable while it
runs; a user-written Python controller runs at 1 kHz in the control process."""

from __future__ import annotations

import time
from typing import Any, ClassVar

import numpy as np
import pytest

import panda_py
from panda_py import constants, controllers, jit
from panda_py.rt.shm import HEADER

pytestmark = pytest.mark.timeout(120)
# whether the control process runs the built-in laws' ticks compiled (numba, no
# PANDA_PY_NO_JIT: the control process has the environment this process has)
COMPILED = jit.enabled()


@pytest.fixture
def panda(reset_panda: panda_py.Panda) -> panda_py.Panda:
    """The module's Panda, reset before each test (conftest.reset_panda): no test here
    needs a fresh process or simulator, and starting them took about 2 s a test."""
    return reset_panda


def _run_for(panda: panda_py.Panda, ctrl: controllers.TorqueController, seconds: float) -> None:
    """Wait until the controller has run ``seconds`` of robot time."""
    deadline = time.monotonic() + 60.0
    while ctrl.get_time() < seconds:
        panda.raise_error()
        assert time.monotonic() < deadline, "the controller's time does not advance"
        time.sleep(0.005)


def test_joint_position_reaches_target_and_takes_new_ones(panda: panda_py.Panda) -> None:
    ctrl = controllers.JointPosition(filter_coeff=0.003)  # a step target, filtered
    panda.start_controller(ctrl)
    assert panda.is_moving()
    target = constants.JOINT_POSITION_START + np.array([0.2, -0.1, 0.1, 0.1, 0.0, 0.1, -0.2])
    ctrl.set_control(target)
    _run_for(panda, ctrl, 3.0)
    assert np.abs(panda.q - target).max() < 0.02
    ctrl.set_stiffness(np.array([800.0] * 4 + [300.0] * 3))
    ctrl.set_control(constants.JOINT_POSITION_START)
    _run_for(panda, ctrl, 6.0)
    assert np.abs(panda.q - constants.JOINT_POSITION_START).max() < 0.02
    panda.stop_controller()
    assert not panda.is_moving()
    t = ctrl.get_time()
    assert t >= 6.0 and ctrl.get_time() == t  # frozen after the stop


def test_integrated_velocity_integrates(panda: panda_py.Panda) -> None:
    ctrl = controllers.IntegratedVelocity()
    panda.start_controller(ctrl)
    q0 = ctrl.get_qd()
    assert np.allclose(q0, panda.q, atol=1e-3)
    velocity = np.array([0.1, 0, 0, 0, 0, 0, -0.1])
    ctrl.set_control(velocity)
    t0 = ctrl.get_time()
    _run_for(panda, ctrl, t0 + 1.0)
    ctrl.set_control(np.zeros(7))
    t1 = ctrl.get_time()
    qd = ctrl.get_qd()
    moved = qd - q0
    assert moved[0] == pytest.approx(0.1 * (t1 - t0), abs=0.02)
    assert moved[6] == pytest.approx(-0.1 * (t1 - t0), abs=0.02)
    assert np.abs(moved[1:6]).max() < 1e-9
    _run_for(panda, ctrl, t1 + 1.0)
    assert np.abs(panda.q - ctrl.get_qd()).max() < 0.02
    panda.stop_controller()


def test_applied_torque_and_teaching_mode(panda: panda_py.Panda) -> None:
    ctrl = controllers.AppliedTorque(damping=np.full(7, 2.0))
    panda.start_controller(ctrl)
    q0 = panda.q
    ctrl.set_control([0, 0, 0, 0, 0, 0, 1.0])  # joint 7 is pushed positive
    _run_for(panda, ctrl, 0.3)
    assert panda.q[6] - q0[6] > 0.01
    panda.stop_controller()
    panda.teaching_mode(True)
    assert panda.is_moving()
    panda.teaching_mode(False)
    assert not panda.is_moving()


def _compiled_ticks(panda: panda_py.Panda) -> int:
    """The ticks the control process ran compiled so far."""
    return int(panda._proc.block.header[HEADER.COMPILED])


def _ran_compiled(panda: panda_py.Panda, before: int, ctrl: controllers.TorqueController) -> None:
    """Where the ticks are compiled, all but a few of ``ctrl``'s ran so."""
    ran = _compiled_ticks(panda) - before
    if COMPILED:
        assert ran >= 1000.0 * ctrl.get_time() - 5
    else:
        assert ran == 0


def test_applied_force_pushes_the_end_effector(panda: panda_py.Panda) -> None:
    ctrl = controllers.AppliedForce(damping=np.full(7, 5.0))
    before = _compiled_ticks(panda)
    panda.start_controller(ctrl)
    z0 = panda.get_position()[2]
    ctrl.set_control([0, 0, 5.0, 0, 0, 0])  # 5 N up
    _run_for(panda, ctrl, 0.4)
    assert panda.get_position()[2] - z0 > 0.005
    panda.stop_controller()
    _ran_compiled(panda, before, ctrl)


def test_cartesian_impedance_holds_and_moves(panda: panda_py.Panda) -> None:
    ctrl = controllers.CartesianImpedance(filter_coeff=0.05)
    panda.start_controller(ctrl)
    x0, q0 = panda.get_position(), panda.get_orientation()
    x_d = x0 + np.array([0.0, 0.05, -0.05])
    ctrl.set_control(x_d, q0)
    ctrl.set_impedance(np.diag([900.0] * 3 + [40.0] * 3))
    _run_for(panda, ctrl, 3.0)
    assert np.linalg.norm(panda.get_position() - x_d) < 5e-3
    panda.stop_controller()


def test_force_controller_aborts_past_its_threshold(panda: panda_py.Panda) -> None:
    ctrl = controllers.Force(threshold=0.005, filter_coeff=1.0)
    assert ctrl.name == "Force Controller"
    before = _compiled_ticks(panda)
    panda.start_controller(ctrl)
    ctrl.set_control([0, 0, -10.0])  # nothing to push against: the arm moves, then aborts
    deadline = time.monotonic() + 30
    while panda.is_moving() and time.monotonic() < deadline:
        time.sleep(0.01)
    assert not panda.is_moving()
    with pytest.raises(panda_py.libfranka.ControlException, match="threshold") as caught:
        panda.raise_error()
    moved = float(str(caught.value).split("(")[1].split(" m >")[0])
    assert 0.005 < moved < 0.006  # the first tick past it (the arm moves < 1 mm a tick)
    assert ctrl.get_time() > 0.02  # it pushed for a while first
    _ran_compiled(panda, before, ctrl)


class Spring(controllers.TorqueController):
    """A user-written law: a joint spring toward ``target``, counting its ticks."""

    signals: ClassVar[dict[str, int]] = {"target": 7, "gain": 1}
    outputs: ClassVar[dict[str, int]] = {"ticks": 1}

    def start(self, state: Any, model: Any) -> None:
        self.initial_signals(target=state.q, gain=[200.0])
        self.ticks = 0

    def step(self, state: Any, model: Any) -> np.ndarray:
        self.ticks += 1
        self.set_output("ticks", [self.ticks])
        k = self.signal("gain")[0]
        return k * (self.signal("target") - state.q) - 10.0 * state.dq


def test_user_written_controller_runs_in_the_control_process(panda: panda_py.Panda) -> None:
    ctrl = Spring()
    panda.start_controller(ctrl)
    target = panda.q + np.array([0.05, 0, 0, 0.05, 0, 0, 0])
    ctrl.set_signals(target=target, gain=300.0)
    _run_for(panda, ctrl, 2.0)
    assert np.abs(panda.q - target).max() < 0.02
    ticks = ctrl.get_output("ticks")[0]
    assert ticks == pytest.approx(ctrl.get_time() * 1000, abs=5)  # one step per 1 ms tick
    with pytest.raises(ValueError, match="target"):
        ctrl.set_signals(target=[1, 2, 3])
    with pytest.raises(ValueError, match="expected one of the signals"):
        ctrl.set_signals(nothing=1.0)
    panda.stop_controller()


class Broken(controllers.TorqueController):
    def step(self, state: Any, model: Any) -> np.ndarray:
        raise ZeroDivisionError("user bug")


class Bad(controllers.TorqueController):
    def step(self, state: Any, model: Any) -> np.ndarray:
        return np.full(7, np.nan)


def test_a_started_controller_or_move_shows_as_moving_at_once(panda: panda_py.Panda) -> None:
    # from the moment start_controller (or an asynchronous move) returns, not only once the
    # robot has accepted the motion a millisecond or two later: a loop of
    # `while panda.is_moving()` after it must not end before it began
    for _ in range(5):
        panda.start_controller(controllers.AppliedTorque())
        assert panda.is_moving()
        panda.stop_controller()
        assert not panda.is_moving()
    handle = panda.move_to_joint_position(panda.q + 0.05, asynchronous=True)
    assert panda.is_moving()
    assert handle.wait(30.0)


@pytest.mark.parametrize(
    ("ctrl", "error"), [(Broken(), ZeroDivisionError), (Bad(), panda_py.libfranka.ControlException)]
)
def test_a_failing_user_controller_stops_with_its_error(
    panda: panda_py.Panda, ctrl: controllers.TorqueController, error: type
) -> None:
    panda.start_controller(ctrl)
    deadline = time.monotonic() + 10
    while panda.is_moving() and time.monotonic() < deadline:
        time.sleep(0.005)
    with pytest.raises(error):
        panda.raise_error()
    assert panda.move_to_start()  # the robot is usable again


@pytest.mark.parametrize("space", ["joint", "pose"])
def test_a_moves_ticks_run_compiled_through_its_settling(panda: panda_py.Panda,
                                                         space: str) -> None:  # fmt: skip
    """A move's ticks run compiled while it follows its plan and while it settles at its
    goal past the trajectory's end: Python's are its first and its last, and no more than
    a few others (the state it ends on is Python's, which judges it). (The settling's
    torques against the Python step's: tests/rt/test_fast_ticks.py.)"""
    q = np.asarray(panda.q)
    before = _compiled_ticks(panda)
    if space == "joint":
        handle = panda.move_to_joint_position(q + 0.15, asynchronous=True)
    else:  # a soft impedance, which the friction holds off the goal at the trajectory's
        # end (at the default one the moves end with their trajectory: test_move_ends.py)
        soft = np.diag([100.0] * 3 + [5.0] * 3)
        handle = panda.move_to_pose(np.add(panda.get_position(), [0.05, -0.04, 0.03]),
                                    panda.get_orientation(), impedance=soft,
                                    asynchronous=True)  # fmt: skip
    assert handle.wait(60.0)
    result = handle.result
    assert result is not None and result.success, result
    ticks, ran = round(1e3 * result.elapsed), _compiled_ticks(panda) - before
    if space == "pose":  # (it settles for some ticks; a joint move ends with its
        assert result.elapsed > result.duration + 0.01  # trajectory on the simulator)
    if COMPILED:
        assert ran >= ticks - 4, (ticks, ran, result)
    else:
        assert ran == 0


@pytest.mark.parametrize("space", ["joint", "pose"])
def test_a_move_that_replaces_another_leads_in_compiled(panda: panda_py.Panda,
                                                        space: str) -> None:  # fmt: skip
    """A move replacing a running one leads in from its reference with the ticks
    compiled, as the plan it joins and its settling: Python's are the hand-over's (ruckig
    calculates the lead-in; a Cartesian one again on its refined limits), the lead-in's
    end and the end."""
    q, x, rot = np.asarray(panda.q), panda.get_position(), panda.get_orientation()

    def move(offset: float) -> Any:
        if space == "joint":
            return panda.move_to_joint_position(q + offset, asynchronous=True)
        return panda.move_to_pose(np.add(x, [offset * 0.4, -offset * 0.3, 0.0]), rot,
                                  asynchronous=True)  # fmt: skip

    before = _compiled_ticks(panda)
    first = move(0.2)
    deadline = time.monotonic() + 30.0
    while np.abs(np.asarray(panda.q) - q).max() < 0.03:  # some way along
        assert time.monotonic() < deadline and not first.done()
        time.sleep(0.0005)
    second = move(-0.1)
    assert second.wait(60.0) and first.done()
    one, two = first.result, second.result
    assert one is not None and one.cancelled and two is not None and two.success, (one, two)
    ticks, ran = round(1e3 * (one.elapsed + two.elapsed)), _compiled_ticks(panda) - before
    if COMPILED:
        assert ran >= ticks - 8, (ticks, ran)
    else:
        assert ran == 0


def test_without_the_jit_the_built_in_laws_tick_in_python() -> None:
    """``PANDA_PY_NO_JIT=1``: the built-in laws still offer their compiled form, and the
    control process runs them in Python instead (it once took the offer, found no loop
    kernels and ended the motion with a bare AssertionError: teaching mode failed)."""
    from panda_py.sim import Simulator, free_loopback_host

    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("PANDA_PY_NO_JIT", "1")
        with (
            Simulator(free_loopback_host(), lockstep=True) as sim,
            panda_py.Panda(sim.host) as panda,
        ):
            panda.teaching_mode(True)  # AppliedTorque
            time.sleep(0.2)
            panda.raise_error()
            panda.teaching_mode(False)
            ctrl = controllers.JointPosition()
            panda.start_controller(ctrl)
            _run_for(panda, ctrl, 0.3)
            panda.raise_error()
            panda.stop_controller()
            assert _compiled_ticks(panda) == 0
            assert np.abs(panda.q - np.asarray(constants.JOINT_POSITION_START)).max() < 0.01
