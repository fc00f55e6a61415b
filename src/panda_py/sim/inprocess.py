"""The simulated robot in the caller's process: ``panda-sim``'s robot (its mode machine,
limit checks and reflexes, MuJoCo physics) with the Franka Hand, the table and the cube,
ticked by the caller 1 ms at a time with no network in between (the fast training world
of :mod:`panda_py.learning` runs on it).

The caller reads the state datagram a client would receive (:meth:`InProcessRobot.read`,
in the wire layout of the newest protocol version the robot's systems speak), answers
with torques (:meth:`InProcessRobot.tick`), and asks for what a client asks over TCP
(start and stop a torque-controlled motion, recover, the hand's commands). Where numba
runs, :meth:`InProcessRobot.compiled_tick` gives the robot's common tick as a compiled
kernel a caller's own compiled loop calls (:mod:`panda_py.sim.compiled`).
"""

from __future__ import annotations

import math
from typing import Any

import mujoco
import numpy as np

from panda_py import fci
from panda_py.fci import (
    ERROR_NAMES,
    MoveControllerMode,
    MoveMotionGeneratorMode,
    MoveStatus,
    RobotMode,
)
from panda_py.robots.params import FRANKA_HAND, START_POSE, get_robot
from panda_py.sim.fast_tick import CompiledTick, compiled_tick
from panda_py.sim.gripper import GripperCore
from panda_py.sim.physics import Physics
from panda_py.sim.robot import Command, RobotCore
from panda_py.sim.wire import StateWire

__all__ = ["InProcessRobot"]

# A Move's maximum deviations, as libfranka sends them for a torque loop (any positive)
_DEVIATIONS = np.array([10.0, 3.12, 2.0 * math.pi])


