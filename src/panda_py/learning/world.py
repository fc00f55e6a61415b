"""The fast training world: the simulated robot in this process, driven at 1 kHz by the
same streamed-target controllers a ``Panda`` runs, with no network in between.

What runs is what ``panda-sim`` and a ``Panda`` run, minus the sockets: the simulator's
robot core (:class:`panda_py.sim.robot.RobotCore`: its mode machine, its limit checks and
reflexes, the MuJoCo physics of :mod:`panda_py.sim.physics`) and its hand
(:class:`panda_py.sim.gripper.GripperCore`); the state each tick is the robot's wire
datagram (:class:`panda_py.sim.wire.StateWire`) read through libfranka's ``TickState``, as
the control process reads it; the controller's torques pass the control process's
finishing (:class:`panda_py.controllers.laws.JointWalls`: joint walls, torque-rate
saturation, torque limits) and libfranka's 100 Hz low-pass filter before the robot checks
and applies them. Nothing is random: the same commands give the same episode.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from panda_py import fci
from panda_py.controllers import CartesianTarget, JointTarget, TorqueController, laws
from panda_py.controllers.finalize import FILTER_GAIN
from panda_py.controllers.model import ControlModel
from panda_py.fci import ERROR_NAMES, MoveControllerMode, MoveMotionGeneratorMode, RobotMode
from panda_py.learning.backend import Backend, Snapshot
from panda_py.libfranka.state import TickState
from panda_py.robots.params import FRANKA_HAND, START_POSE, get_robot, robot_for_protocol
from panda_py.sim.gripper import GripperCore
from panda_py.sim.physics import DT, Physics
from panda_py.sim.robot import Command, RobotCore
from panda_py.sim.wire import StateWire

__all__ = ["FastWorld"]

# A Move's maximum deviations, as libfranka sends them for a torque loop (any positive)
_DEVIATIONS = np.array([10.0, 3.12, 2.0 * math.pi])
_START_POSITION = np.array([0.31, 0.0, 0.48])  # [m] by the start pose's TCP (warm-up only)
_DOWN = np.array([1.0, 0.0, 0.0, 0.0])  # the fingers down (x, y, z, w)
GRIPPER_SPEED = 0.1  # [m/s] the hand's open and close speed
GRASP_FORCE = 20.0  # [N] the hand's grasp force


class FastWorld(Backend):
    """A simulated ``robot`` (``"fer"`` or ``"fr3"``) with the Franka Hand, the table and
    the 4 cm cube, stepped in this process at 1 kHz of simulated time (as fast as the
    computer goes); deterministic: the same start and actions give the same episode,
    bit for bit. It speaks the newest protocol version its robot's systems do (the
    state layout and limits a ``Panda`` on ``panda-sim`` would get)."""

    deterministic = True

    def __init__(self, robot: str = "fer") -> None:
        spec = self.spec = get_robot(robot)
        self.spec_name = spec.name
        self.version = max(spec.protocol_versions)
        self.dialect = fci.dialect(self.version)
        self.physics = Physics(spec, scene=True)
        self.core = RobotCore(spec, self.physics, np.asarray(START_POSE, dtype=float))
        self.hand = GripperCore(self.physics)
        self._wire = StateWire(self.dialect, self.core)
        self.model = ControlModel(spec)
        limits = robot_for_protocol(self.version)
        self._walls = laws.JointWalls(limits.joints.q_min, limits.joints.q_max)
        self._tau_max = np.array(limits.joints.tau_max)
        self._tau = np.zeros(7)
        z7 = np.zeros(7)
        self._command = Command(
            message_id=0, q_c=z7.copy(), dq_c=z7.copy(), O_T_EE_c=np.zeros(16),
            O_dP_EE_c=np.zeros(6), elbow_c=np.zeros(2), valid_elbow=False,
            motion_generation_finished=False, tau_J_d=np.zeros(7), torque_command_finished=False,
        )  # fmt: skip
        self._controller: TorqueController | None = None
        self._state: TickState | None = None
        self._hand_id = 0
        self.ticks = 0  # [ms] the robot's clock
        self._fail: str | None = None  # why the running controller stopped
        self._warm_up()

    def _warm_up(self) -> None:
        """Run both streamed controllers toward a new target for a few ticks (then
        power up again), so nothing compiles or loads in an episode's first step, as
        the control process warms its laws before its loop."""
        q = np.asarray(START_POSE, dtype=float)
        joint, pose = JointTarget(), CartesianTarget()
        for ctrl, target in ((joint, (q + 0.01,)), (pose, (_START_POSITION, _DOWN))):
            self.start(ctrl)
            ctrl.set_target(*target)
            self.advance(self.ticks + 20)
            self.stop()
        self.home(q, None)

    # --- the loop ---------------------------------------------------------------------

    def _read(self) -> TickState:
        data = bytes(self._wire.fill(self.ticks, self.core.success_rate))
        return TickState(self.dialect, data)

    def start(self, controller: TorqueController) -> None:
        """Start ``controller`` as ``Panda.start_controller`` does: the robot begins a
        torque-controlled motion and the controller runs from the next tick."""
        mode = RobotMode(self.core.robot_mode)
        if mode != RobotMode.IDLE:
            raise RuntimeError(
                f"start: the robot must be idle, it is in mode {mode.name} (recover() after a "
                "reflex)"
            )
        has_none = self.dialect.has_motion_generator_none
        # protocol <= 6 has no "no generator": a zero joint velocity one, as libfranka's
        generator = (
            MoveMotionGeneratorMode.NONE if has_none else MoveMotionGeneratorMode.JOINT_VELOCITY
        )
        status = self.core.request_move(
            int(MoveControllerMode.EXTERNAL_CONTROLLER), int(generator), _DEVIATIONS,
            has_none=has_none,
        )  # fmt: skip
        if status != fci.MoveStatus.MOTION_STARTED:
            raise RuntimeError(f"start: the robot refused the motion ({status.name})")
        state = self._read()
        controller.t = controller.dt = 0.0
        controller.start(state, self.model)
        self._walls.reset()
        self._controller = controller
        self._fail = None

    def stop(self) -> None:
        """End the running controller's motion (the arm holds where it is)."""
        if self._controller is not None and self.core.robot_mode == RobotMode.MOVE:
            self.core.request_stop_move()
        self._controller = None

    def _tick(self) -> None:
        core, ctrl = self.core, self._controller
        command = None
        if ctrl is not None and core.robot_mode == RobotMode.MOVE:
            state = self._read()
            ctrl.tick(DT)
            tau = np.ascontiguousarray(ctrl.step(state, self.model), dtype=np.float64)
            out = self._tau
            # walls, saturations and the low-pass filter, as the control process does
            if not self._walls.finalize(
                tau, state.q, state.dq, state.tau_J_d, self._tau_max, out, FILTER_GAIN
            ):
                self._fail = f"the controller commanded non-finite torques: {tau.tolist()}"
                self.stop()
            else:
                command = self._command
                command.message_id = self.ticks
                command.tau_J_d[:] = out
                ctrl.published()
        self.hand.tick()
        core.finger_force = self.hand.force
        core.tick(command if core.robot_mode == RobotMode.MOVE else None)
        self.ticks += 1
        if ctrl is not None and core.robot_mode != RobotMode.MOVE and self._fail is None:
            self._fail = "reflex: " + ", ".join(self.reflex_flags())
            self._controller = None
        self.hand.completed.clear()

    def advance(self, ms: int) -> None:
        """Run ticks (1 ms each) until the robot's clock reads ``ms``, or the controller
        stopped (a reflex)."""
        while self.ticks < ms:
            self._tick()
            if self._fail is not None:
                return

    # --- Backend ----------------------------------------------------------------------

    def time_ms(self) -> int:
        return self.ticks

    def snapshot(self) -> Snapshot:
        s = self.core.state
        return Snapshot(
            q=s["q"].copy(), dq=s["dq"].copy(),
            O_T_EE=s["O_T_EE"].reshape(4, 4).T.copy(),
            gripper_width=self.hand.width, cube=self._cube_position(), time_ms=self.ticks,
        )  # fmt: skip

    def _cube_position(self) -> np.ndarray:
        return self.physics.data.body("cube").xpos.copy()

    def failure(self) -> str | None:
        return self._fail

    def reflex_flags(self) -> list[str]:
        """The error flags of the last reflex (libfranka's ``Errors`` names)."""
        return [ERROR_NAMES[i] for i in np.flatnonzero(self.core.reflex_reason)]

    def inject_reflex(self, *flags: str) -> None:
        """Raise error flags (libfranka's ``Errors`` names) as a robot-side reflex, as
        ``Simulator.inject_reflex`` does (for fault tests)."""
        self.core.inject_reflex(list(flags or ("joint_reflex",)))

    def home(self, q: np.ndarray, cube: np.ndarray | None) -> None:
        """Teleport: power-up state at ``q`` [rad] at rest, the hand open, the cube at
        ``cube`` [m] (its centre, upright; default where the scene puts it), the clock at
        0: every episode from the same start is the same."""
        self.stop()
        self.ticks = 0
        self.core.reset(np.asarray(q, dtype=float))  # also puts the cube back
        self.hand = GripperCore(self.physics)  # open, as the reset left the fingers
        if cube is not None:
            self.place_cube(cube)
        self._fail = None

    def place_cube(self, position: Any) -> None:
        """Put the cube, upright and at rest, with its centre at ``position`` [m]."""
        self.physics.place_body("cube", np.asarray(position, dtype=float))

    def recover(self) -> None:
        self.stop()
        self.core.request_recovery()
        self._fail = None

    def hand_open(self) -> None:
        self._hand_id += 1
        self.hand.move(self._hand_id, FRANKA_HAND.max_width, GRIPPER_SPEED)

    def hand_close(self) -> None:
        self._hand_id += 1
        # close on whatever is between the fingers (any width counts as held)
        self.hand.grasp_object(self._hand_id, 0.0, 0.005, FRANKA_HAND.max_width,
                               GRIPPER_SPEED, GRASP_FORCE)  # fmt: skip

    def close(self) -> None:
        self.stop()
