"""Control loops: libfranka's callback style (``Robot.control`` and friends) and the
active-control style (``start_*_control`` returning :class:`ActiveControl`)."""

from __future__ import annotations

import gc
import typing
from collections.abc import Callable, Sequence
from typing import Any

from panda_py.fci import MoveControllerMode, MoveMotionGeneratorMode
from panda_py.libfranka._active import ActiveControl, RobotBase
from panda_py.libfranka._commander import Commander, check_cutoff
from panda_py.libfranka._motion import MotionSession
from panda_py.libfranka._warm import rehearsal
from panda_py.libfranka.async_control import check_maximum_velocities
from panda_py.libfranka.commands import (
    CartesianPose,
    CartesianVelocities,
    JointPositions,
    JointVelocities,
    Torques,
)
from panda_py.libfranka.errors import InvalidOperationException
from panda_py.libfranka.realtime import check_realtime, realtime_scope
from panda_py.libfranka.state import RobotState
from panda_py.libfranka.types import (
    ControllerMode,
    Duration,
)

__all__ = ["ActiveControl", "ControlMixin"]

_MOTIONS: dict[type, tuple[MoveMotionGeneratorMode, str]] = {
    JointPositions: (MoveMotionGeneratorMode.JOINT_POSITION, "joint_positions"),
    JointVelocities: (MoveMotionGeneratorMode.JOINT_VELOCITY, "joint_velocities"),
    CartesianPose: (MoveMotionGeneratorMode.CARTESIAN_POSITION, "cartesian_pose"),
    CartesianVelocities: (MoveMotionGeneratorMode.CARTESIAN_VELOCITY, "cartesian_velocities"),
}
_MOVE_CONTROLLER = {
    ControllerMode.kJointImpedance: MoveControllerMode.JOINT_IMPEDANCE,
    ControllerMode.kCartesianImpedance: MoveControllerMode.CARTESIAN_IMPEDANCE,
}

Callback = Callable[[RobotState, Duration], Any]


def _callback_kind(callback: Any, explicit: type | None) -> type:
    """What ``callback`` returns: ``explicit``, else its return annotation, else Torques."""
    if not callable(callback):
        raise ValueError(f"control_callback: expected a callable, got {callback!r}")
    if explicit is not None:
        if explicit is not Torques and explicit not in _MOTIONS:
            raise ValueError(
                f"motion: expected one of Torques, {', '.join(t.__name__ for t in _MOTIONS)}, "
                f"got {explicit!r}"
            )
        return explicit
    try:
        hint = typing.get_type_hints(callback).get("return")
    except Exception:  # unresolvable annotations: fall back to the default
        hint = None
    if hint is Torques or hint in _MOTIONS:
        return typing.cast(type, hint)
    return Torques


