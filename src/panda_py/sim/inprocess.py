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

import numpy as np

from panda_py import fci
from panda_py.fci import (
    ERROR_NAMES,
    ControllerMode,
    MotionGeneratorMode,
    MoveControllerMode,
    MoveMotionGeneratorMode,
    MoveStatus,
    RobotMode,
)
from panda_py.robots.params import FRANKA_HAND, START_POSE, get_robot
from panda_py.sim import gripper
from panda_py.sim.gripper import GripperCore
from panda_py.sim.physics import DT, Physics
from panda_py.sim.robot import Command, RobotCore
from panda_py.sim.safety import joint_limit_vectors
from panda_py.sim.wire import StateWire

__all__ = ["CompiledTick", "InProcessRobot"]

# A Move's maximum deviations, as libfranka sends them for a torque loop (any positive)
_DEVIATIONS = np.array([10.0, 3.12, 2.0 * math.pi])


class InProcessRobot:
    """A simulated ``robot`` (``"fer"`` or ``"fr3"``) with the Franka Hand, the table and
    the 4 cm cube, at rest at ``q`` [rad], ticked in this process (:meth:`tick`, 1 ms of
    simulated time each, as fast as the computer goes); deterministic: the same requests
    and torques give the same states, bit for bit. It speaks the newest protocol version
    its robot's systems do (:attr:`version`, :attr:`dialect`)."""

    def __init__(self, robot: str = "fer", *, q: Any = START_POSE) -> None:
        spec = self.spec = get_robot(robot)
        self.version = max(spec.protocol_versions)
        self.dialect = fci.dialect(self.version)
        self.physics = Physics(spec, scene=True)
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
        self._compiled: CompiledTick | None = None
        if self.core.compiled:
            try:
                self._compiled = CompiledTick(self)
            except ImportError:  # numba without the parts the whole tick needs
                self._compiled = None

    # --- the state ----------------------------------------------------------------------

    def read(self) -> bytearray:
        """The state datagram of this tick, as a client receives it (:attr:`dialect`'s
        layout; message id: the clock [ms]); a buffer the next call rewrites."""
        return self._wire.fill(self.ticks, self.core.success_rate)

    @property
    def robot_mode(self) -> RobotMode:
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
        return self.physics.data.body(name).xpos.copy()

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
        return float(FRANKA_HAND.max_width)

    # --- the tick -----------------------------------------------------------------------

    def tick(self, tau: np.ndarray | None) -> None:
        """One tick (1 ms): the hand, then the robot with the torque command ``tau`` (7,)
        [Nm] (None: none this tick; ignored outside a motion), then the physics."""
        core, hand = self.core, self.hand
        command = None
        if tau is not None and core.robot_mode == RobotMode.MOVE:
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


