"""``RobotState`` and ``GripperState``: thin, lazy views over a received datagram.

A ``RobotState`` keeps the datagram's ``bytes``; each attribute converts its field to a
float64 NumPy array only when read (one ``frombuffer`` at the field's offset), so a
control loop pays only for the fields its callback uses and nothing is decoded up front.
Transforms are flat 16-vectors in column-major order and inertia tensors flat 9-vectors,
exactly as libfranka's ``std::array``s. Fields missing from older protocol versions read as
libfranka documents them (``O_ddP_O`` = (0, 0, -9.81), ``NE_T_EE`` = identity,
accelerometers zero).
"""

from __future__ import annotations

from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py.fci import Dialect
from panda_py.libfranka._wire import Layout, layout
from panda_py.libfranka.types import Duration, Errors, RobotMode
from panda_py.robots.params import GRAVITY

__all__ = ["GripperState", "RobotState", "TickState", "combine_load"]

FloatArray = NDArray[np.float64]

_IDENTITY16 = np.eye(4).reshape(16)
_F64 = np.dtype(np.float64)


def _array(name: str, doc: str) -> Any:
    def get(self: RobotState) -> FloatArray:
        return self._field(name)

    return property(get, doc=doc)


def _scalar(name: str, doc: str) -> Any:
    def get(self: RobotState) -> float:
        return float(self._layout.scalars[name].unpack(self._data)[0])

    return property(get, doc=doc)


def _skew(v: FloatArray) -> FloatArray:
    return np.array([[0.0, -v[2], v[1]], [v[2], 0.0, -v[0]], [-v[1], v[0], 0.0]])


def combine_load(
    m_ee: float,
    F_x_Cee: Any,
    I_ee: Any,
    m_load: float,
    F_x_Cload: Any,
    I_load: Any,
) -> tuple[float, FloatArray, FloatArray]:
    """End effector plus payload as one rigid body, as libfranka combines them:
    ``(m_total [kg], F_x_Ctotal (3,) [m], I_total (9,) column-major [kg m^2] about the
    combined centre of mass)`` by the parallel-axis theorem. Inputs: masses [kg], centres
    of mass in the flange frame [m], inertias (9,) column-major about each own centre."""
    m_total = float(m_ee) + float(m_load)
    c_ee = np.asarray(F_x_Cee, dtype=np.float64).reshape(3)
    c_load = np.asarray(F_x_Cload, dtype=np.float64).reshape(3)
    if m_total > 0.0:
        c_total = (float(m_ee) * c_ee + float(m_load) * c_load) / m_total
    else:
        c_total = np.zeros(3)
    I_total = np.zeros((3, 3))
    for m, c, inertia in ((m_ee, c_ee, I_ee), (m_load, c_load, I_load)):
        I_c = np.asarray(inertia, dtype=np.float64).reshape(3, 3, order="F")
        S = _skew(c - c_total)
        I_total += I_c - float(m) * (S @ S)  # I + m (|r|^2 1 - r r^T)
    return m_total, c_total, I_total.reshape(9, order="F")


