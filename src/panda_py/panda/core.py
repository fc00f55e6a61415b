"""``Panda``: panda-py's high-level interface to one robot, on a control process.

    panda = panda_py.Panda("172.16.0.2")
    panda.move_to_start()
    pose = panda.get_pose()

The robot's 1 kHz loop runs in a process of its own (:mod:`panda_py.rt`), so nothing the
user's Python does (a busy loop, a long computation, the garbage collector) can make the
robot miss a cycle. This process reads the newest state from shared memory (``q``,
``get_pose`` cost microseconds and never wait for the network), feeds controllers through
shared memory, and sends everything else as requests handled between ticks.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Iterable
from typing import Any, Literal, Protocol, cast, overload

import numpy as np
from numpy.typing import ArrayLike, NDArray

from panda_py import checks, fci, kinematics
from panda_py.controllers import TorqueController, laws
from panda_py.controllers.plans import JointPlan, MoveResult, PosePlan, rotation_angle
from panda_py.libfranka.model import Model
from panda_py.libfranka.realtime import fifo_permitted, has_realtime_kernel
from panda_py.libfranka.state import RobotState
from panda_py.libfranka.types import RealtimeConfig
from panda_py.panda import planning as _plans
from panda_py.panda.context import PandaContext
from panda_py.panda.handle import MotionHandle
from panda_py.panda.motions import JointMotion, PoseMotion
from panda_py.panda.move_args import JOINT_MOVE_DEFAULTS
from panda_py.panda.plan_torques import load_of
from panda_py.panda.proxy import RobotProxy
from panda_py.robots.params import START_POSE, get_robot
from panda_py.rt import byvalue
from panda_py.rt import requests as rq
from panda_py.rt.process import ControlProcess, ControlProcessError, Pending
from panda_py.rt.shm import HEADER, LOG_FIELDS, LogRing, anonymous_file

__all__ = ["Panda", "realtime_priority_available"]

FloatArray = NDArray[np.float64]


class Until(Protocol):
    """What ``until=`` takes: a condition of :mod:`panda_py.conditions`, or a user's own
    object with the same method (sent to the control process by value)."""

    def holds(self, state: Any, progress: Any) -> bool: ...


CONNECT_TIMEOUT = 5.0  # [s] for the robot to answer the connection
CLOSE_MOTION_TIMEOUT = 5.0  # [s] close() waits this long for a cancelled move to rest
LOG_MAX_BYTES = 8 << 30  # [bytes] the largest log buffer enable_logging allocates
_warned_realtime = False


def realtime_priority_available() -> tuple[bool, str]:
    """Whether a process may run under ``SCHED_FIFO`` (what the control process asks for),
    and why not (an empty message when it may)."""
    if fifo_permitted():
        return True, ""
    return False, (
        "SCHED_FIFO is not permitted (grant the rtprio limit or CAP_SYS_NICE, as for libfranka)"
    )


class Panda:
    """The main interface to control one robot (panda-py's ``Panda``).

    Connects to the robot at ``hostname`` (its FCI address) from a new control process,
    which speaks whichever protocol version (3-10) the robot does. ``name`` names the
    logger. ``realtime_config``: ``kIgnore`` runs without ``SCHED_FIFO`` when it is not
    permitted (with a warning), ``kEnforce`` refuses to. ``cpus`` (not in panda-py) pins
    the control loop to these CPUs (Linux), e.g. a core isolated for it (``isolcpus``); or,
    beside a simulated robot on a machine whose cores stall now and then (a VM), to the
    simulator's (``Simulator(cpus=...)``): both then stall together, and no command is lost
    to it.
    """

    def __init__(
        self,
        hostname: str,
        name: str = "panda",
        realtime_config: RealtimeConfig = RealtimeConfig.kIgnore,
        *,
        cpus: Iterable[int] | None = None,
    ) -> None:
        if not isinstance(hostname, str) or not hostname:
            raise ValueError(f"hostname: expected the robot's address, got {hostname!r}")
        if not isinstance(name, str):
            raise ValueError(f"name: expected a str (the logger's name), got {name!r}")
        config = RealtimeConfig.parse(realtime_config)
        pinned = checks.cpus("cpus", cpus)
        self._name = name
        self._logger = logging.getLogger(name)
        self._controller: TorqueController | None = None
        self._motion: MotionHandle | None = None  # the newest move (it may be running)
        self._log_ring: LogRing | None = None
        # the moves' checks (inverse kinematics) compile or load their kernels on first use,
        # a third of a second: done here while the control process starts, so the first
        # move (an asynchronous one in particular) takes effect at once
        warm = threading.Thread(target=kinematics.warmup, name="panda_py-warmup", daemon=True)
        warm.start()
        try:
            self._proc = ControlProcess(
                hostname, config, timeout=CONNECT_TIMEOUT, logger=self._logger, cpus=pinned
            )
        finally:
            warm.join()
        self._info: rq.Connected = self._proc.info
        self._hostname = hostname
        self._dialect = fci.dialect(self._info.server_version)
        self._spec = get_robot(self._info.robot)
        self._limits = get_robot(self._info.limits)
        self._model = Model(self._spec)
        block = self._proc.block
        q = block.field_views(self._dialect.state_dtype, "q")
        T = block.field_views(self._dialect.state_dtype, "O_T_EE")
        # column-major 16 -> the 4x4 pose as a (Fortran-ordered) view, and its position
        pose = (T[0].reshape(4, 4).T, T[1].reshape(4, 4).T)
        self._p_view = (T[0][12:15], T[1][12:15])
        self._header = block.header
        # the state latch read inline by q and get_pose (a user's hot path), with the
        # block's copies of the two slots (float64; v10's float32 fields cast)
        self._q_copies = block.slot_copies(q)
        self._T_copies = block.slot_copies(pose)
        self._logger.info("Connected to robot (%s).", hostname)
        self._logger.info(
            "Using %s joint limits (robot server version %d).",
            self._limits.name,
            self._info.server_version,
        )
        self._warn_realtime()

    def _warn_realtime(self) -> None:
        global _warned_realtime
        if _warned_realtime:
            return
        _warned_realtime = True
        ok, why = realtime_priority_available()
        if not ok:
            self._logger.warning(
                "Realtime scheduling is unavailable, so the control process runs at normal "
                "priority and can miss its deadline when the machine is busy (%s).",
                why,
            )
        if not has_realtime_kernel():
            self._logger.info("The running kernel is not a realtime (PREEMPT_RT) kernel.")

    # --- lifecycle ---------------------------------------------------------------------

    def close(self) -> None:
        """Stop what runs, close the connection and end the control process."""
        proc = getattr(self, "_proc", None)
        if proc is not None:
            self._unbind()
            motion = getattr(self, "_motion", None)
            if motion is not None and not motion.done() and not proc.dead and not proc.closed:
                try:  # a running move ends gently, not with the connection
                    motion.cancel()
                    motion.wait(CLOSE_MOTION_TIMEOUT)
                except Exception:
                    pass
            proc.close()
        ring, self._log_ring = getattr(self, "_log_ring", None), None
        if ring is not None:
            ring.close()

    def __enter__(self) -> Panda:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    def __del__(self) -> None:
        try:
            self.close()
        except Exception:
            pass

    @property
    def name(self) -> str:
        """The name given at construction (the logger's)."""
        return self._name

    # --- state -------------------------------------------------------------------------

    def _data(self) -> bytes:
        proc = self._proc
        if proc.dead:
            raise proc.gone()
        data = proc.block.read_state()
        if data is None:
            raise ControlProcessError("no robot state received yet")
        return data

    def get_state(self) -> RobotState:
        """A copy of the newest robot state (the control process reads it at 1 kHz)."""
        return RobotState(self._dialect, self._data())

    @property
    def q(self) -> FloatArray:
        """Current joint positions [rad]."""
        proc = self._proc
        if proc.dead:
            raise proc.gone()
        # the state latch, read inline (this is the hot path of a user's loop)
        h, copies = self._header, self._q_copies
        while True:
            seq = h[0]
            out = copies[seq & 1]()
            if seq == h[0]:
                return out

    def get_pose(self) -> FloatArray:
        """Current end-effector pose in the base frame (4x4)."""
        proc = self._proc
        if proc.dead:
            raise proc.gone()
        h, copies = self._header, self._T_copies
        while True:
            seq = h[0]
            out = copies[seq & 1]()
            if seq == h[0]:
                return out

    def get_position(self) -> FloatArray:
        """Current end-effector position in the base frame [m]."""
        proc = self._proc
        if proc.dead:
            raise proc.gone()
        return proc.block.read_field(self._p_view)

    def get_orientation(self, scalar_first: bool = False) -> FloatArray:
        """Current end-effector orientation as a unit quaternion: (x, y, z, w), or
        (w, x, y, z) with ``scalar_first``."""
        quat = laws.quat_from_matrix(RobotState(self._dialect, self._data()).O_T_EE)
        return np.roll(quat, 1) if scalar_first else quat

    def refresh_state(self) -> None:
        """Wait for the next state from the robot (at most a few periods)."""
        header = self._proc.block.header
        ticks = header[HEADER.TICKS]
        deadline = time.monotonic() + 0.1
        while header[HEADER.TICKS] == ticks and time.monotonic() < deadline:
            time.sleep(50e-6)
        self._proc.check()

    def get_robot(self) -> RobotProxy:
        """The libfranka-level robot (setters, ``automatic_error_recovery``,
        ``read_once``), run in the control process that owns the connection."""
        return RobotProxy(self._proc, self._info.server_version, self._model, self.stop_controller)

    def get_model(self) -> Model:
        """The robot's dynamics model (computed locally)."""
        return self._model

    def get_joint_limits_lower(self) -> FloatArray:
        """Lower joint position limits of the connected robot [rad] (FER, FR3 before robot
        system 5.9, or FR3 from 5.9 on, from its protocol version)."""
        return np.array(self._limits.joints.q_min)

    def get_joint_limits_upper(self) -> FloatArray:
        """Upper joint position limits of the connected robot [rad]."""
        return np.array(self._limits.joints.q_max)

    # --- errors ------------------------------------------------------------------------

    def raise_error(self) -> None:
        """Raise the error that ended the last controller or move (a
        :class:`~panda_py.libfranka.ControlException` with its reflex flags), if any; or
        :class:`~panda_py.rt.process.ControlProcessError` if the control process is gone."""
        self._proc.check()

    def recover(self) -> None:
        """Automatic error recovery if the robot is in a reflex or has errors."""
        self._proc.call(rq.Recover())

    def is_moving(self) -> bool:
        """True while a controller or a move runs: from the return of
        ``start_controller`` or ``move_to_*(..., asynchronous=True)`` until it ended."""
        return bool(self._proc.block.header[HEADER.RUNNING]) or self._moving()

    def set_default_behavior(self) -> None:
        """Recover, then set panda-py's default collision thresholds and impedances."""
        self.recover()
        self._logger.info("Resetting impedance and collision behavior.")
        robot = self.get_robot()
        robot.set_collision_behavior(
            [20.0] * 7, [20.0] * 7, [10.0] * 7, [10.0] * 7,
            [20.0] * 6, [20.0] * 6, [10.0] * 6, [10.0] * 6,
        )  # fmt: skip
        # the impedances a robot powers up with (robots.params, the one place they live)
        robot.set_joint_impedance(list(self._limits.default_K_theta))
        robot.set_cartesian_impedance(list(self._limits.default_K_x))

    # --- controllers ---------------------------------------------------------------------

    def _unbind(self) -> None:
        ctrl, self._controller = self._controller, None
        if ctrl is not None:
            ctrl.detach()

    def start_controller(self, controller: TorqueController) -> None:
        """Stop what runs, recover from errors, and start ``controller`` at 1 kHz in the
        control process; feed it with its ``set_control``/setters from here."""
        if not isinstance(controller, TorqueController):
            raise ValueError(
                f"controller: expected a panda_py.controllers.TorqueController, got "
                f"{type(controller).__name__}"
            )
        payload = byvalue.dumps(controller)  # before anything stops: a bad one stops nothing
        self.stop_controller()
        self.recover()
        self._logger.info("Starting new controller (%s).", controller.name)
        values = self._proc.call(rq.StartController(payload))
        controller.attach(self._proc.block, values)
        self._controller = controller

    def stop_controller(self) -> None:
        """Stop the running controller (the robot holds its position); a running move
        (``asynchronous=True``) is cancelled: it comes gently to rest first."""
        motion = self._motion
        if motion is not None and not motion.done():
            motion.cancel()
            motion.wait()
        if self._controller is not None:
            self._logger.info("Stopping active controller (%s).", self._controller.name)
        self._proc.call(rq.Stop())
        self._unbind()

    def teaching_mode(self, active: bool, damping: Any = (0.0,) * 7) -> None:
        """Hand guiding: gravity compensation with the given joint damping [Nm s/rad]."""
        from panda_py.controllers import AppliedTorque

        ctrl = AppliedTorque(damping=damping) if active else None
        self.stop_controller()
        self.recover()
        if ctrl is not None:
            self.start_controller(ctrl)

    # --- moves -------------------------------------------------------------------------

    def _moving(self) -> bool:
        """Whether a move of ours runs (one started with ``asynchronous=True``)."""
        return self._motion is not None and not self._motion.done()

    def _prepare_move(self, what: str) -> None:
        """Before a move: stop a controller and recover, as panda-py; a running move is
        left running, for the new one to replace mid-motion."""
        if not self._moving():
            self.stop_controller()
            self.recover()
        self._logger.info("Initializing motion generation (%s).", what)

    def _move_result(self, result: MoveResult) -> None:
        if result.error is not None:
            self._proc.errors.append(result.error)
            self._logger.error("Control loop interrupted: %s", result.error)
        if result.cancelled:  # as asked: cancelled, or replaced by a newer move
            self._logger.info("Motion %s", result.reason)
        elif not result.success:
            self._logger.warning("Motion %s", result.reason)

    def _move(
        self, plan: JointPlan | PosePlan | None, what: str, asynchronous: bool,
        until: Until | None = None, then: JointPlan | PosePlan | None = None,
    ) -> bool | MotionHandle:  # fmt: skip
        """Run ``plan``: block and return the success flag, or return a handle."""
        if plan is None:
            self._logger.info("Already at goal.")
            if not asynchronous:
                return True
            pending = Pending(0)
            pending.set_result(MoveResult(True, ""))
        else:
            until_bytes = None if until is None else byvalue.dumps(until)
            pending = self._proc.submit(rq.Move(plan, until_bytes, then))
        handle = MotionHandle(self._proc, pending, what, self._move_result)
        self._motion = handle
        if asynchronous:
            return handle
        try:
            return handle.wait()
        except BaseException:  # Ctrl-C (KeyboardInterrupt) or any error while it ran
            self._stop_interrupted(handle)
            raise

    def _stop_interrupted(self, handle: MotionHandle) -> None:
        """A blocking move whose wait was interrupted: bring the arm gently to rest before
        the exception goes on, so a script that catches it has no arm moving behind its
        back. The cancel goes out first; a second interrupt while the arm decelerates (or a
        control process already gone) leaves it to the control process."""
        try:
            if not handle.done():
                handle.cancel()
                handle.wait(CLOSE_MOTION_TIMEOUT)
        except BaseException:  # (the first exception is the one to raise)
            pass

    @overload
    def move(
        self, motion: JointMotion | PoseMotion, *, asynchronous: Literal[False] = False,
        until: Until | None = None, then: JointMotion | PoseMotion | None = None,
    ) -> bool: ...  # fmt: skip
    @overload
    def move(
        self, motion: JointMotion | PoseMotion, *, asynchronous: Literal[True],
        until: Until | None = None, then: JointMotion | PoseMotion | None = None,
    ) -> MotionHandle: ...  # fmt: skip
    @overload
    def move(
        self, motion: JointMotion | PoseMotion, *, asynchronous: bool,
        until: Until | None = None, then: JointMotion | PoseMotion | None = None,
    ) -> bool | MotionHandle: ...  # fmt: skip
    def move(
        self, motion: JointMotion | PoseMotion, *, asynchronous: bool = False,
        until: Until | None = None, then: JointMotion | PoseMotion | None = None,
    ) -> bool | MotionHandle:  # fmt: skip
        """Run ``motion``, a :class:`~panda_py.JointMotion` (a time-optimal trajectory
        through joint positions tracked by joint impedance) or a
        :class:`~panda_py.PoseMotion` (straight, time-optimal segments of the end
        effector tracked by Cartesian impedance): True if it ends at rest within its
        success thresholds of its goal (panda-py's ``move_to_*``, which call this).

        ``asynchronous=True`` returns a :class:`MotionHandle` at once; a move started
        while another runs replaces it mid-motion (continuously, within the robot's
        limits); ``until`` a condition (:mod:`panda_py.conditions`) evaluated every tick
        in the control process that ends the move gently when it holds, or hands over to
        ``then`` (another motion). An exception while a blocking move runs (Ctrl-C
        included) brings the arm to rest before it propagates."""
        flag, until, then = self._guard(asynchronous, until, then)
        if isinstance(motion, JointMotion):
            return self._move_joints(motion, flag, until, then)
        if isinstance(motion, PoseMotion):
            return self._move_pose(motion, flag, until, then)
        raise ValueError(f"motion: expected a JointMotion or a PoseMotion, got "
                         f"{type(motion).__name__}")  # fmt: skip

    def _move_joints(
        self, motion: JointMotion, flag: bool, until: Until | None,
        then: JointMotion | PoseMotion | None,
    ) -> bool | MotionHandle:  # fmt: skip
        waypoints, opts = motion.waypoints, motion.options
        self._check_in_limits(waypoints)
        replacing = self._moving()
        self._prepare_move("moveToJointPosition")
        plan: JointPlan | None
        if replacing and len(waypoints) == 1:  # the control process leads in to the goal
            plan = _plans.joint_goal(waypoints[0], opts, self._limits)
        else:
            q_now = np.clip(self.q, self.get_joint_limits_lower(), self.get_joint_limits_upper())
            plan = _plans.joint_move(q_now, waypoints, opts, self._limits)
        return self._move(plan, "move_to_joint_position", flag, until,
                          self._plan_then(then, plan))  # fmt: skip

    def _move_pose(
        self, motion: PoseMotion, flag: bool, until: Until | None,
        then: JointMotion | PoseMotion | None,
    ) -> bool | MotionHandle:  # fmt: skip
        positions, quats, opts = motion.positions, motion.orientations, motion.options
        if opts.joint_space is not None and (flag or until is not None):
            raise ValueError(
                "stiffness, damping: panda-py < 1.0's joint-space form of move_to_pose "
                "blocks and has no until; give impedance instead for asynchronous=True or until"
            )
        state = self.get_state()
        q_now = state.q
        F_T_EE = state.F_T_EE.reshape(4, 4, order="F")
        _plans.check_reachable(positions, quats, q_now, self._limits, F_T_EE)
        replacing = self._moving()
        self._prepare_move("moveToPose")
        plan: PosePlan | None
        if replacing and len(positions) == 1 and opts.joint_space is None:
            plan = _plans.pose_goal(positions[0], quats[0], opts, q_now.copy(), self._limits)
        else:
            state = self.get_state()
            p_now = state.O_T_EE[12:15].copy()
            quat_now = laws.quat_from_matrix(state.O_T_EE)
            plan = _plans.pose_move(p_now, quat_now, positions, quats, opts, state.q.copy(),
                                    self._limits, F_T_EE=F_T_EE, load=load_of(state))  # fmt: skip
        if opts.joint_space is None or plan is None:
            return self._move(plan, "move_to_pose", flag, until, self._plan_then(then, plan))
        # panda-py < 1.0's form: the straight path tracked in joint space
        joint_plan = _plans.pose_move_in_joint_space(plan, opts, state.q, self._limits, F_T_EE)
        if not self._move(joint_plan, "move_to_pose", False):
            return False
        T = self.get_pose()
        pos_err = float(np.linalg.norm(T[:3, 3] - positions[-1]))
        rot_err = rotation_angle(self.get_orientation(), quats[-1])
        ok = pos_err <= opts.success_threshold and rot_err <= opts.orientation_threshold
        if not ok:
            self._logger.warning(
                "Motion finished %.4f m and %.2f deg from the goal, above the success threshold.",
                pos_err,
                math.degrees(rot_err),
            )
        return ok

    def _check_in_limits(self, waypoints: FloatArray) -> None:
        lower, upper = self._limits.joints.q_min, self._limits.joints.q_max
        for i, q in enumerate(waypoints.tolist()):  # (in scalars: few waypoints, cold caches)
            bad = [j for j in range(7) if not lower[j] <= q[j] <= upper[j]]
            if bad:
                j = bad[0]
                raise ValueError(
                    f"waypoints[{i}]: joint {j + 1} at {q[j]:.4f} rad is outside the "
                    f"{self._limits.name} joint limits [{lower[j]}, {upper[j]}] rad"
                )

    def _guard(
        self, asynchronous: object, until: object, then: object
    ) -> tuple[bool, Until | None, JointMotion | PoseMotion | None]:
        """The checked ``asynchronous``, ``until`` and ``then`` of a move."""
        if not isinstance(asynchronous, (bool, np.bool_)):
            raise ValueError(f"asynchronous: expected True or False, got {asynchronous!r}")
        # a condition of panda_py.conditions, or a user's own object with the same
        # holds(state, progress) (sent by value like a user's controller)
        if until is not None and not callable(getattr(until, "holds", None)):
            raise ValueError(
                "until: expected a condition of panda_py.conditions (e.g. Force.z < -10.0), "
                f"got {type(until).__name__}"
            )
        if then is not None:
            if until is None:
                raise ValueError("then: a move continues with another only after its until "
                                 "condition held; give until as well")  # fmt: skip
            if not isinstance(then, (JointMotion, PoseMotion)):
                raise ValueError(
                    f"then: expected a JointMotion or a PoseMotion, got {type(then).__name__}"
                )
            if isinstance(then, JointMotion):
                self._check_in_limits(then.waypoints)
            elif then.options.joint_space is not None:
                raise ValueError("then: expected a PoseMotion with impedance options, not "
                                 "panda-py < 1.0's joint stiffness and damping")  # fmt: skip
        return bool(asynchronous), cast("Until | None", until), then

    def _plan_then(
        self, then: JointMotion | PoseMotion | None, first: JointPlan | PosePlan | None
    ) -> JointPlan | PosePlan | None:
        """The plan of ``then``, from where the first move ends (the lead-in bridges the
        gap from wherever its condition holds)."""
        if then is None:
            return None
        state = self.get_state()
        if isinstance(then, JointMotion):
            start = first.q[-1] if isinstance(first, JointPlan) else state.q
            return _plans.joint_move(start, then.waypoints, then.options, self._limits,
                                     at_rest=True)  # fmt: skip
        if isinstance(first, PosePlan):
            p, quat = first.position[-1], first.orientation[-1]
        else:
            p, quat = state.O_T_EE[12:15].copy(), laws.quat_from_matrix(state.O_T_EE)
        return _plans.pose_move(p, quat, then.positions, then.orientations, then.options,
                                state.q.copy(), self._limits, at_rest=True,
                                F_T_EE=state.F_T_EE.reshape(4, 4, order="F"),
                                load=load_of(state))  # fmt: skip

    # --- panda-py's moves: one line each over move() -------------------------------------

    @overload
    def move_to_joint_position(
        self, *args: Any, asynchronous: Literal[False] = False, until: Until | None = None,
        then: JointMotion | PoseMotion | None = None, **kwargs: Any,
    ) -> bool: ...  # fmt: skip
    @overload
    def move_to_joint_position(
        self, *args: Any, asynchronous: Literal[True], until: Until | None = None,
        then: JointMotion | PoseMotion | None = None, **kwargs: Any,
    ) -> MotionHandle: ...  # fmt: skip
    @overload
    def move_to_joint_position(
        self, *args: Any, asynchronous: bool, until: Until | None = None,
        then: JointMotion | PoseMotion | None = None, **kwargs: Any,
    ) -> bool | MotionHandle: ...  # fmt: skip
    def move_to_joint_position(
        self, *args: Any, asynchronous: bool = False, until: Until | None = None,
        then: JointMotion | PoseMotion | None = None, **kwargs: Any,
    ) -> bool | MotionHandle:  # fmt: skip
        """Move through joint positions (``positions`` (7,) or ``waypoints``, a sequence
        of them) on a time-optimal trajectory tracked by joint impedance; True if the arm
        ends within ``success_threshold`` [rad] of the goal. Keywords as panda-py:
        ``speed_factor=0.2, stiffness, damping, dq_threshold=0.001,
        success_threshold=0.01``.

        Beyond panda-py: ``max_deviation`` [rad] (keyword) lets the path cut each
        intermediate waypoint's corner by up to that much instead of stopping there (0,
        panda-py's, stops); ``asynchronous``, ``until`` and ``then`` as :meth:`move`
        (``self.move(JointMotion(*args, **kwargs), ...)``)."""
        motion = JointMotion(*args, **kwargs)
        return self.move(motion, asynchronous=asynchronous, until=until, then=then)

    @overload
    def move_to_start(
        self, speed_factor: float = 0.2, stiffness: ArrayLike = ..., damping: ArrayLike = ...,
        dq_threshold: float = 0.001, success_threshold: float = 0.01, *,
        asynchronous: Literal[False] = False, until: Until | None = None,
        then: JointMotion | PoseMotion | None = None,
    ) -> bool: ...  # fmt: skip
    @overload
    def move_to_start(
        self, speed_factor: float = 0.2, stiffness: ArrayLike = ..., damping: ArrayLike = ...,
        dq_threshold: float = 0.001, success_threshold: float = 0.01, *,
        asynchronous: Literal[True], until: Until | None = None,
        then: JointMotion | PoseMotion | None = None,
    ) -> MotionHandle: ...  # fmt: skip
    def move_to_start(
        self,
        speed_factor: float = 0.2,
        stiffness: ArrayLike = JOINT_MOVE_DEFAULTS["stiffness"],
        damping: ArrayLike = JOINT_MOVE_DEFAULTS["damping"],
        dq_threshold: float = 0.001,
        success_threshold: float = 0.01,
        *,
        asynchronous: bool = False,
        until: Until | None = None,
        then: JointMotion | PoseMotion | None = None,
    ) -> bool | MotionHandle:
        """Move to panda-py's start pose (``constants.JOINT_POSITION_START``);
        ``asynchronous``, ``until``, ``then`` as :meth:`move`."""
        motion = JointMotion(np.array(START_POSE), speed_factor, stiffness, damping,
                             dq_threshold, success_threshold)  # fmt: skip
        return self.move(motion, asynchronous=asynchronous, until=until, then=then)

    @overload
    def move_to_pose(
        self, *args: Any, asynchronous: Literal[False] = False, until: Until | None = None,
        then: JointMotion | PoseMotion | None = None, **kwargs: Any,
    ) -> bool: ...  # fmt: skip
    @overload
    def move_to_pose(
        self, *args: Any, asynchronous: Literal[True], until: Until | None = None,
        then: JointMotion | PoseMotion | None = None, **kwargs: Any,
    ) -> MotionHandle: ...  # fmt: skip
    @overload
    def move_to_pose(
        self, *args: Any, asynchronous: bool, until: Until | None = None,
        then: JointMotion | PoseMotion | None = None, **kwargs: Any,
    ) -> bool | MotionHandle: ...  # fmt: skip
    def move_to_pose(
        self, *args: Any, asynchronous: bool = False, until: Until | None = None,
        then: JointMotion | PoseMotion | None = None, **kwargs: Any,
    ) -> bool | MotionHandle:  # fmt: skip
        """Move the end effector through poses on straight, time-optimal segments
        tracked by Cartesian impedance: ``(positions, orientations)``, ``(position,
        orientation)`` (quaternions x, y, z, w), ``(poses)`` or ``(pose)`` (4x4). True if
        it ends within ``success_threshold`` [m] and ``orientation_threshold`` [rad].
        Keywords as panda-py: ``speed_factor=0.2, impedance, damping_ratio=1.0,
        nullspace_stiffness=15.0, dq_threshold=0.001, success_threshold=0.02,
        orientation_threshold=0.1``; ``max_deviation`` [m] as
        :meth:`move_to_joint_position`'s; ``asynchronous``, ``until``, ``then`` as
        :meth:`move` (``self.move(PoseMotion(*args, **kwargs), ...)``). ``damping_ratio``
        is the damping ratio on the arm's own end-effector inertia (panda-py's ``2
        damping_ratio sqrt(K)`` assumes a unit mass; see
        :class:`~panda_py.controllers.tracking.PoseImpedance`)."""
        motion = PoseMotion(*args, **kwargs)
        return self.move(motion, asynchronous=asynchronous, until=until, then=then)

    # --- logging -----------------------------------------------------------------------

    def enable_logging(self, buffer_size: int) -> None:
        """Keep the last ``buffer_size`` robot states (1 kHz, while connected) for
        :meth:`get_log`; clears the log. An integral float (``2e3``) is accepted."""
        size: Any = buffer_size
        if isinstance(size, float) and math.isfinite(size) and size.is_integer():
            size = int(size)
        if isinstance(size, bool) or not isinstance(size, (int, np.integer)) or size < 1:
            raise ValueError(f"buffer_size: expected a whole number >= 1, got {buffer_size!r}")
        record, spans = LogRing.layout(self._dialect.state_dtype, LOG_FIELDS)
        nbytes = LogRing.nbytes(int(size), record)
        if nbytes > LOG_MAX_BYTES:
            raise ValueError(
                f"buffer_size: {size} states need {nbytes / 2**30:.1f} GiB, more than the "
                f"{LOG_MAX_BYTES / 2**30:.0f} GiB allowed"
            )
        fd = anonymous_file(nbytes, "panda_py-log")
        try:
            ring = LogRing(fd, int(size), record, spans)
            self._proc.call(rq.EnableLog(int(size)), fds=(fd,))
        finally:
            import os

            os.close(fd)
        old, self._log_ring = self._log_ring, ring
        if old is not None:
            old.close()

    def disable_logging(self) -> None:
        """Stop logging; :meth:`get_log` keeps returning what was logged."""
        self._proc.call(rq.DisableLog())

    def get_log(self) -> dict[str, list[FloatArray]]:
        """The logged states, oldest first: panda-py's keys (``q``, ``dq``, ``tau_J``,
        ``O_T_EE``, ``O_F_ext_hat_K``, ``K_F_ext_hat_K``, ``tau_ext_hat_filtered``,
        ``elbow``, ``control_command_success_rate``, ``time`` [ms]), each a list of 1-D
        arrays."""
        ring = self._log_ring
        keys = [n for n in LOG_FIELDS if n != "message_id"] + ["time"]
        if ring is None:
            return {k: [] for k in keys}
        recs = ring.snapshot(self._proc.block.header)
        n = len(recs)
        if n == 0:
            return {k: [] for k in keys}
        out: dict[str, list[FloatArray]] = {}
        for key in keys:
            field = "message_id" if key == "time" else key
            arr = np.asarray(recs[field], dtype=np.float64).reshape(n, -1).copy()
            out[key] = list(arr)
        return out

    def create_context(
        self, frequency: float, max_runtime: float = 0.0, max_iter: int = 0
    ) -> PandaContext:
        """A fixed-frequency loop (see :class:`~panda_py.PandaContext`)."""
        return PandaContext(self, frequency, max_runtime, max_iter)
