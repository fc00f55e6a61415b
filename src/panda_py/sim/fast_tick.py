"""The compiled tick of a simulated robot (:func:`panda_py.sim.compiled.torque_tick`)
bound to one :class:`~panda_py.sim.robot.RobotCore` and its physics: which ticks it may
run, its arguments, and the robot taken back after it (its counters, the hand's force,
the part of the state's fill it left). Used by :class:`~panda_py.sim.inprocess.InProcessRobot`
(for a caller's compiled loop) and by the server's tick (a torque command at a time)."""

from __future__ import annotations

import math
import operator
from typing import Any

import numpy as np

from panda_py.fci import ControllerMode, MotionGeneratorMode, RobotMode
from panda_py.sim import gripper
from panda_py.sim.gripper import GripperCore
from panda_py.sim.physics import DT
from panda_py.sim.robot import RobotCore
from panda_py.sim.safety import joint_limit_vectors

__all__ = ["CompiledTick", "compiled_tick"]


def compiled_tick(core: RobotCore) -> CompiledTick | None:
    """``core``'s compiled tick, or None where its tick runs in Python only (no numba,
    ``PANDA_PY_NO_JIT=1``, a MuJoCo whose memory is not laid out as expected)."""
    if not core.compiled:
        return None
    try:
        return CompiledTick(core)
    except ImportError:
        return None