class CompiledTick:
    """The compiled tick of one :class:`InProcessRobot`, for a caller's compiled loop:
    :meth:`enter` says whether the next ticks may run compiled and gives the kernel's
    arguments after the torques (``torque_tick(tau, *args)``); :meth:`leave` takes the
    robot back after ``ticks`` compiled ticks and the last one's status, doing the part
    the kernel left (the state's fill) -- a ``ROBOT`` or ``WHOLE`` status leaves the
    caller to run that tick by :meth:`InProcessRobot.tick`."""

    def __init__(self, robot: InProcessRobot) -> None:
        from panda_py.sim import compiled

        self._k = compiled
        self.kernel = compiled.torque_tick
        self.measured_ok = compiled.measured_ok
        self._robot = robot
        ph = robot.physics
        core = robot.core
        self.ints = np.zeros(compiled.INTS, dtype=np.int64)
        self.ints[compiled.I_MODEL] = ph.model._address
        self.ints[compiled.I_DATA] = ph.data._address
        self.ints[compiled.I_FINGER_ACT] = ph.finger_act
        self.ints[compiled.I_FINGER_Q] = ph.finger_q
        self.ints[compiled.I_FINGER_Q2] = ph.finger_q2
        self.ints[compiled.I_FINGER_V] = ph.finger_v
        self.hand = np.zeros(compiled.HAND)
        self.gains = np.array((*gripper.SERVO_GAINS, gripper.FORCE_RATE * DT, DT))
        robot_geom = np.asarray(ph.robot_geoms, dtype=np.uint8)
        self._contacts = (*compiled.contact_views(ph.model, ph.data), robot_geom)
        self._fk = np.zeros((2, 4, 4))
        self._scratch = np.zeros((4, 7))
        self._off = np.array([core.state_offsets[n][0] for n in compiled.FILL_FIELDS],
                             dtype=np.int64)  # fmt: skip
        self._upper, self._lower = joint_limit_vectors(core.spec)
        self._moving = {MotionGeneratorMode.NONE: 0,
                        MotionGeneratorMode.JOINT_VELOCITY: compiled.MOVING_JOINT}  # fmt: skip

    def enter(self) -> tuple[tuple[Any, ...], tuple[Any, ...]] | None:
        """Where the next ticks may run compiled (a torque-controlled motion under way,
        its first command accepted, the hand holding, nothing touching the robot): the
        kernel's arguments after the torques, and :func:`~panda_py.sim.compiled.measured_ok`'s
        (whether a tick may start compiled); else None (tick in Python)."""
        robot = self._robot
        core, hand, ph = robot.core, robot.hand, robot.physics
        mg = core.mg_mode
        if (
            core.robot_mode != RobotMode.MOVE
            or core.ctrl_mode != ControllerMode.EXTERNAL_CONTROLLER
            or mg not in self._moving
            or core.first_command
            or core.async_gen is not None
            or core.contact_active
            or hand.action is not None
            or not core.compiled_fill_ready()
        ):
            return None
        k, ints, h = self._k, self.ints, self.hand
        ints[k.I_FLAGS] = self._moving[mg]
        ints[k.I_JOINT_GENERATOR] = int(mg == MotionGeneratorMode.JOINT_VELOCITY)
        ints[k.I_RECEIVED] = core.received_total
        ints[k.I_SUCCESS_COUNT] = core.success_count
        ints[k.I_SUCCESS_I] = core.success_i
        h[k.H_HOLD] = hand.hold_width
        h[k.H_FORCE] = hand.force
        h[k.H_GRASP_FORCE] = math.nan if hand.grasp is None else hand.grasp.force
        h[k.H_MAX_WIDTH] = hand.max_width
        joint, cart, d = core.joint, core.cart, ph.data
        v0 = ph.v0
        links, const = core.compiled_fill_constants()
        check = (d.qpos, d.qvel, ph.q0, v0, *core.measured_limits())
        return (
            ints, h, self.gains, d.qpos, d.qvel, ph.q0, v0, d.ctrl, ph.applied_arm,
            ph.tau_applied, ph.gravity_torque(), self._contacts, d.xmat,
            core.state_buffer, self._off, core.tau_J_d, core.tau_max, core.dtau_step,
            core.tau_ext, core.q_hold, joint.q, joint.dq, joint.ddq, joint.dddq, self._upper,
            self._lower, cart.T, cart.v, cart.a, core.elbow_c, core.delbow_c, core.ddelbow_c,
            np.frombuffer(core.success, dtype=np.uint8), self._fk, core.chain_constants(),
            links, const, self._scratch,
        ), check  # fmt: skip

    def leave(self, ticks: int, status: int) -> None:
        """Take the robot back after ``ticks`` ticks the kernel completed (counting one
        it left the fill of) and the last call's ``status``: the counters and the hand's
        force back, and the fill's part it left done here."""
        if ticks == 0:
            return
        robot, k = self._robot, self._k
        core, ints = robot.core, self.ints
        core.received_total = int(ints[k.I_RECEIVED])
        core.success_count = int(ints[k.I_SUCCESS_COUNT])
        core.success_i = int(ints[k.I_SUCCESS_I])
        core.success_rate = core.success_count / len(core.success)
        core.consecutive_lost = 0
        robot.hand.force = core.finger_force = float(self.hand[k.H_FORCE])
        robot.ticks += ticks
        if status == k.Tick.FILL:
            core.fill_state()
        elif status == k.Tick.CONTACTS:
            core.fill_contacts()
