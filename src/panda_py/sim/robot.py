"""The simulated robot's core: mode machine, Move lifecycle (a Move starts or is refused
in :meth:`RobotCore.request_move`), command checks. Its parts: the setters in
:mod:`.settings`, the state in :mod:`.state`, the checks' arithmetic in :mod:`.safety`.

Version-independent: it speaks in :mod:`panda_py.fci` enums and fills a float64 "master"
state keyed by libfranka's field names; the server copies that into each connection's
wire dialect.
"""

from __future__ import annotations

import logging

import numpy as np

from panda_py import fci
from panda_py.fci import (
    ERROR_NAMES,
    ControllerMode,
    ErrorRecoveryStatus,
    MotionGeneratorMode,
    MoveControllerMode,
    MoveMotionGeneratorMode,
    MoveStatus,
    RobotMode,
    StopMoveStatus,
)
from panda_py.kinematics import get_kinematics
from panda_py.robots.end_effectors import end_effector_load
from panda_py.robots.params import RobotSpec
from panda_py.sim import fastpath
from panda_py.sim.async_motion import AsyncJointGenerator, async_refusal
from panda_py.sim.command import Command
from panda_py.sim.drive import JointDrive
from panda_py.sim.physics import DT, Physics
from panda_py.sim.safety import (
    START_CARTESIAN_TOLERANCE,
    START_POSE_TOLERANCE,
    CartesianSignal,
    JointSignal,
    all_finite,
    from_col_major,
    is_valid_transform,
    pose_error,
)
from panda_py.sim.settings import CollisionThresholds, RobotSettings
from panda_py.sim.state import CONTACT_FIELDS, StateAssembly

log = logging.getLogger("panda_py.sim")

_ERROR_INDEX = {name: i for i, name in enumerate(ERROR_NAMES)}
# the velocity and acceleration a held joint is tracked at (read, never written)
_REST = np.zeros(7)

# After this many lost commands in a row the robot aborts (FCI docs: "20 consecutively
# dropped packets" -> communication_constraints_violation).
MAX_CONSECUTIVE_LOST = 20
# Window of control_command_success_rate [ticks].
SUCCESS_WINDOW = 100