class ControlMixin(RobotBase):
    """``Robot``'s control methods."""

    def _start(
        self,
        controller: MoveControllerMode,
        generator: MoveMotionGeneratorMode,
        maximum_velocity: tuple[float, ...] | None = None,
    ) -> MotionSession:
        if self._session is not None and not self._session.done:
            raise InvalidOperationException("libfranka: Attempted to start multiple motions!")
        session = MotionSession(self._conn, controller, generator, self._log, maximum_velocity)
        self._session = session
        return session

    def _plan(
        self, kind: type, torque: bool, controller_mode: Any
    ) -> tuple[MoveControllerMode, MoveMotionGeneratorMode, bool]:
        """(Move controller, Move generator, whether a generator runs) for a loop."""
        if kind is Torques:  # torque only
            if self._conn.dialect.has_motion_generator_none:
                return MoveControllerMode.EXTERNAL_CONTROLLER, MoveMotionGeneratorMode.NONE, False
            # protocol <= 6: a joint velocity generator commanding zero (libfranka <= 0.13.2)
            return (
                MoveControllerMode.EXTERNAL_CONTROLLER,
                MoveMotionGeneratorMode.JOINT_VELOCITY,
                True,
            )
        generator = _MOTIONS[kind][0]
        if torque:
            return MoveControllerMode.EXTERNAL_CONTROLLER, generator, True
        try:
            controller = _MOVE_CONTROLLER[ControllerMode(controller_mode)]
        except (ValueError, KeyError):
            raise ValueError(
                f"controller_mode: expected ControllerMode.kJointImpedance or "
                f"kCartesianImpedance, got {controller_mode!r}"
            ) from None
        return controller, generator, True

    def control(
        self,
        control_callback: Callback,
        motion_generator_callback: Callback | None = None,
        *,
        controller_mode: ControllerMode = ControllerMode.kJointImpedance,
        limit_rate: bool = True,
        cutoff_frequency: float = 100.0,
        motion: type | None = None,
    ) -> None:
        """Run a 1 kHz control loop until a callback returns a command marked
        ``motion_finished``.

        * ``control(torque_cb)``: torque control (``Torques`` [Nm], gravity compensated);
        * ``control(torque_cb, motion_cb)``: torques plus a motion generator;
        * ``control(motion_cb, controller_mode=...)``: a motion generator tracked by the
          robot's joint or Cartesian impedance controller. What a lone callback returns is
          read from ``motion=`` (e.g. ``motion=JointPositions``), else from its return
          annotation, else it is taken to return ``Torques``.

        Callbacks get ``(RobotState, Duration since the previous call)``. ``limit_rate``
        and ``cutoff_frequency`` [Hz] (>= 1000 disables) as in libfranka.
        """
        limit_rate, cutoff_frequency = check_cutoff(limit_rate, cutoff_frequency)
        if motion_generator_callback is not None:
            if not callable(motion_generator_callback):
                raise ValueError(
                    f"motion_generator_callback: expected a callable, got "
                    f"{motion_generator_callback!r}"
                )
            _callback_kind(control_callback, Torques)
            kind = _callback_kind(motion_generator_callback, motion)
            if kind is Torques:
                raise ValueError("motion: the motion generator cannot return Torques")
            self._run(
                control_callback,
                motion_generator_callback,
                kind,
                controller_mode,
                limit_rate,
                cutoff_frequency,
            )
            return
        kind = _callback_kind(control_callback, motion)
        if kind is Torques:
            self._run(
                control_callback, None, Torques, controller_mode, limit_rate, cutoff_frequency
            )
        else:
            self._run(None, control_callback, kind, controller_mode, limit_rate, cutoff_frequency)

    def _run(
        self,
        control_cb: Callback | None,
        motion_cb: Callback | None,
        kind: type,
        controller_mode: Any,
        limit_rate: bool,
        cutoff_frequency: float,
    ) -> None:
        conn = self._conn
        d = conn.dialect
        controller, generator, has_mg = self._plan(kind, control_cb is not None, controller_mode)
        commander = Commander(d, self._limits, limit_rate, cutoff_frequency)
        torque = commander.torques
        convert = None if motion_cb is None else getattr(commander, _MOTIONS[kind][1])
        command = commander.buffer
        log = self._log
        gc_was_enabled = gc.isenabled()
        kinds = ((Torques,) if control_cb is not None else ()) + (
            (kind,) if motion_cb is not None else ()
        )
        net = conn.net
        with realtime_scope(self._realtime_config):
            session = self._start(controller, generator)
            send, receive = session.send, session.receive
            scratch = Commander(d, self._limits, limit_rate, cutoff_frequency)
            # No cyclic garbage collection inside the loop: a collection pass costs more
            # than a tick; cycles the callbacks create are collected after the motion.
            gc.disable()
            try:
                net.before_spin = rehearsal(conn, scratch, kinds)
                data = receive()  # libfranka skips the state that shows the modes
                prev = conn.last_id
                # Between reading a state and sending its command only what the answer
                # needs runs (logging waits until the command is out).
                while True:
                    state = RobotState(d, data)
                    mid = conn.last_id
                    dt = Duration(mid - prev)
                    prev = mid
                    if control_cb is not None:
                        if torque(control_cb(state, dt), data):
                            log.append(state)
                            break
                    if convert is not None:
                        if convert(motion_cb(state, dt), data):  # type: ignore[misc]
                            log.append(state)
                            break
                    send(command)
                    log.append(state)
                    data = receive()
                session.finish(command, motion=has_mg, control=control_cb is not None)
            except BaseException:
                session.cancel()
                raise
            finally:
                net.before_spin = None
                if gc_was_enabled:
                    gc.enable()
                if self._session is session:
                    self._session = None

    # --- active control (libfranka >= 0.15 / pylibfranka) ---------------------------------

    def _start_active(
        self,
        kind: type,
        controller_mode: Any,
        limit_rate: bool,
        cutoff_frequency: float,
        state_type: type[RobotState] = RobotState,
    ) -> ActiveControl:
        limit_rate, cutoff_frequency = check_cutoff(limit_rate, cutoff_frequency)
        check_realtime(self._realtime_config)
        controller, generator, has_mg = self._plan(kind, False, controller_mode)
        commander = Commander(self._conn.dialect, self._limits, limit_rate, cutoff_frequency)
        session = self._start(controller, generator)
        session.caller_driven = True
        convert = commander.torques if kind is Torques else getattr(commander, _MOTIONS[kind][1])
        return ActiveControl(
            self, session, commander, convert, control=kind is Torques, motion=has_mg,
            state_type=state_type,
        )  # fmt: skip

    def start_torque_control(
        self,
        *,
        limit_rate: bool = False,
        cutoff_frequency: float = 1000.0,
        state_type: type[RobotState] = RobotState,
    ) -> ActiveControl:
        """Start torque control driven by the caller (``writeOnce(Torques)``).
        ``state_type`` (an extension of ours): what ``readOnce`` returns, a
        :class:`RobotState` or a :class:`~panda_py.libfranka.state.TickState` (each field
        decoded once, read-only), which a loop whose laws read fields often wants."""
        if not (isinstance(state_type, type) and issubclass(state_type, RobotState)):
            raise ValueError(f"state_type: expected RobotState or a subclass, got {state_type!r}")
        return self._start_active(Torques, None, limit_rate, cutoff_frequency, state_type)

    def start_joint_position_control(
        self,
        controller_mode: ControllerMode = ControllerMode.kJointImpedance,
        *,
        limit_rate: bool = False,
        cutoff_frequency: float = 1000.0,
    ) -> ActiveControl:
        """Start a joint position generator driven by the caller."""
        return self._start_active(JointPositions, controller_mode, limit_rate, cutoff_frequency)

    def start_joint_velocity_control(
        self,
        controller_mode: ControllerMode = ControllerMode.kJointImpedance,
        *,
        limit_rate: bool = False,
        cutoff_frequency: float = 1000.0,
    ) -> ActiveControl:
        """Start a joint velocity generator driven by the caller."""
        return self._start_active(JointVelocities, controller_mode, limit_rate, cutoff_frequency)

    def start_async_joint_position_control(
        self,
        controller_mode: ControllerMode = ControllerMode.kJointImpedance,
        maximum_velocities: Sequence[float] | None = None,
    ) -> ActiveControl:
        """Start protocol v10's asynchronous joint position control (libfranka's
        ``startAsyncJointPositionControl``): each ``writeOnce(JointPositions)`` is a target
        the robot's own generator moves to at up to ``maximum_velocities`` [rad/s] (7, each
        > 0 and within the robot's limit; required, as in libfranka). Use it through
        :class:`~panda_py.libfranka.AsyncPositionControlHandler`."""
        velocity = check_maximum_velocities(self._limits.spec, maximum_velocities)
        check_realtime(self._realtime_config)
        controller, generator, has_mg = self._plan(JointPositions, False, controller_mode)
        commander = Commander(self._conn.dialect, self._limits, False, 1000.0)
        session = self._start(controller, generator, velocity)
        session.caller_driven = True
        return ActiveControl(
            self, session, commander, commander.joint_positions, control=False, motion=has_mg
        )

    def start_cartesian_pose_control(
        self,
        controller_mode: ControllerMode = ControllerMode.kJointImpedance,
        *,
        limit_rate: bool = False,
        cutoff_frequency: float = 1000.0,
    ) -> ActiveControl:
        """Start a Cartesian pose generator driven by the caller."""
        return self._start_active(CartesianPose, controller_mode, limit_rate, cutoff_frequency)

    def start_cartesian_velocity_control(
        self,
        controller_mode: ControllerMode = ControllerMode.kJointImpedance,
        *,
        limit_rate: bool = False,
        cutoff_frequency: float = 1000.0,
    ) -> ActiveControl:
        """Start a Cartesian velocity generator driven by the caller."""
        return self._start_active(
            CartesianVelocities, controller_mode, limit_rate, cutoff_frequency
        )