class InProcessRobot:
    """A simulated ``robot`` (``"fer"`` or ``"fr3"``) with the Franka Hand, the table and
    the 4 cm cube, at rest at ``q`` [rad], ticked in this process (:meth:`tick`, 1 ms of
    simulated time each, as fast as the computer goes); deterministic: the same requests
    and torques give the same states, bit for bit. It speaks the newest protocol version
    its robot's systems do (:attr:`version`, :attr:`dialect`). ``compiled``: the
    common tick of a torque motion compiled where numba runs (False: the Python
    reference always; the two give the same states). ``cube``: False leaves the cube
    out of the scene (a task that never uses it: the arm moves as with it wherever it
    does not touch it, and each tick's physics costs less)."""

    def __init__(
        self, robot: str = "fer", *, q: Any = START_POSE, compiled: bool = True, cube: bool = True
    ) -> None:
        spec = self.spec = get_robot(robot)
        self.version = max(spec.protocol_versions)
        self.dialect = fci.dialect(self.version)
        self.has_cube = bool(cube)
        self.physics = Physics(spec, scene=True, cube=self.has_cube)
        if not self.has_cube:
            # The robot alone (the table is fixed) is one island of constraints: MuJoCo's
            # search for islands each step finds it again, a tenth of the step. Without
            # the search the solve is the same (tests/learning/test_world_reach.py: the
            # same trajectory, bit for bit); beside the cube it is not (to 1e-10).
            self.physics.model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_ISLAND)
        self.core = RobotCore(spec, self.physics, np.asarray(q, dtype=float))
        self.hand = GripperCore(self.physics)
        self._wire = StateWire(self.dialect, self.core)
        z7 = np.zeros(7)
        self._command = Command(
            message_id=0, q_c=z7.copy(), dq_c=z7.copy(), O_T_EE_c=np.zeros(16),
            O_dP_EE_c=np.zeros(6), elbow_c=np.zeros(2), valid_elbow=False,
            motion_generation_finished=False, tau_J_d=np.zeros(7), torque_command_finished=False,
        )  # fmt: skip
        self.ticks = 0  # [ms] the robot's clock
        self._bodies: dict[str, int] = {}  # body names' ids
        self._compiled = compiled_tick(self.core) if compiled else None
        if self._compiled is not None:
            self._compiled.warm(self.hand)

    # --- the state ----------------------------------------------------------------------

    def read(self) -> bytearray:
        """The state datagram of this tick, as a client receives it (:attr:`dialect`'s
        layout; message id: the clock [ms]); a buffer the next call rewrites."""
        return self._wire.fill(self.ticks, self.core.success_rate)

    @property
    def robot_mode(self) -> RobotMode:
        """The robot's mode (idle, move, reflex, ...), as the state reports it."""
        return RobotMode(self.core.robot_mode)

    @property
    def q(self) -> np.ndarray:
        """Joint positions [rad] (7,), as the state reports them (a copy)."""
        return self.core.state["q"].copy()

    @property
    def dq(self) -> np.ndarray:
        """Joint velocities [rad/s] (7,) (a copy)."""
        return self.core.state["dq"].copy()

    @property
    def O_T_EE(self) -> np.ndarray:
        """The end effector's pose (4, 4) in the base frame [m] (a copy)."""
        return self.core.state["O_T_EE"].reshape(4, 4).T.copy()

    @property
    def tau_J_d(self) -> np.ndarray:
        """The torques [Nm] (7,) of the last command the robot took, as the state
        reports them (a copy)."""
        return self.core.state["tau_J_d"].copy()

    @property
    def gripper_width(self) -> float:
        """The fingers' opening [m], as the hand measures it."""
        return self.hand.width

    def body_position(self, name: str) -> np.ndarray:
        """Where the scene's body ``name`` (e.g. ``"cube"``) is [m] (a copy)."""
        at = self._bodies.get(name)
        if at is None:  # (MuJoCo's accessor by name: most of this call's cost, once)
            try:
                at = self._bodies[name] = self.physics.model.body(name).id
            except KeyError:
                raise ValueError(f"name: expected a body of the scene, got {name!r}") from None
        return self.physics.data.xpos[at].copy()

    def reflex_flags(self) -> list[str]:
        """The error flags of the last reflex (libfranka's ``Errors`` names)."""
        return [ERROR_NAMES[i] for i in np.flatnonzero(self.core.reflex_reason)]

    # --- what a client asks -------------------------------------------------------------

    def start_torque_control(self) -> MoveStatus:
        """Start a motion under an external (torque) controller, as libfranka's
        ``Robot.control`` with a torque callback asks: MOTION_STARTED, or why not. The
        motion's torques come from :meth:`tick` from the next tick on."""
        has_none = self.dialect.has_motion_generator_none
        # protocol <= 6 has no "no generator": a zero joint velocity one, as libfranka's
        generator = (
            MoveMotionGeneratorMode.NONE if has_none else MoveMotionGeneratorMode.JOINT_VELOCITY
        )
        return self.core.request_move(
            int(MoveControllerMode.EXTERNAL_CONTROLLER), int(generator), _DEVIATIONS,
            has_none=has_none,
        )  # fmt: skip

    def stop_motion(self) -> None:
        """End a running motion (the arm holds where it is)."""
        if self.core.robot_mode == RobotMode.MOVE:
            self.core.request_stop_move()

    def recover(self) -> None:
        """Stop, and recover from a reflex (automatic error recovery)."""
        self.stop_motion()
        self.core.request_recovery()

    def inject_reflex(self, *flags: str) -> None:
        """Raise error flags (libfranka's ``Errors`` names; default ``joint_reflex``) as a
        robot-side reflex, as ``Simulator.inject_reflex`` does (for fault tests)."""
        self.core.inject_reflex(list(flags or ("joint_reflex",)))

    def reset(self, q: Any) -> None:
        """Power-up state at ``q`` [rad] at rest, the hand open, the cube where the scene
        puts it, the clock at 0."""
        self.ticks = 0
        self.core.reset(np.asarray(q, dtype=float))  # also puts the cube back
        self.hand = GripperCore(self.physics)  # open, as the reset left the fingers

    def place_body(self, name: str, position: Any) -> None:
        """Put the scene's free body ``name`` (e.g. ``"cube"``), upright and at rest, with
        its origin at ``position`` [m]."""
        self.physics.place_body(name, np.asarray(position, dtype=float))

    def hand_move(self, command_id: int, width: float, speed: float) -> None:
        """Start moving the fingers to ``width`` [m] at ``speed`` [m/s]."""
        self.hand.move(command_id, width, speed)

    def hand_grasp(self, command_id: int, width: float, epsilon_inner: float,
                   epsilon_outer: float, speed: float, force: float) -> None:  # fmt: skip
        """Start a grasp (libfranka's ``Gripper::grasp``: close at ``speed`` [m/s] until
        the fingers stall, then hold with ``force`` [N])."""
        self.hand.grasp_object(command_id, width, epsilon_inner, epsilon_outer, speed, force)

    @property
    def hand_max_width(self) -> float:
        """The hand's widest opening [m]."""
        return float(FRANKA_HAND.max_width)

    # --- the tick -----------------------------------------------------------------------

    def tick(self, tau: np.ndarray | None) -> None:
        """One tick (1 ms): the hand, then the robot with the torque command ``tau`` (7,)
        [Nm] (None: none this tick; ignored outside a motion), then the physics."""
        core, hand = self.core, self.hand
        command = None
        moving = core.robot_mode == RobotMode.MOVE
        fast = self._compiled
        if tau is not None and moving and fast is not None and fast.command(tau, hand):
            self.ticks += 1
            return
        if tau is not None and moving:
            command = self._command
            command.message_id = self.ticks
            command.tau_J_d[:] = tau
        hand.tick()
        core.finger_force = hand.force
        core.tick(command)
        self.ticks += 1
        hand.completed.clear()

    def compiled_tick(self) -> CompiledTick | None:
        """The robot's common tick compiled (:func:`panda_py.sim.compiled.torque_tick`),
        or None where it runs in Python only (no numba, ``PANDA_PY_NO_JIT=1``)."""
        return self._compiled