class RobotState:
    """The robot's state at one 1 ms tick (libfranka's ``franka::RobotState``).

    Attributes are NumPy float64 arrays (libfranka's ``std::array``s), floats for the
    masses and the success rate, ``time`` a :class:`Duration` (the robot's tick counter in
    ms), ``robot_mode`` a :class:`RobotMode`, ``current_errors``/``last_motion_errors``
    :class:`Errors`.
    """

    __slots__ = ("_data", "_dialect", "_layout")

    def __init__(self, dialect: Dialect, data: bytes | np.void | np.ndarray) -> None:
        """A state of ``dialect``'s layout from a datagram's ``bytes`` (or a state record
        of ``dialect.state_dtype``)."""
        if type(data) is not bytes:
            if isinstance(data, (np.void, np.ndarray)):
                data = dialect.encode_state(data)
            else:
                data = bytes(data)
            if len(data) < dialect.state_size:
                raise ValueError(
                    f"data: expected a RobotState v{dialect.version} of {dialect.state_size} "
                    f"bytes, got {len(data)} bytes"
                )
        self._dialect = dialect
        self._layout: Layout = layout(dialect)
        self._data: bytes = data

    @classmethod
    def from_bytes(cls, dialect: Dialect, data: bytes) -> RobotState:
        """Decode one RobotState datagram of ``dialect``'s layout (raises
        ``ProtocolError`` if it is too short)."""
        dialect.decode_state(data)  # the size check
        return cls(dialect, bytes(data))

    @property
    def _record(self) -> np.void:
        """The whole state as a (read-only) record of ``dialect.state_dtype``."""
        return self._dialect.decode_state(self._data)

    def _field(self, name: str) -> FloatArray:
        # one struct unpack and one array construction: fewer NumPy entry points than
        # frombuffer + astype, which counts when the caches are cold (see ._wire)
        unpack, offset, shape = self._layout.arrays[name]
        out = np.array(unpack(self._data, offset), _F64)
        return out if shape is None else out.reshape(shape)

    @property
    def raw(self) -> bytes:
        """The state as the robot sent it (its protocol version's datagram)."""
        return self._data

    def raw_fields(self, names: tuple[str, ...]) -> bytes:
        """The raw bytes of the fields ``names`` (in that order): a cheap key of what
        they hold, e.g. to notice that the load changed without decoding it."""
        spans = self._layout.spans(names)
        data = self._data
        if len(spans) == 1:  # (the load's fields: one slice a tick)
            a, b = spans[0]
            return data[a:b]
        return b"".join([data[a:b] for a, b in spans])

    @property
    def version(self) -> int:
        """The protocol version this state was decoded with."""
        return self._dialect.version

    @property
    def message_id(self) -> int:
        """The robot's tick counter [ms]."""
        return int(self._layout.header.unpack(self._data)[0])

    @property
    def time(self) -> Duration:
        """Robot time since power-up, from the tick counter [ms]."""
        return Duration(self.message_id)

    @property
    def robot_mode(self) -> RobotMode:
        """The robot's mode (:class:`~panda_py.libfranka.RobotMode`: idle, move, guiding,
        reflex, user stopped, ...)."""
        return RobotMode(self._layout.header.unpack(self._data)[3])

    @property
    def current_errors(self) -> Errors:
        """Errors active now (the ``errors`` field)."""
        return Errors(self._record["errors"])

    @property
    def last_motion_errors(self) -> Errors:
        """Errors that aborted the last motion (the ``reflex_reason`` field)."""
        return Errors(self._record["reflex_reason"])

    @property
    def motion_generator_mode(self) -> int:
        """Wire value of the motion generator (:class:`panda_py.fci.MotionGeneratorMode`)."""
        return int(self._layout.header.unpack(self._data)[1])

    @property
    def controller_mode(self) -> int:
        """Wire value of the active controller (:class:`panda_py.fci.ControllerMode`)."""
        return int(self._layout.header.unpack(self._data)[2])

    @property
    def F_T_NE(self) -> FloatArray:
        """Flange -> nominal end effector (16,) column-major [m]; ``F_T_EE`` before v4."""
        if self._dialect.has_F_T_NE:
            return self._field("F_T_NE")
        return self._field("F_T_EE")

    @property
    def NE_T_EE(self) -> FloatArray:
        """Nominal end effector -> end effector (16,) column-major [m]; identity before v4."""
        if self._dialect.has_F_T_NE:
            return self._field("NE_T_EE")
        return _IDENTITY16.copy()

    @property
    def O_ddP_O(self) -> FloatArray:
        """Base acceleration (3,) [m/s^2]; (0, 0, -9.81) before protocol v5."""
        if self._dialect.has_O_ddP_O:
            return self._field("O_ddP_O")
        return np.array(GRAVITY, dtype=np.float64)

    @property
    def accelerometer_top(self) -> FloatArray:
        """(6, 3) [m/s^2] per joint 1..6 (protocol v10; zeros before)."""
        if self._dialect.has_accelerometers:
            return self._field("accelerometer_top")
        return np.zeros((6, 3))

    @property
    def accelerometer_bottom(self) -> FloatArray:
        """(6, 3) [m/s^2] per joint 1..6 (protocol v10; zeros before)."""
        if self._dialect.has_accelerometers:
            return self._field("accelerometer_bottom")
        return np.zeros((6, 3))

    def _total(self) -> tuple[float, FloatArray, FloatArray]:
        return combine_load(
            self.m_ee, self._field("F_x_Cee"), self._field("I_ee"), self.m_load,
            self._field("F_x_Cload"), self._field("I_load"),
        )  # fmt: skip

    @property
    def m_total(self) -> float:
        """End effector plus load mass [kg]."""
        return self.m_ee + self.m_load

    @property
    def F_x_Ctotal(self) -> FloatArray:
        """Combined centre of mass of end effector and load in the flange frame (3,) [m]."""
        return self._total()[1]

    @property
    def I_total(self) -> FloatArray:
        """Combined inertia about ``F_x_Ctotal`` (9,) column-major [kg m^2]."""
        return self._total()[2]

    O_T_EE = _array("O_T_EE", "Measured end-effector pose in the base frame (16,) [m].")
    O_T_EE_d = _array("O_T_EE_d", "Last desired end-effector pose (16,) [m].")
    F_T_EE = _array("F_T_EE", "Flange -> end effector (16,) [m].")
    EE_T_K = _array("EE_T_K", "End effector -> stiffness frame K (16,) [m].")
    m_ee = _scalar("m_ee", "End-effector mass [kg].")
    I_ee = _array("I_ee", "End-effector inertia about its centre of mass (9,) [kg m^2].")
    F_x_Cee = _array("F_x_Cee", "End-effector centre of mass in the flange frame (3,) [m].")
    m_load = _scalar("m_load", "Payload mass [kg].")
    I_load = _array("I_load", "Payload inertia about its centre of mass (9,) [kg m^2].")
    F_x_Cload = _array("F_x_Cload", "Payload centre of mass in the flange frame (3,) [m].")
    elbow = _array("elbow", "Measured elbow (joint-3 position [rad], joint-4 flip sign).")
    elbow_d = _array("elbow_d", "Desired elbow.")
    elbow_c = _array("elbow_c", "Commanded elbow.")
    delbow_c = _array("delbow_c", "Commanded elbow velocity [rad/s].")
    ddelbow_c = _array("ddelbow_c", "Commanded elbow acceleration [rad/s^2].")
    tau_J = _array("tau_J", "Measured link-side joint torque (7,) [Nm].")
    tau_J_d = _array("tau_J_d", "Desired torque without gravity (7,) [Nm].")
    dtau_J = _array("dtau_J", "Derivative of the measured torque (7,) [Nm/s].")
    q = _array("q", "Measured joint position (7,) [rad].")
    q_d = _array("q_d", "Desired joint position (7,) [rad].")
    dq = _array("dq", "Measured joint velocity (7,) [rad/s].")
    dq_d = _array("dq_d", "Desired joint velocity (7,) [rad/s].")
    ddq_d = _array("ddq_d", "Desired joint acceleration (7,) [rad/s^2].")
    joint_contact = _array("joint_contact", "Contact level per joint (7,) [0/1].")
    cartesian_contact = _array("cartesian_contact", "Contact level per Cartesian axis (6,).")
    joint_collision = _array("joint_collision", "Collision level per joint (7,) [0/1].")
    cartesian_collision = _array("cartesian_collision", "Collision per Cartesian axis (6,).")
    tau_ext_hat_filtered = _array("tau_ext_hat_filtered", "External torque, filtered (7,) [Nm].")
    O_F_ext_hat_K = _array("O_F_ext_hat_K", "External wrench at K, base frame (6,) [N, Nm].")
    K_F_ext_hat_K = _array("K_F_ext_hat_K", "External wrench at K, K frame (6,) [N, Nm].")
    O_dP_EE_d = _array("O_dP_EE_d", "Desired end-effector twist (6,) [m/s, rad/s].")
    O_T_EE_c = _array("O_T_EE_c", "Last commanded end-effector pose (16,) [m].")
    O_dP_EE_c = _array("O_dP_EE_c", "Last commanded twist (6,) [m/s, rad/s].")
    O_ddP_EE_c = _array("O_ddP_EE_c", "Last commanded acceleration (6,) [m/s^2, rad/s^2].")
    theta = _array("theta", "Motor position (7,) [rad].")
    dtheta = _array("dtheta", "Motor velocity (7,) [rad/s].")
    control_command_success_rate = _scalar(
        "control_command_success_rate", "Fraction of the last commands that arrived [0..1]."
    )

    def __reduce__(self) -> tuple[Any, ...]:
        # the dialect (a per-version singleton) travels as its version number, so states
        # cross process boundaries (e.g. in ControlException.log)
        return (_state_from_version, (self._dialect.version, self._data))

    def __repr__(self) -> str:
        return (
            f"RobotState(time={self.message_id} ms, robot_mode={self.robot_mode.name}, "
            f"q={np.round(self.q, 4).tolist()})"
        )

    def __str__(self) -> str:
        """Every field, as libfranka's ``operator<<`` prints a ``RobotState`` (and so
        ``print(panda.get_state())`` in panda-python): ``{"O_T_EE": [1,0,...], ...,
        "robot_mode": "Idle", "time": 106}``, numbers as C++ streams them (6 digits)."""
        parts = []
        for name in PRINTED_FIELDS:
            try:
                value = getattr(self, name)
            except (AttributeError, KeyError):
                continue  # a field this protocol version does not carry
            parts.append(f'"{name}": {_streamed(value)}')
        parts.append(f'"current_errors": {self.current_errors}')
        parts.append(f'"last_motion_errors": {self.last_motion_errors}')
        parts.append(
            f'"control_command_success_rate": {_streamed(self.control_command_success_rate)}'
        )
        parts.append(f'"robot_mode": "{self.robot_mode.name[1:]}"')
        parts.append(f'"time": {self.message_id}')
        return "{" + ", ".join(parts) + "}"