class RobotCore(RobotSettings, StateAssembly):
    """The robot's behaviour, advanced one 1 ms tick at a time by the server."""

    def __init__(self, spec: RobotSpec, physics: Physics, q_start: np.ndarray) -> None:
        self.spec = spec
        self.physics = physics
        self._q_min = np.asarray(spec.joints.q_min)
        self._q_max = np.asarray(spec.joints.q_max)
        self._dq_max = np.asarray(spec.joints.dq_max)
        self._tau_max = np.asarray(spec.joints.tau_max)
        self._dtau_max = np.asarray(spec.joints.dtau_max)
        self._K_default = np.asarray(spec.default_K_theta)
        # Measured-state limits with the robot's tolerance, and the torque change per tick.
        self._q_lo = self._q_min - 1e-3
        self._q_hi = self._q_max + 1e-3
        self._dq_hi = self._dq_max * 1.05
        self._dtau_step = (self._dtau_max * (1 + 1e-6) + 1e-6) * DT
        # The hand's TCP kinematics, fast generated fk (O_T_EE of the nominal EE).
        self._kin = get_kinematics(spec, F_T_EE=physics.F_T_NE)
        self._kin_frame = np.array(physics.F_T_NE, dtype=float)
        self._new_state()
        self.reset(q_start)

    # -- setup ---------------------------------------------------------------------------

    def reset(self, q: np.ndarray) -> None:
        """Power-up state at joint positions ``q`` [rad]: idle, no errors, defaults set."""
        q = np.asarray(q, dtype=float)
        self.physics.reset(q)
        self.robot_mode = RobotMode.IDLE
        self.mg_mode = MotionGeneratorMode.IDLE
        self.ctrl_mode = ControllerMode.JOINT_IMPEDANCE
        self.errors = np.zeros(len(ERROR_NAMES), dtype=np.uint8)
        self.reflex_reason = np.zeros(len(ERROR_NAMES), dtype=np.uint8)
        self.thresholds = CollisionThresholds()
        self.K_theta = self._K_default.copy()
        self.K_x = np.asarray(self.spec.default_K_x, dtype=float)
        self.guiding_axes = np.ones(6, dtype=bool)
        self.guiding_elbow = False
        self.filters = np.full(5, 1000.0)
        # The mounted end effector as Desk configures it: its TCP and its load.
        load = end_effector_load(self.physics.end_effector)
        self._set_frame(self.physics.F_T_NE)
        self.NE_T_EE = np.eye(4)
        self.EE_T_K = np.eye(4)
        self.m_ee = load.mass
        ixx, iyy, izz, ixy, ixz, iyz = load.inertia
        self.I_ee = np.array([[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]])
        self.F_x_Cee = np.array(load.com)
        self.m_load = 0.0
        self.I_load = np.zeros((3, 3))
        self.F_x_Cload = np.zeros(3)
        self._fill_static()
        self.joint = JointSignal(self._fast.kernels if self._fast is not None else None)
        self.joint.reset(q)
        self.cart = CartesianSignal()
        self.cart.reset(self.physics.flange_pose_at(q) @ self.F_T_EE)
        self.elbow_c = np.array([q[2], self._elbow_sign(q[3])])
        self.delbow_c = np.zeros(2)
        self.ddelbow_c = np.zeros(2)
        self.tau_J_d = np.zeros(7)
        self.tau_prev_J = np.zeros(7)
        self.tau_ext = np.zeros(7)
        self.contact_active = False
        self.q_hold = q.copy()
        self.drive: JointDrive | None = None  # a move of the robot's own (the Desk's)
        self.first_command = True
        self.consecutive_lost = 0
        self.lost_total = 0
        self.received_total = 0
        self.success = bytearray(b"\x01" * SUCCESS_WINDOW)
        self.success_count = SUCCESS_WINDOW
        self.success_i = 0
        self.success_rate = 0.0
        self.pending_final: MoveStatus | None = None
        self.async_gen: AsyncJointGenerator | None = None  # v10 robot-side generator
        self.finger_force = 0.0  # [N] set by the gripper each tick
        for name in CONTACT_FIELDS:
            self.state[name][:] = 0.0
        self._filled_mode: MotionGeneratorMode | None = None  # all fields to be written
        self._fill_state()

    # -- TCP requests ----------------------------------------------------------------------

    def _mode_allows_commands(self) -> bool:
        return self.robot_mode == RobotMode.IDLE

    def request_move(
        self,
        controller: int,
        generator: int,
        deviations: np.ndarray,
        *,
        has_none: bool,
        use_async: bool = False,
        maximum_velocity: np.ndarray | None = None,
    ) -> MoveStatus:
        """Handle a Move request; MOTION_STARTED means the motion runs from the next tick."""
        if self.robot_mode != RobotMode.IDLE:
            log.info("Move rejected: robot is in mode %s", self.robot_mode.name)
            return MoveStatus.COMMAND_NOT_POSSIBLE_REJECTED
        try:
            ctrl = MoveControllerMode(controller)
            mg = MoveMotionGeneratorMode(generator)
        except ValueError:
            log.warning(
                "Move rejected: controller %d / generator %d unknown", controller, generator
            )
            return MoveStatus.INVALID_ARGUMENT_REJECTED
        if mg == MoveMotionGeneratorMode.NONE and (
            not has_none or ctrl != MoveControllerMode.EXTERNAL_CONTROLLER
        ):
            log.warning("Move rejected: no motion generator needs an external controller (v7+)")
            return MoveStatus.INVALID_ARGUMENT_REJECTED
        dev = np.asarray(deviations, dtype=float)
        if not all_finite(dev) or np.any(dev <= 0.0):
            log.warning("Move rejected: maximum deviations %s out of range", dev.tolist())
            return MoveStatus.INVALID_ARGUMENT_REJECTED
        if use_async:
            refusal = async_refusal(ctrl, mg, maximum_velocity)
            if refusal:
                log.warning("async Move rejected: %s", refusal)
                return MoveStatus.INVALID_ARGUMENT_REJECTED
        q = self.physics.q.copy()
        self.robot_mode = RobotMode.MOVE
        self.mg_mode = fci.STATE_GENERATOR_OF_MOVE[mg]
        self.ctrl_mode = ControllerMode(int(ctrl))
        self.first_command = True
        self.consecutive_lost = 0
        self.success[:] = b"\x01" * SUCCESS_WINDOW
        self.success_count = SUCCESS_WINDOW
        self.pending_final = None
        self.joint.reset(q)
        self.q_hold = q
        self.cart.reset(self.physics.flange_pose_at(q) @ self.F_T_EE)
        self.elbow_c[:] = [q[2], self._elbow_sign(q[3])]
        self.delbow_c[:] = 0.0
        self.ddelbow_c[:] = 0.0
        self.tau_J_d[:] = 0.0
        self.async_gen = None
        if use_async:
            assert maximum_velocity is not None
            self.async_gen = AsyncJointGenerator(self.spec, q, maximum_velocity)
        return MoveStatus.MOTION_STARTED

    def request_stop_move(self) -> StopMoveStatus:
        """StopMove: end a running motion (its Move gets PREEMPTED); a robot in Reflex stays
        there until AutomaticErrorRecovery."""
        if self.robot_mode == RobotMode.MOVE:
            self._end_motion(MoveStatus.PREEMPTED)
        elif self.robot_mode == RobotMode.USER_STOPPED:
            return StopMoveStatus.EMERGENCY_ABORTED
        return StopMoveStatus.SUCCESS

    def request_recovery(self) -> ErrorRecoveryStatus:
        if self.robot_mode == RobotMode.MOVE:
            return ErrorRecoveryStatus.COMMAND_NOT_POSSIBLE_REJECTED
        if self.robot_mode == RobotMode.USER_STOPPED:
            return ErrorRecoveryStatus.EMERGENCY_ABORTED
        if self.robot_mode in (RobotMode.REFLEX, RobotMode.IDLE):
            self.errors[:] = 0
            self.robot_mode = RobotMode.IDLE
            self.q_hold = self.physics.q.copy()
            self.joint.reset(self.q_hold)
        return ErrorRecoveryStatus.SUCCESS

    # -- faults and buttons (simulator API) ----------------------------------------------

    def inject_reflex(self, names: list[str]) -> None:
        """Raise the named error flags as if the robot had detected them."""
        unknown = [n for n in names if n not in _ERROR_INDEX]
        if unknown:
            raise ValueError(f"unknown error flags {unknown}; valid: {list(ERROR_NAMES)}")
        self._reflex(names)

    def set_user_stop(self, pressed: bool) -> None:
        """The external activation device (user stop): abort any motion, hold until released."""
        if pressed:
            if self.robot_mode == RobotMode.MOVE:
                self._end_motion(MoveStatus.EMERGENCY_ABORTED)
            self.robot_mode = RobotMode.USER_STOPPED
            self.q_hold = self.physics.q.copy()
        elif self.robot_mode == RobotMode.USER_STOPPED:
            self.robot_mode = RobotMode.IDLE

    def set_guiding(self, on: bool) -> None:
        """The pilot's guiding button: free the arm by hand (only from Idle)."""
        if on and self.robot_mode == RobotMode.IDLE:
            self.robot_mode = RobotMode.GUIDING
        elif not on and self.robot_mode == RobotMode.GUIDING:
            self.robot_mode = RobotMode.IDLE
            self.q_hold = self.physics.q.copy()
            self.joint.reset(self.q_hold)

    def safety_stop(self, status: MoveStatus) -> None:
        """An activated safety function (the brakes closing, the FCI switched off in Desk)
        ends a running motion with ``status``; the arm holds where it is."""
        if self.robot_mode == RobotMode.MOVE:
            self._end_motion(status)

    def client_lost(self) -> None:
        """The FCI client vanished: a running motion stops as on a real robot."""
        if self.robot_mode == RobotMode.MOVE:
            self._reflex(["communication_constraints_violation"])
        self.pending_final = None

    # -- the tick ----------------------------------------------------------------------

    def _reflex(self, names: list[str]) -> None:
        for n in names:
            self.errors[_ERROR_INDEX[n]] = 1
        was_moving = self.robot_mode == RobotMode.MOVE
        self.reflex_reason[:] = self.errors
        if was_moving:
            self._end_motion(MoveStatus.REFLEX_ABORTED)
        self.robot_mode = RobotMode.REFLEX
        log.info("reflex: %s", ", ".join(names))

    def _end_motion(self, status: MoveStatus) -> None:
        # A finished motion generator holds its last target; after a torque-controlled
        # motion (whose generator only idles at its start) the robot holds where it is.
        tracked = self.ctrl_mode != ControllerMode.EXTERNAL_CONTROLLER
        self.robot_mode = RobotMode.IDLE
        self.mg_mode = MotionGeneratorMode.IDLE
        self.ctrl_mode = ControllerMode.JOINT_IMPEDANCE
        if status == MoveStatus.SUCCESS and tracked:
            self.q_hold = self.joint.q.copy()
        else:
            self.q_hold = self.physics.q.copy()
        self.joint.reset(self.q_hold)
        self.tau_J_d[:] = 0.0
        self.pending_final = status
        self.async_gen = None

    def tick(self, command: Command | None, *, excused: bool = False) -> None:
        """Advance one tick. ``command`` is the client's answer to the last state (None
        when it was lost or outside a motion). ``excused``: a missing command is not the
        client's fault (the robot itself was late), so it is extrapolated like a lost
        one but not counted against the client."""
        if self.robot_mode == RobotMode.MOVE:
            torque = self._motion_tick(command, excused)
            if self.robot_mode != RobotMode.MOVE:
                torque = self._hold_torque()
        else:
            torque = self._hold_torque()
        self._apply(torque)

    def configure_end_effector(
        self, mass: float, com: np.ndarray, inertia: np.ndarray, F_T_NE: np.ndarray
    ) -> None:
        """The end effector as the Desk now configures it (checked there): the load
        (``mass`` [kg], ``com`` [m], ``inertia`` [kg m^2]) and the frame ``F_T_NE`` the
        robot reports and computes ``O_T_EE`` with. The physics keeps the hand the scene
        mounts (the simulated robot compensates its true weight, where a real one would
        compensate the configured load)."""
        self.m_ee = float(mass)
        self.F_x_Cee = np.array(com, dtype=float)
        self.I_ee = np.array(inertia, dtype=float)
        self._set_frame(F_T_NE)
        self._fill_static()
        self.cart.reset(self.physics.flange_pose_at(self.physics.q) @ self.F_T_EE)

    def _set_frame(self, F_T_NE: np.ndarray) -> None:
        """The end effector's frame (flange to nominal EE), with the kinematics and the
        compiled tick that compute O_T_EE in it."""
        self.F_T_NE = np.array(F_T_NE, dtype=float)
        if not np.array_equal(self.F_T_NE, self._kin_frame):
            self._kin = get_kinematics(self.spec, F_T_EE=self.F_T_NE)
            self._kin_frame = self.F_T_NE.copy()
            self._fast = fastpath.load(self)

    def drive_to(self, q: np.ndarray) -> None:
        """Move the arm to ``q`` [rad] on a path of the robot's own (the Desk's pack pose),
        while idle; :attr:`driving` says when it is there. Anything else the robot does
        (a motion, guiding, a stop) ends the drive where the arm is."""
        self.drive = JointDrive(self.spec, self.physics.q, q)

    @property
    def driving(self) -> bool:
        return self.drive is not None

    def _hold_torque(self) -> np.ndarray:
        drive = self.drive
        if drive is not None and self.robot_mode != RobotMode.IDLE:
            self.drive = drive = None
            self.q_hold = self.physics.q.copy()
        if self.robot_mode == RobotMode.GUIDING:
            return -2.0 * self.physics.dq  # hand guiding: gravity-compensated, lightly damped
        if drive is not None:
            q_d, dq_d, ddq_d = drive.advance(DT)
            if drive.finished:
                self.drive = None
                self.q_hold = drive.goal.copy()
            self.joint.reset(q_d)  # the state's q_d: the path, as the robot reports it
            return self._joint_tracking(q_d, dq_d, ddq_d)
        return self._joint_tracking(self.q_hold, _REST, _REST)

    def _joint_tracking(self, q_d: np.ndarray, dq_d: np.ndarray, ddq_d: np.ndarray) -> np.ndarray:
        """The joint impedance controller's torque tracking (q_d, dq_d, ddq_d) at the
        stiffness the client set (K_theta), compiled where the tick is; a buffer the next
        call reuses."""
        fast = self._fast
        if fast is not None:
            return fast.joint_tracking(
                self.physics, q_d, dq_d, ddq_d, self.K_theta, self._K_default
            )
        scale = np.maximum(self.K_theta / self._K_default, 1e-3)
        return self.physics.joint_tracking_torque(q_d, dq_d, ddq_d, scale)

    def _motion_tick(self, command: Command | None, excused: bool = False) -> np.ndarray:
        if self.async_gen is not None:
            self._async_tick(command)
        elif command is None and self.first_command:
            return self._hold_torque()  # the client's loop has not started yet
        elif command is None and excused:
            self._extrapolate()
        elif command is None:
            self.consecutive_lost += 1
            self.lost_total += 1
            self._record_success(False)
            if self.consecutive_lost >= MAX_CONSECUTIVE_LOST:
                self._reflex(["communication_constraints_violation"])
                return np.zeros(7)
            if not self.first_command:
                self._extrapolate()
        else:
            self.consecutive_lost = 0
            self.received_total += 1
            self._record_success(True)
            status = self._accept(command)
            if status is not None:
                return np.zeros(7)
        if self.robot_mode != RobotMode.MOVE:
            return np.zeros(7)
        # Measured-state checks during motion.
        if self.contact_active or not self._measured_in_limits():
            flags = self._measured_violations()
            if flags:
                self._reflex(flags)
                return np.zeros(7)
        if self.ctrl_mode == ControllerMode.EXTERNAL_CONTROLLER:
            return self.tau_J_d.copy()
        tau = self._joint_tracking(self.joint.q, self.joint.dq, self.joint.ddq)
        self.tau_J_d[:] = tau
        return tau

    def _measured_in_limits(self) -> bool:
        """No joint beyond its position limits or its speed limit (with the robot's
        tolerance); a NaN passes here and is caught by the flags' own tests."""
        q, dq, fast = self.physics.q, self.physics.dq, self._fast
        if fast is not None:
            return fast.measured_in_limits(q, dq, self._q_lo, self._q_hi, self._dq_hi)
        return not (
            (q < self._q_lo).any() or (q > self._q_hi).any() or (np.abs(dq) > self._dq_hi).any()
        )

    def _finite(self, x: np.ndarray) -> bool:
        """No NaN and no infinity in the vector ``x``."""
        fast = self._fast
        return fast.all_finite(x) if fast is not None else all_finite(x)

    def _torque_in_limits(self, tau: np.ndarray) -> bool:
        """A torque command within the joints' range and rate limits (False for a NaN)."""
        fast = self._fast
        if fast is not None:
            return fast.torque_in_limits(tau, self.tau_J_d, self._tau_max, self._dtau_step)
        return bool(
            (np.abs(tau) <= self._tau_max).all()
            and (np.abs(tau - self.tau_J_d) <= self._dtau_step).all()
        )

    def _measured_violations(self) -> list[str]:
        """Flags of the checks on the measured state (position, velocity, contact)."""
        ph = self.physics
        flags = []
        if (ph.q < self._q_lo).any() or (ph.q > self._q_hi).any():
            flags.append("joint_position_limits_violation")
        if (np.abs(ph.dq) > self._dq_hi).any():
            flags.append("joint_velocity_violation")
        if (np.abs(self.tau_ext) > self.thresholds.upper_torque_nom).any():
            flags.append("joint_reflex")
        if self.state["cartesian_collision"].any():
            flags.append("cartesian_reflex")
        return flags

    def _record_success(self, ok: bool) -> None:
        i = self.success_i
        self.success_count += ok - self.success[i]
        self.success[i] = ok
        self.success_i = (i + 1) % SUCCESS_WINDOW
        self.success_rate = self.success_count / SUCCESS_WINDOW

    def _extrapolate(self) -> None:
        mg = self.mg_mode
        if mg in (MotionGeneratorMode.JOINT_POSITION, MotionGeneratorMode.JOINT_VELOCITY):
            self.joint.extrapolate()
        elif mg in (MotionGeneratorMode.CARTESIAN_POSITION, MotionGeneratorMode.CARTESIAN_VELOCITY):
            self.cart.extrapolate()
            self._track_cartesian(valid_elbow=False)
        # A lost torque command: the robot keeps the last torques (tau_J_d unchanged).

    def _accept(self, c: Command) -> MoveStatus | None:
        """Apply one received command; returns a final status if the motion ended."""
        mg = self.mg_mode
        external = self.ctrl_mode == ControllerMode.EXTERNAL_CONTROLLER
        if mg == MotionGeneratorMode.NONE:  # a torque-only motion (v7+): tested below
            finite = True
        elif mg == MotionGeneratorMode.JOINT_POSITION:
            finite = self._finite(c.q_c)
        elif mg == MotionGeneratorMode.JOINT_VELOCITY:
            finite = self._finite(c.dq_c)
        elif mg == MotionGeneratorMode.CARTESIAN_POSITION:
            finite = all_finite(c.O_T_EE_c, c.elbow_c)
        elif mg == MotionGeneratorMode.CARTESIAN_VELOCITY:
            finite = all_finite(c.O_dP_EE_c, c.elbow_c)
        else:
            finite = True
        # NaN fails every <= test: a torque command that is within its range and its
        # rate is finite, so one test each covers both on the common path.
        tau = c.tau_J_d
        tau_ok = not external or self._torque_in_limits(tau)
        if not finite or (not tau_ok and not all_finite(tau)):
            log.warning("motion aborted: non-finite value in command %d", c.message_id)
            self._end_motion(MoveStatus.INPUT_ERROR_ABORTED)
            return MoveStatus.INPUT_ERROR_ABORTED
        flags: list[str] = []
        if mg == MotionGeneratorMode.JOINT_POSITION:
            if self.first_command and np.any(np.abs(c.q_c - self.physics.q) > START_POSE_TOLERANCE):
                flags.append("joint_position_motion_generator_start_pose_invalid")
            self.joint.push_position(c.q_c)
            flags += self.joint.violations(self.spec, cartesian=False)
        elif mg == MotionGeneratorMode.JOINT_VELOCITY:
            self.joint.push_velocity(c.dq_c)
            flags += self.joint.violations(self.spec, cartesian=False)
        elif mg in (MotionGeneratorMode.CARTESIAN_POSITION, MotionGeneratorMode.CARTESIAN_VELOCITY):
            flags += self._accept_cartesian(c)
        if external:
            if not tau_ok:
                if (np.abs(tau - self.tau_J_d) > self._dtau_step).any():
                    flags.append("controller_torque_discontinuity")
                if (np.abs(tau) > self._tau_max).any():
                    flags.append("tau_J_range_violation")
            self.tau_J_d[:] = tau
        self.first_command = False
        if flags:
            self._reflex(flags)
            return MoveStatus.REFLEX_ABORTED
        finished = (
            c.motion_generation_finished
            if mg != MotionGeneratorMode.NONE
            else c.torque_command_finished
        )
        if finished or (c.torque_command_finished and external):
            self._end_motion(MoveStatus.SUCCESS)
            return MoveStatus.SUCCESS
        return None

    def _async_tick(self, c: Command | None) -> None:
        """One tick of the robot-side generator: a received command is the newest target
        (or, finished, the order to come to rest); the generator moves either way."""
        gen = self.async_gen
        assert gen is not None
        if c is not None:
            self.consecutive_lost = 0
            self.received_total += 1
            self._record_success(True)
            self.first_command = False
            if c.motion_generation_finished:
                gen.stop()  # libfranka's stopControl sends zeros: not a target
            elif not all_finite(c.q_c):
                log.warning("motion aborted: non-finite target in command %d", c.message_id)
                self._end_motion(MoveStatus.INPUT_ERROR_ABORTED)
                return
            else:
                gen.set_target(np.asarray(c.q_c, dtype=float))
        self.joint.push_position(gen.step())
        flags = self.joint.violations(self.spec, cartesian=False)
        if flags:  # the generator keeps the limits; this is the robot's own check
            self._reflex(flags)
        elif gen.stopping and gen.at_rest:
            self._end_motion(MoveStatus.SUCCESS)

    def _accept_cartesian(self, c: Command) -> list[str]:
        flags: list[str] = []
        if self.mg_mode == MotionGeneratorMode.CARTESIAN_POSITION:
            T = from_col_major(c.O_T_EE_c)
            if not is_valid_transform(T):
                return ["cartesian_position_motion_generator_invalid_frame"]
            if self.first_command and np.any(
                np.abs(pose_error(self.cart.T, T)) > START_CARTESIAN_TOLERANCE
            ):
                flags.append("cartesian_position_motion_generator_start_pose_invalid")
            self.cart.push_pose(T)
        else:
            self.cart.push_twist(np.asarray(c.O_dP_EE_c, dtype=float))
        flags += self.cart.violations(self.spec)
        if c.valid_elbow:
            sign = float(c.elbow_c[1])
            if sign not in (1.0, -1.0):
                flags.append("cartesian_motion_generator_elbow_sign_inconsistent")
            elif self.first_command and sign != self.elbow_c[1]:
                flags.append("cartesian_motion_generator_start_elbow_invalid")
            elif sign != self.elbow_c[1]:
                flags.append("cartesian_motion_generator_elbow_sign_inconsistent")
            q3 = float(c.elbow_c[0])
            if not self._q_min[2] <= q3 <= self._q_max[2]:
                flags.append("cartesian_motion_generator_elbow_limit_violation")
            delbow = (q3 - self.elbow_c[0]) / DT
            self.ddelbow_c[0] = (delbow - self.delbow_c[0]) / DT
            self.delbow_c[0] = delbow
            self.elbow_c[0] = q3
        self._track_cartesian(valid_elbow=bool(c.valid_elbow))
        flags += self.joint.violations(self.spec, cartesian=True)
        return flags

    def _track_cartesian(self, *, valid_elbow: bool) -> None:
        """Joint targets of the commanded pose: the robot's own IK from the last targets."""
        O_T_F = self.cart.T @ self._EE_T_F
        q3 = float(self.elbow_c[0]) if valid_elbow else None
        q = self.physics.solve_ik(O_T_F, self.joint.q, q3)
        self.joint.push_position(q)

    # -- for the compiled tick (panda_py.sim.compiled) ---------------------------------

    @property
    def compiled(self) -> bool:
        """Whether the tick's arithmetic runs compiled (:mod:`.fastpath`)."""
        return self._fast is not None

    @property
    def tau_max(self) -> np.ndarray:
        """The joints' torque limits [Nm] the commands are checked against."""
        return self._tau_max

    @property
    def dtau_step(self) -> np.ndarray:
        """The largest torque change per tick [Nm] a command may ask (with tolerance)."""
        return self._dtau_step

    def measured_limits(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """The measured state's limits with the robot's tolerance: q_min, q_max [rad],
        |dq| max [rad/s]."""
        return self._q_lo, self._q_hi, self._dq_hi

    def chain_constants(self) -> np.ndarray:
        """The packed kinematic chain to the nominal end effector (O_T_EE's)."""
        return self._kin.chain_constants

    def compiled_fill_ready(self) -> bool:
        """Whether the compiled fill may write the next state as the reference would:
        compiled kernels, NE_T_EE the identity, the motion's fields written once."""
        return self._fast is not None and self._NE_identity and self._filled_mode == self.mg_mode

    def compiled_fill_constants(self) -> tuple[np.ndarray, np.ndarray]:
        """The compiled fill's link bodies and constants (``_tick_jit.fill_state``)."""
        assert self._fast is not None
        return self._fast.fill_constants()

    def fill_state(self) -> None:
        """Fill the state's per-tick fields from the physics (after a step)."""
        self._fill_state()

    def fill_contacts(self) -> None:
        """The contact fields of the state's fill (after the rest of it)."""
        self._fill_contacts(self._T_view["O_T_EE"])

    # -- physics -----------------------------------------------------------------------

    def _apply(self, torque: np.ndarray) -> None:
        self.physics.step(torque, self.finger_force)
        self._fill_state()
