"""``Robot``: a Franka arm over FCI, in pure Python, speaking every protocol version 3-10.

    robot = Robot("172.16.0.2")            # negotiates the robot's protocol version
    state = robot.read_once()
    robot.control(lambda s, dt: Torques(np.zeros(7)))   # runs until motion_finished

It connects with the newest protocol version; a robot that answers "incompatible" says
which version it speaks, and the client reconnects speaking that one.
"""

from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable
from typing import Any

import numpy as np

from panda_py import fci
from panda_py.checks import timeout as _timeout
from panda_py.checks import vector as _vec
from panda_py.fci import Command
from panda_py.libfranka._connection import RobotConnection
from panda_py.libfranka._motion import MotionSession
from panda_py.libfranka._network import TCP_TIMEOUT
from panda_py.libfranka._variants import NamedControlMixin
from panda_py.libfranka.errors import (
    IncompatibleVersionException,
    InvalidOperationException,
    ModelException,
)
from panda_py.libfranka.limits import RateLimits
from panda_py.libfranka.model import Model
from panda_py.libfranka.realtime import check_realtime
from panda_py.libfranka.state import RobotState
from panda_py.libfranka.types import RealtimeConfig
from panda_py.robots.params import RobotKind, RobotSpec, get_robot, robot_for_protocol

__all__ = ["Robot"]

log = logging.getLogger("panda_py.libfranka")

#: Robot TCP requests other than motions wait this long for their response [s].
REQUEST_TIMEOUT = TCP_TIMEOUT


def collision_thresholds(args: tuple[Any, ...], kwargs: dict[str, Any]) -> dict[str, Any]:
    """``set_collision_behavior``'s 4 or 8 arguments (positional or by name) as the 8
    checked arrays the robot takes, by their wire names."""
    eight = fci.COLLISION_THRESHOLD_FIELDS
    four = ("lower_torque_thresholds", "upper_torque_thresholds", "lower_force_thresholds",
            "upper_force_thresholds")  # fmt: skip
    n = len(args) + len(kwargs)
    names = eight if n == 8 else four if n == 4 else None
    if names is None:
        raise ValueError(f"set_collision_behavior: expected 4 or 8 arguments, got {n}")
    values = dict(zip(names, args, strict=False))
    for key, value in kwargs.items():
        if key not in names or key in values:
            raise ValueError(f"set_collision_behavior: unexpected argument {key!r}")
        values[key] = value
    arrays = {
        k: _vec(k, values[k], 7 if "torque" in k else 6, "[Nm]" if "torque" in k else "[N]")
        for k in names
    }
    if n == 4:
        arrays = {k: arrays[k.replace("_acceleration", "").replace("_nominal", "")] for k in eight}
    return arrays