class CompiledTick:
    """The compiled tick (:func:`panda_py.sim.compiled.torque_tick`) of one robot core
    and its physics, for a caller's compiled loop or the server's tick: :meth:`enter`
    says whether the next ticks may run compiled and gives the kernel's arguments after
    the torques (``torque_tick(tau, *args)``); :meth:`leave` takes the robot back after
    ``ticks`` compiled ticks and the last one's status, doing the part the kernel left
    (the state's fill). A ``ROBOT`` status leaves the robot's part of that tick to the
    reference (:meth:`RobotCore.tick`, the hand's tick before it)."""

    def __init__(self, core: RobotCore) -> None:
        from panda_py.sim import compiled

        self._k = compiled
        self.kernel = compiled.torque_tick
        self._core = core
        ph = self._physics = core.physics
        self.ints = np.zeros(compiled.INTS, dtype=np.int64)
        self.ints[compiled.I_MODEL] = ph.model._address
        self.ints[compiled.I_DATA] = ph.data._address
        self.hand = np.zeros(compiled.HAND)
        self.gains = np.array((*gripper.SERVO_GAINS, gripper.FORCE_RATE * DT, DT))
        robot_geom = np.asarray(ph.robot_geoms, dtype=np.uint8)
        self._contacts = (*compiled.contact_views(ph.model, ph.data), robot_geom)
        self._cull = compiled.contact_cull(ph.model, ph.data)
        self._fk = np.zeros((2, 4, 4))
        self._scratch = np.zeros((4, 7))
        self._off = np.array([core.state_offsets[n][0] for n in compiled.FILL_FIELDS],
                             dtype=np.int64)  # fmt: skip
        self._upper, self._lower = joint_limit_vectors(core.spec)
        self._moving = {MotionGeneratorMode.NONE: 0,
                        MotionGeneratorMode.JOINT_VELOCITY: compiled.MOVING_JOINT}  # fmt: skip
        self._entry: Any = None
        self._tau = np.zeros(7)  # the command's torques, as the kernel takes them
        self.ticks_run = 0  # ticks the kernel ran, in all (diagnostics)
        self._key: tuple[Any, ...] | None = None  # what the arguments were made of
        self._args: tuple[Any, ...] = ()

    def enter(self, hand: GripperCore | None) -> tuple[Any, ...] | None:
        """Where the next ticks may run compiled (a torque-controlled motion under way,
        its first command accepted, the hand (None: none) holding, nothing touching the
        robot): the kernel's arguments after the torques; else None (tick in Python)."""
        core = self._core
        mg = core.mg_mode
        if (
            core.robot_mode != RobotMode.MOVE
            or core.ctrl_mode != ControllerMode.EXTERNAL_CONTROLLER
            or mg not in self._moving
            or core.first_command
            or core.async_gen is not None
            or core.contact_active
            or (hand is not None and hand.action is not None)
            or not core.compiled_fill_ready()
        ):
            return None
        self._update(hand)
        # the arrays the core replaces (a new hold, a reset, another end effector) made
        # the arguments anew; otherwise the last ones (the same arrays, updated in place)
        key = (core.q_hold, core.tau_J_d, core.joint, core.cart, core.success,
               core.elbow_c, core.chain_constants())  # fmt: skip
        if self._key is None or not all(map(operator.is_, key, self._key)):
            self._args = self._arguments(core.measured_limits())
            self._key = key
        return self._args

    def _update(self, hand: GripperCore | None) -> None:
        """The scalars the kernel reads and updates: the core's and the hand's."""
        core, ph, mg = self._core, self._physics, self._core.mg_mode
        k, ints, h = self._k, self.ints, self.hand
        ints[k.I_FLAGS] = self._moving.get(mg, 0)
        ints[k.I_JOINT_GENERATOR] = int(mg == MotionGeneratorMode.JOINT_VELOCITY)
        ints[k.I_RECEIVED] = core.received_total
        ints[k.I_SUCCESS_COUNT] = core.success_count
        ints[k.I_SUCCESS_I] = core.success_i
        with_hand = hand is not None and ph.finger_act >= 0
        ints[k.I_FINGER_ACT] = ph.finger_act if with_hand else -1
        ints[k.I_FINGER_Q] = ph.finger_q if with_hand else -1
        ints[k.I_FINGER_Q2] = ph.finger_q2 if with_hand else -1
        ints[k.I_FINGER_V] = ph.finger_v if with_hand else -1
        if hand is not None:
            h[k.H_HOLD] = hand.hold_width
            h[k.H_FORCE] = hand.force
            h[k.H_GRASP_FORCE] = math.nan if hand.grasp is None else hand.grasp.force
            h[k.H_MAX_WIDTH] = hand.max_width

    def _arguments(self, measured: tuple[np.ndarray, ...]) -> tuple[Any, ...]:
        core, ph = self._core, self._physics
        ints, h = self.ints, self.hand
        joint, cart, d = core.joint, core.cart, ph.data
        v0 = ph.v0
        links, const = core.compiled_fill_constants()
        return (
            ints, h, self.gains, d.qpos, d.qvel, ph.q0, v0, d.ctrl, ph.applied_arm,
            ph.tau_applied, ph.gravity_torque(), self._contacts, d.xmat,
            core.state_buffer, self._off, core.tau_J_d, core.tau_max, core.dtau_step,
            (ph.dq_before, ph.drive_terms, ph.constraint_arm), core.q_hold, joint.q, joint.dq,
            joint.ddq, joint.dddq, self._upper, self._lower, cart.T, cart.v, cart.a,
            core.elbow_c, core.delbow_c, core.ddelbow_c,
            np.frombuffer(core.success, dtype=np.uint8), self._fk, core.chain_constants(),
            links, const, self._scratch, measured,
        )  # fmt: skip

    @property
    def contact_cull(self) -> tuple[np.ndarray, ...]:
        """The arrays with which a caller's compiled loop skips the collision detection of
        a tick in which no contact can arise (:func:`panda_py.sim.compiled.contact_cull`:
        ``clear_of_contacts(cull)`` before the tick, ``restore_contacts(cull)`` after
        it where it was clear); never clear where the scene has more than the robot and
        fixed geoms (the cube)."""
        return self._cull

    @property
    def physics(self) -> Any:
        """The robot's physics (its MuJoCo data and the fingers' indices)."""
        return self._physics

    @property
    def success_window(self) -> int:
        """The ticks the command success rate is counted over."""
        return len(self._core.success)

    @property
    def state_buffer(self) -> np.ndarray:
        """The robot's state buffer the kernel fills (``RobotCore.state_buffer``)."""
        return self._core.state_buffer

    def warm_arguments(self, hand: GripperCore | None) -> tuple[Any, ...]:
        """Arguments of the kernel's types that no state passes: with measured limits
        nothing is within, the kernel returns at once, changing nothing (for a warm-up)."""
        never = np.full(7, np.inf)
        self._update(hand)
        return self._arguments((never, -never, -never))

    def warm(self, hand: GripperCore | None) -> None:
        """Compile (or load) the kernel for this robot's arguments now, not at a motion's
        first tick: one call with measured limits no state passes (it returns at once,
        changing nothing)."""
        status = self.tick(np.zeros(7), self.warm_arguments(hand))
        if status != self._k.Tick.ROBOT:
            raise RuntimeError(f"the compiled tick's warm-up ran the tick ({status})")

    def tick(self, tau: np.ndarray, args: tuple[Any, ...]) -> int:
        """One compiled tick with the torques ``tau`` (float64 (7,)) on :meth:`enter`'s
        ``args``: the kernel's status (by its compiled entry point once it has one: the
        dispatcher's type checks of these arguments cost more than the tick's work)."""
        entry = self._entry
        if entry is None:
            status = int(self.kernel(tau, *args))
            if len(self.kernel.signatures) == 1:
                self._entry = self.kernel.overloads[self.kernel.signatures[0]].entry_point
            return status
        return int(entry(tau, *args))

    def command(self, tau_J_d: np.ndarray, hand: GripperCore | None) -> bool:
        """One tick with a received torque command ``tau_J_d`` [Nm] where the compiled
        tick may run it: True if it ran (all of it), False if the reference must run the
        robot's part of this tick (nothing was changed)."""
        args = self.enter(hand)
        if args is None:
            return False
        tau = self._tau
        tau[:] = tau_J_d
        status = self.tick(tau, args)
        if status == self._k.Tick.ROBOT:
            return False
        self.leave(1, status, hand)
        return True

    def leave(self, ticks: int, status: int, hand: GripperCore | None) -> None:
        """Take the robot back after ``ticks`` ticks the kernel completed (counting one
        it left the fill of) and the last call's ``status``: the counters and the hand's
        force back, and the fill's part it left done here."""
        if ticks == 0:
            return
        self.ticks_run += ticks
        k, core, ints = self._k, self._core, self.ints
        core.received_total = int(ints[k.I_RECEIVED])
        core.success_count = int(ints[k.I_SUCCESS_COUNT])
        core.success_i = int(ints[k.I_SUCCESS_I])
        core.success_rate = core.success_count / len(core.success)
        core.consecutive_lost = 0
        if hand is not None:
            hand.force = core.finger_force = float(self.hand[k.H_FORCE])
        if status == k.Tick.FILL:
            core.fill_state()
        elif status == k.Tick.CONTACTS:
            core.fill_contacts()
