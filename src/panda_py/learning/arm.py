"""The robot backend: an environment on any ``Panda`` (a Franka robot, or ``panda-sim``,
in lockstep in tests), through the streamed-target controllers in its control process.

The policy's steps follow the robot's clock (every ``1 / policy_rate`` of it: the wall
clock on a robot; a simulator in lockstep keeps its own pace). The cube is where the
``scene`` puts it: a :class:`~panda_py.sim.Simulator` places it itself
(``Simulator.place_cube``) and reports where it is; on a real robot, pass an object with
the same two methods (``place_cube(position)``, e.g. asking a person to put it there and
waiting for the answer; ``cube_position()``, e.g. from a camera), or none for reaching.
"""

from __future__ import annotations

import threading
import time
from typing import Any, Protocol

import numpy as np

from panda_py.controllers import TorqueController
from panda_py.learning.backend import Backend, FloatArray, Snapshot
from panda_py.libfranka import Gripper, RobotMode
from panda_py.panda import Panda
from panda_py.robots.params import FRANKA_HAND

__all__ = ["RobotArm", "Scene"]

POLL = 2e-4  # [s] how often the robot's clock is read while waiting for it
CLOCK_TIMEOUT = 30.0  # [s] of wall time the robot's clock may stand still before it counts as gone
LOOP_END_TIMEOUT = 5.0  # [s] for the control process to end its loop after a reflex
HOME_SPEED_FACTOR = 0.3  # of the joint limits, the move home
GRIPPER_SPEED = 0.1  # [m/s] the hand's open and close speed
GRASP_FORCE = 20.0  # [N] the hand's grasp force


class Scene(Protocol):
    """Who places the cube and tells where it is (a ``Simulator`` is one)."""

    def place_cube(self, position: Any) -> None:
        """Have the cube's centre at ``position`` [m] (base frame), upright, at rest."""
        ...

    def cube_position(self) -> Any:
        """Where the cube's centre is [m], (3,)."""
        ...


class RobotArm(Backend):
    """The robot at ``hostname`` (its FCI address), with its hand when ``hand`` (what
    picking needs), and the ``scene`` that places the cube (see the module). ``panda``:
    an already connected ``Panda`` to use instead of connecting (it is not closed then)."""

    def __init__(
        self,
        hostname: str,
        *,
        scene: Scene | None = None,
        hand: bool = True,
        panda: Panda | None = None,
    ) -> None:
        self._own = panda is None
        self.panda = Panda(hostname) if panda is None else panda
        try:
            self.gripper = Gripper(hostname) if hand else None
        except BaseException:
            if self._own:
                self.panda.close()
            raise
        self.scene = scene
        self.has_hand = self.gripper is not None
        self.has_cube = scene is not None
        self.spec_name = self.panda.get_model().spec.name
        self._running = False
        # the hand reports at 100 Hz: a thread keeps its newest width, so an observation
        # never waits up to 10 ms for the next report
        self._width: float | None = None
        self._closing = threading.Event()
        self._watch: threading.Thread | None = None
        if self.gripper is not None:
            self._watch = threading.Thread(
                target=self._watch_hand, args=(self.gripper,), name="panda_py-hand", daemon=True
            )
            self._watch.start()

    def _watch_hand(self, gripper: Gripper) -> None:
        while not self._closing.is_set():
            try:
                self._width = float(gripper.read_once().width)
            except Exception:  # closed (or gone): the next snapshot reads, and says so
                self._width = None
                return

    def _hand_width(self) -> float:
        if self.gripper is None:
            return 0.0
        width = self._width
        return float(self.gripper.read_once().width) if width is None else width

    def time_ms(self) -> int:
        return int(self.panda.get_state().time.to_msec())

    def snapshot(self) -> Snapshot:
        state = self.panda.get_state()
        width = self._hand_width()
        cube = None
        if self.scene is not None:
            cube = np.asarray(self.scene.cube_position(), dtype=np.float64)
        return Snapshot(
            q=state.q, dq=state.dq, O_T_EE=state.O_T_EE.reshape(4, 4).T.copy(),
            gripper_width=float(width), cube=cube, time_ms=int(state.time.to_msec()),
        )  # fmt: skip

    def start(self, controller: TorqueController) -> None:
        self.panda.start_controller(controller)
        self._running = True

    def stop(self) -> None:
        if self._running:
            self._running = False
            self.panda.stop_controller()

    def advance(self, ms: int) -> None:
        panda = self.panda
        last, still = -1, time.monotonic()
        while True:
            state = panda.get_state()
            now = int(state.time.to_msec())
            if now >= ms or (self._running and self._ended(state)):
                return
            if now != last:
                last, still = now, time.monotonic()
            elif time.monotonic() - still > CLOCK_TIMEOUT:
                raise TimeoutError(f"advance: the robot's clock stood still at {now} ms for "
                                   f"{CLOCK_TIMEOUT} s")  # fmt: skip
            time.sleep(POLL)

    def _ended(self, state: Any) -> bool:
        """Whether the controller stopped, or the robot has just stopped it (a reflex the
        control process has yet to see)."""
        return state.robot_mode == RobotMode.kReflex or not self.panda.is_moving()

    def failure(self) -> str | None:
        if not self._running or not self._ended(self.panda.get_state()):
            return None
        self._running = False
        # the control process ends its loop at the reflex: wait for it to say why
        deadline = time.monotonic() + LOOP_END_TIMEOUT
        while self.panda.is_moving() and time.monotonic() < deadline:
            time.sleep(POLL)
        state = self.panda.get_state()
        flags = list(state.last_motion_errors.active) or list(state.current_errors.active)
        try:
            self.panda.raise_error()
        except Exception as exc:  # the loop's error: what ended the controller
            reason = f"{type(exc).__name__}: {exc}"
        else:
            reason = "the controller stopped"
        if flags and state.robot_mode == RobotMode.kReflex:
            return f"reflex: {', '.join(flags)} ({reason})"
        return reason

    def home(self, q: FloatArray, cube: FloatArray | None) -> None:
        self.stop()
        self.panda.recover()
        if self.gripper is not None:
            self.gripper.move(FRANKA_HAND.max_width, GRIPPER_SPEED)
        for attempt in (1, 2):  # a reflex on the way (e.g. a bump): recover, once more
            if self.panda.move_to_joint_position(np.asarray(q), speed_factor=HOME_SPEED_FACTOR):
                break
            if attempt == 2:
                raise RuntimeError(
                    "reset: the arm did not reach its home pose (see the log for why); "
                    "clear its way and reset again"
                )
            self.panda.recover()
        if cube is not None:
            if self.scene is None:
                raise ValueError(
                    "scene: this task places the cube; give RobotArm a scene (a Simulator, or "
                    "an object with place_cube(position) and cube_position())"
                )
            self.scene.place_cube(cube)

    def recover(self) -> None:
        self.stop()
        self.panda.recover()

    def hand_open(self) -> None:
        if self.gripper is not None:
            self.gripper.move(FRANKA_HAND.max_width, GRIPPER_SPEED, asynchronous=True)

    def hand_close(self) -> None:
        if self.gripper is not None:
            self.gripper.grasp(0.0, GRIPPER_SPEED, GRASP_FORCE, 0.005, FRANKA_HAND.max_width,
                               asynchronous=True)  # fmt: skip

    def close(self) -> None:
        self._closing.set()
        try:
            if self.gripper is not None:
                self.gripper.close()
            if self._watch is not None:
                self._watch.join(timeout=5.0)
        finally:
            if self._own:
                self.panda.close()
            else:
                self.stop()