class Robot(NamedControlMixin):
    """A Franka arm (libfranka's ``franka::Robot`` with panda-py's Python names).

    ``hostname``: the robot's (FCI) address. ``realtime_config``: ``kIgnore`` (default,
    as panda-py 1.1.1: control loops try ``SCHED_FIFO`` and warn once without it) or
    ``kEnforce`` (raise :class:`RealtimeException` without it). ``log_size``: states kept
    for :attr:`ControlException.log`. ``version``: force one protocol version instead of
    negotiating. ``robot``: "fer" or "fr3" (the limits of the client-side rate limiter);
    by default from the protocol version (<= 5: FER, >= 6: FR3).
    """

    def __init__(
        self,
        hostname: str,
        realtime_config: RealtimeConfig = RealtimeConfig.kIgnore,
        log_size: int = 50,
        *,
        version: int | None = None,
        robot: str | RobotKind | RobotSpec | None = None,
        timeout: float = REQUEST_TIMEOUT,
    ) -> None:
        config = RealtimeConfig.parse(realtime_config)
        if isinstance(log_size, bool) or not isinstance(log_size, int) or log_size < 0:
            raise ValueError(f"log_size: expected an int >= 0, got {log_size!r}")
        if version is not None and version not in fci.SUPPORTED_VERSIONS:
            raise ValueError(f"version: expected one of {fci.SUPPORTED_VERSIONS}, got {version!r}")
        timeout = _timeout("timeout", timeout)
        spec = None if robot is None else get_robot(robot)
        check_realtime(config)  # as libfranka >= 0.18: before anything is sent
        self._realtime_config = config
        self._log: deque[RobotState] = deque(maxlen=log_size)
        self._session: MotionSession | None = None
        self._conn = self._negotiate(hostname, version, timeout)
        if spec is None:
            spec = robot_for_protocol(self._conn.server_version)
        self._spec = spec
        self._limits = RateLimits.for_robot(spec)

    @staticmethod
    def _negotiate(hostname: str, version: int | None, timeout: float) -> RobotConnection:
        offer = fci.NEWEST_VERSION if version is None else version
        try:
            return RobotConnection(hostname, offer, timeout=timeout)
        except IncompatibleVersionException as exc:
            server = exc.server_version
            if version is not None or server == offer or server not in fci.SUPPORTED_VERSIONS:
                raise IncompatibleVersionException(
                    f"libfranka: Incompatible library version (server version: {server}, "
                    f"library version: {offer}). This client speaks protocol versions "
                    f"{fci.SUPPORTED_VERSIONS[0]}-{fci.SUPPORTED_VERSIONS[-1]}.",
                    server_version=server,
                    library_version=offer,
                ) from exc
            log.info("robot speaks protocol v%d; reconnecting with it", server)
            return RobotConnection(hostname, server, timeout=timeout)

    # --- lifecycle --------------------------------------------------------------------

    def close(self) -> None:
        """Stop any motion this object runs and close the connection."""
        session = self._session
        if session is not None and not session.done and not self._conn.net.closed:
            session.cancel()
        self._session = None
        self._conn.close()

    def __enter__(self) -> Robot:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def __del__(self) -> None:
        conn = getattr(self, "_conn", None)
        if conn is not None:
            conn.close()

    # --- information --------------------------------------------------------------------

    @property
    def spin_wait(self) -> bool:
        """How control loops wait for the next state (an extension of ours, not
        libfranka's): True (the default), sleep until shortly before it is due and then
        poll for it, which catches it sooner on a machine whose threads wake slowly;
        False, sleep until it arrives, which costs no CPU while waiting. Measured in
        ``Panda``'s control process (``benchmarks/bench_panda.py``), polling bought
        nothing there: it is off."""
        return bool(self._conn.net.spin)

    @spin_wait.setter
    def spin_wait(self, on: bool) -> None:
        if not isinstance(on, bool):
            raise ValueError(f"spin_wait: expected True or False, got {on!r}")
        self._conn.net.spin = on

    def server_version(self) -> int:
        """The robot's protocol version."""
        return int(self._conn.server_version)

    @property
    def skipped_states(self) -> int:
        """States a read (:meth:`read`, :meth:`read_once`) passed over for a newer one queued
        behind them, as libfranka's hands the newest: the caller was late. Counted since
        connecting; where a stream's times have gaps, these are this client's and the rest
        the network's (or the robot's). Beyond libfranka."""
        return self._conn.net.skipped_states

    @property
    def robot_spec(self) -> RobotSpec:
        """The robot parameters used for limits and the model (FER or FR3)."""
        return self._spec

    @property
    def rate_limits(self) -> RateLimits:
        """The limits the client-side rate limiter (``limit_rate``) enforces on this
        robot's commands (FER or FR3: libfranka's ``rate_limiting.h``)."""
        return self._limits

    def read_once(self) -> RobotState:
        """A fresh robot state: queued states are discarded and the next one is awaited (up
        to 1 s), as libfranka's ``readOnce`` does, so a setter's effect is visible in it."""
        self._no_motion("read_once")
        return RobotState(self._conn.dialect, self._conn.receive_fresh_state())

    def read(self, read_callback: Callable[[RobotState], bool]) -> None:
        """Call ``read_callback(state)`` for every new state until it returns False."""
        if not callable(read_callback):
            raise ValueError(f"read_callback: expected a callable, got {read_callback!r}")
        self._no_motion("read")
        d = self._conn.dialect
        while read_callback(RobotState(d, self._conn.receive_state())):
            pass

    def _no_motion(self, what: str) -> None:
        if self._session is not None and not self._session.done:
            raise InvalidOperationException(
                f"libfranka: {what}: not while a motion runs (use its readOnce())"
            )

    def load_model(self) -> Model:
        """The dynamics model of this robot, computed locally (no download, no robot)."""
        try:
            return Model(self._spec)
        except ValueError as exc:
            raise ModelException(f"libfranka: cannot build the model: {exc}") from exc

    def get_robot_model(self) -> str:
        """The robot's URDF (GetRobotModel, protocol v8 and later)."""
        if not self._conn.dialect.has_get_robot_model:
            raise InvalidOperationException(
                f"libfranka: GetRobotModel needs protocol v8+, the robot speaks "
                f"v{self.server_version()}"
            )
        return bytes(self._conn.execute(Command.GET_ROBOT_MODEL)["urdf"]).decode()

    # --- for a loop that owns this robot (an extension of ours, not libfranka's) -----------

    def fileno(self) -> int:
        """The socket the robot's states arrive on, for ``select``/``poll``: readable
        when a state is waiting. A loop that also waits on other things (the control
        process of ``Panda`` waits on its requests too) waits on this, then takes the
        state with :meth:`receive_raw_state`."""
        return self._conn.net.state_fileno()

    @property
    def state_dtype(self) -> np.dtype:
        """The numpy record type of this robot's raw states (its protocol version's)."""
        return self._conn.dialect.state_dtype

    def receive_raw_state(self) -> bytes:
        """The newest state datagram newer than the last one taken (waits up to 1 s), as
        the robot sent it; :meth:`decode_state` makes it a :class:`RobotState`. Queued
        older states are skipped, as a 1 kHz loop that fell behind wants."""
        self._no_motion("receive_raw_state")
        return self._conn.receive_state()

    def decode_state(self, data: bytes, state_type: type[RobotState] = RobotState) -> RobotState:
        """A raw state of this robot (:meth:`receive_raw_state`, ``RobotState.raw``) as a
        :class:`RobotState` (or ``state_type``, a subclass such as ``TickState``)."""
        if not (isinstance(state_type, type) and issubclass(state_type, RobotState)):
            raise ValueError(f"state_type: expected RobotState or a subclass, got {state_type!r}")
        dialect = self._conn.dialect
        if not isinstance(data, (bytes, bytearray, memoryview)):
            raise ValueError(f"data: expected a raw state (bytes), got {type(data).__name__}")
        if len(data) < dialect.state_size:
            raise ValueError(
                f"data: expected a RobotState v{dialect.version} of {dialect.state_size} bytes, "
                f"got {len(data)} bytes"
            )
        return state_type(dialect, bytes(data))

    # --- commands -------------------------------------------------------------------------

    def _execute(self, command: Command, **fields: Any) -> dict[str, Any]:
        return self._conn.execute(command, **fields)

    def set_collision_behavior(self, *args: Any, **kwargs: Any) -> None:
        """Contact/collision thresholds. Either 8 arguments
        ``(lower_torque_thresholds_acceleration, upper_torque_thresholds_acceleration,
        lower_torque_thresholds_nominal, upper_torque_thresholds_nominal,
        lower_force_thresholds_acceleration, upper_force_thresholds_acceleration,
        lower_force_thresholds_nominal, upper_force_thresholds_nominal)`` or 4
        ``(lower_torque_thresholds, upper_torque_thresholds, lower_force_thresholds,
        upper_force_thresholds)`` used for both phases. Torques (7,) [Nm], forces (6,)
        [N, N, N, Nm, Nm, Nm]."""
        self._execute(Command.SET_COLLISION_BEHAVIOR, **collision_thresholds(args, kwargs))

    def set_joint_impedance(self, K_theta: Any) -> None:
        """Stiffness of the internal joint impedance controller (7,) [Nm/rad]."""
        self._execute(Command.SET_JOINT_IMPEDANCE, K_theta=_vec("K_theta", K_theta, 7, "[Nm/rad]"))

    def set_cartesian_impedance(self, K_x: Any) -> None:
        """Stiffness of the internal Cartesian impedance controller (6,) [N/m, Nm/rad]."""
        self._execute(Command.SET_CARTESIAN_IMPEDANCE, K_x=_vec("K_x", K_x, 6, "[N/m, Nm/rad]"))

    def set_guiding_mode(self, guiding_mode: Any, elbow: bool) -> None:
        """Which axes (x, y, z, R, P, Y) are free in guiding mode, and the elbow."""
        axes = np.asarray(guiding_mode)
        if axes.shape != (6,) or axes.dtype.kind not in "bi":
            raise ValueError(f"guiding_mode: expected 6 bools, got {guiding_mode!r}")
        if not isinstance(elbow, (bool, np.bool_)):
            raise ValueError(f"elbow: expected a bool, got {elbow!r}")
        self._execute(Command.SET_GUIDING_MODE, guiding_mode=axes.astype(bool), nullspace=elbow)

    def set_k(self, EE_T_K: Any) -> None:
        """End effector -> stiffness frame K (16 column-major, or 4x4) [m]."""
        self._execute(Command.SET_EE_TO_K, EE_T_K=_vec("EE_T_K", EE_T_K, 16, "(transform)"))

    def set_ee(self, NE_T_EE: Any) -> None:
        """Nominal end effector -> end effector (16 column-major, or 4x4) [m]. Protocol v3
        has no nominal frame: there the transform is sent as flange -> end effector."""
        T = _vec("NE_T_EE", NE_T_EE, 16, "(transform)")
        if self._conn.dialect.has_F_T_NE:
            self._execute(Command.SET_NE_TO_EE, NE_T_EE=T)
        else:
            self._execute(Command.SET_F_TO_EE, F_T_EE=T)

    set_K = set_k
    set_EE = set_ee

    def set_load(self, load_mass: float, F_x_Cload: Any, load_inertia: Any) -> None:
        """Payload: mass [kg], centre of mass in the flange frame (3,) [m], inertia about
        it (9 column-major or 3x3) [kg m^2]."""
        m = _vec("load_mass", [load_mass], 1, "[kg]")[0]
        if m < 0.0:
            raise ValueError(f"load_mass: expected a mass >= 0 [kg], got {m}")
        self._execute(Command.SET_LOAD, m_load=float(m),
                      F_x_Cload=_vec("F_x_Cload", F_x_Cload, 3, "[m]"),
                      I_load=_vec("load_inertia", load_inertia, 9, "[kg m^2]"))  # fmt: skip

    def set_filters(self, joint_position_filter_frequency: float,
                    joint_velocity_filter_frequency: float,
                    cartesian_position_filter_frequency: float,
                    cartesian_velocity_filter_frequency: float,
                    controller_filter_frequency: float) -> None:  # fmt: skip
        """Robot-side low-pass cut-offs [Hz] (1..1000; protocol v3-v5 only, removed in
        libfranka 0.10 in favour of the client-side filter)."""
        if not self._conn.dialect.has_set_filters:
            raise InvalidOperationException(
                f"libfranka: SetFilters exists up to protocol v5; the robot speaks "
                f"v{self.server_version()}. Use cutoff_frequency= of control() instead."
            )
        values = _vec("filter frequencies", [joint_position_filter_frequency,
                      joint_velocity_filter_frequency, cartesian_position_filter_frequency,
                      cartesian_velocity_filter_frequency, controller_filter_frequency], 5, "[Hz]")  # fmt: skip  # noqa: E501
        names = fci.dialect(self.server_version()).request_payload(Command.SET_FILTERS).field_names
        self._execute(Command.SET_FILTERS, **dict(zip(names, values.tolist(), strict=True)))

    def automatic_error_recovery(self) -> None:
        """Clear errors after a reflex (the robot returns to Idle)."""
        self._execute(Command.AUTOMATIC_ERROR_RECOVERY)

    def stop(self) -> None:
        """Stop a running motion (StopMove). An active control started here is cancelled;
        a callback loop (running in another thread, or calling this from its callback)
        then ends with ``ControlException`` ("Move command preempted!")."""
        session = self._session
        if session is not None and not session.done and session.caller_driven:
            session.cancel()
            self._session = None
            return
        self._execute(Command.STOP_MOVE)