# The fields libfranka's operator<< prints, in its order (src/robot_state.cpp).
PRINTED_FIELDS = (
    "O_T_EE", "O_T_EE_d", "F_T_NE", "NE_T_EE", "F_T_EE", "EE_T_K", "m_ee", "F_x_Cee", "I_ee",
    "m_load", "F_x_Cload", "I_load", "m_total", "F_x_Ctotal", "I_total", "elbow", "elbow_d",
    "elbow_c", "delbow_c", "ddelbow_c", "tau_J", "tau_J_d", "dtau_J", "q", "dq", "q_d",
    "dq_d", "ddq_d", "joint_contact", "cartesian_contact", "joint_collision",
    "cartesian_collision", "tau_ext_hat_filtered", "O_F_ext_hat_K", "K_F_ext_hat_K",
    "O_dP_EE_d", "O_ddP_O", "O_T_EE_c", "O_dP_EE_c", "O_ddP_EE_c", "theta", "dtheta",
)  # fmt: skip


def _streamed(value: Any) -> str:
    """A number or an array as C++'s ``ostream`` writes doubles (``%g``, 6 digits),
    arrays as ``[a,b,c]``."""
    a = np.asarray(value, dtype=float)
    if a.ndim == 0:
        return f"{float(a):g}"
    return "[" + ",".join(f"{x:g}" for x in a.ravel(order="F")) + "]"


def _state_from_version(version: int, data: bytes) -> RobotState:
    from panda_py.fci import dialect

    return RobotState(dialect(version), data)


class GripperState:
    """The Franka Hand's state: ``width``/``max_width`` [m], ``is_grasped``,
    ``temperature`` [°C], ``time`` (:class:`Duration`, the gripper's tick counter)."""

    __slots__ = ("is_grasped", "max_width", "temperature", "time", "width")

    def __init__(self, record: np.void) -> None:
        self.width = float(record["width"])
        self.max_width = float(record["max_width"])
        self.is_grasped = bool(record["is_grasped"])
        self.temperature = int(record["temperature"])
        self.time = Duration(int(record["message_id"]))

    def __repr__(self) -> str:
        return (
            f"GripperState(width={self.width:.4f}, max_width={self.max_width:.4f}, "
            f"is_grasped={self.is_grasped}, temperature={self.temperature})"
        )


class TickState(RobotState):
    """A state as a 1 kHz loop's laws read it within one tick (an extension of ours): each
    array field is decoded once, on its first read, and every later read returns the same
    read-only array (a law, the walls and the model read ``q`` five times a tick). Copy an
    array to keep it past the tick or to change it."""

    __slots__ = ("_bulk", "_cache")

    def __init__(self, dialect: Dialect, data: bytes | np.void | np.ndarray) -> None:
        super().__init__(dialect, data)
        self._cache: dict[str, FloatArray] = {}
        self._bulk: FloatArray | None = None

    def _field(self, name: str) -> FloatArray:
        out = self._cache.get(name)
        if out is None:
            # the state's array fields decoded in one call at the first read, each field
            # a slice of that (one NumPy call a field instead of an unpack and an array)
            where = self._layout.bulk_slices.get(name)
            if where is not None:
                bulk = self._bulk
                if bulk is None:
                    bulk = self._bulk = self._layout.decode_bulk(self._data)
                start, stop, shape = where
                out = bulk[start:stop] if shape is None else bulk[start:stop].reshape(shape)
            else:
                out = super()._field(name)
                out.flags.writeable = False
            self._cache[name] = out
        return out
