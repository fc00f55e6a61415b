"""Per-version byte layouts of the robot protocol (UDP state/command, TCP payloads).

Facts from libfranka-common at the commits the libfranka releases pin as their ``common``
submodule (checked commit by commit, layouts only):

=======  ===========  ===================  ===============================================
version  common       libfranka            wire changes
=======  ===========  ===================  ===============================================
3        14069e1,     0.4.0-0.7.1          (baseline here) SetFToEE; 37 error flags
         6c99ef9,                          (0.6 added LoadModelLibrary X86/Windows, 0.7.1
         277a0fc                           ARM/ARM64: enum values only, layout unchanged)
4        af64d3e      0.8.0                F_T_NE, NE_T_EE in the state; SetNEToEE
5        e6aa0fc      0.9.0-0.9.2          O_ddP_O in the state; 41 error flags
6        ea26b89,     0.10.0-0.13.2        GetCartesianLimit, SetFilters removed (ids
         5adeec6                           renumbered); safety status codes inserted
7        dd768c8      0.13.3-0.13.6        Move kNone; RobotCommand.torque_command_finished
8        22b0837      0.14.0-0.14.2        GetRobotModel appended
9        cd38d0e      0.15.0-0.17.0        version bump only
10       d96c221      0.18.0-0.20.4        float32 state + accelerometers; LoadModelLibrary
                      (0.20.5-0.21.x:      removed; Move request + async generator fields
                      2e090a6, not public,
                      same sizes measured
                      on the binaries)
=======  ===========  ===================  ===============================================

Versions 1 and 2 (libfranka 0.1-0.3) are not supported.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from .codec import FieldSpec, PayloadCodec, packed_dtype
from .enums import (
    Command,
    CommandBaseStatus,
    ConnectStatus,
    ErrorRecoveryStatus,
    GetterSetterStatus,
    LoadModelLibraryStatus,
    MoveStatus,
    StopMoveStatus,
)

SUPPORTED_VERSIONS: tuple[int, ...] = (3, 4, 5, 6, 7, 8, 9, 10)
"""The robot protocol versions this package speaks (libfranka 0.4.0-0.21.x)."""
NEWEST_VERSION = 10
"""The newest robot protocol version spoken here, offered first on Connect."""


def errors_count(version: int) -> int:
    """Number of ``errors``/``reflex_reason`` flags: 37 up to v4, 41 from v5 on."""
    return 37 if version <= 4 else 41


#: SetCollisionBehavior's threshold fields in wire order: (lower, upper) pairs of joint
#: torques (7) [Nm] then Cartesian forces (6) [N, Nm], acceleration phase before nominal.
COLLISION_THRESHOLD_FIELDS = (
    "lower_torque_thresholds_acceleration", "upper_torque_thresholds_acceleration",
    "lower_torque_thresholds_nominal", "upper_torque_thresholds_nominal",
    "lower_force_thresholds_acceleration", "upper_force_thresholds_acceleration",
    "lower_force_thresholds_nominal", "upper_force_thresholds_nominal",
)  # fmt: skip


def state_float_fields() -> dict[str, int]:
    """The RobotState's float fields of the newest version in wire order -> number of
    values (older versions lack some, never reorder them)."""
    fields = state_fields(NEWEST_VERSION)
    out: dict[str, int] = {}
    for spec in fields[1:]:  # after message_id
        if spec[1] not in ("<f4", "<f8"):
            continue
        shape = spec[2] if len(spec) == 3 else 1
        out[spec[0]] = int(np.prod(shape))
    del out["control_command_success_rate"]  # a trailing scalar, not a state vector
    return out


def state_fields(version: int) -> list[FieldSpec]:
    """RobotState fields in wire order. 4x4 transforms are flat column-major 16-vectors."""
    f = "<f8" if version <= 9 else "<f4"  # v10 sends every float as float32
    n_err = errors_count(version)
    fields: list[FieldSpec] = [
        ("message_id", "<u8"),
        ("O_T_EE", f, 16),
        ("O_T_EE_d", f, 16),
        ("F_T_EE", f, 16),
        ("EE_T_K", f, 16),
    ]
    if version >= 4:
        fields += [("F_T_NE", f, 16), ("NE_T_EE", f, 16)]
    fields += [
        ("m_ee", f),
        ("I_ee", f, 9),
        ("F_x_Cee", f, 3),
        ("m_load", f),
        ("I_load", f, 9),
        ("F_x_Cload", f, 3),
        ("elbow", f, 2),
        ("elbow_d", f, 2),
    ]
    for name in ("tau_J", "tau_J_d", "dtau_J", "q", "q_d", "dq", "dq_d", "ddq_d"):
        fields.append((name, f, 7))
    fields += [
        ("joint_contact", f, 7),
        ("cartesian_contact", f, 6),
        ("joint_collision", f, 7),
        ("cartesian_collision", f, 6),
        ("tau_ext_hat_filtered", f, 7),
        ("O_F_ext_hat_K", f, 6),
        ("K_F_ext_hat_K", f, 6),
        ("O_dP_EE_d", f, 6),
    ]
    if version >= 5:
        fields.append(("O_ddP_O", f, 3))
    fields += [
        ("elbow_c", f, 2),
        ("delbow_c", f, 2),
        ("ddelbow_c", f, 2),
        ("O_T_EE_c", f, 16),
        ("O_dP_EE_c", f, 6),
        ("O_ddP_EE_c", f, 6),
        ("theta", f, 7),
        ("dtheta", f, 7),
    ]
    if version >= 10:
        # 6 sensors (joints 1-6; joint 7 has none) x (x, y, z) [m/s^2], sensor-major.
        fields += [("accelerometer_top", f, (6, 3)), ("accelerometer_bottom", f, (6, 3))]
    fields += [
        ("motion_generator_mode", "u1"),
        ("controller_mode", "u1"),
        ("errors", "u1", n_err),
        ("reflex_reason", "u1", n_err),
        ("robot_mode", "u1"),
        ("control_command_success_rate", f),
    ]
    return fields


def command_fields(version: int) -> list[FieldSpec]:
    """RobotCommand fields in wire order (always float64)."""
    fields: list[FieldSpec] = [
        ("message_id", "<u8"),
        ("q_c", "<f8", 7),
        ("dq_c", "<f8", 7),
        ("O_T_EE_c", "<f8", 16),
        ("O_dP_EE_c", "<f8", 6),
        ("elbow_c", "<f8", 2),
        ("valid_elbow", "?"),
        ("motion_generation_finished", "?"),
        ("tau_J_d", "<f8", 7),
    ]
    if version >= 7:
        fields.append(("torque_command_finished", "?"))
    return fields


def state_dtype(version: int) -> np.dtype[Any]:
    return packed_dtype(state_fields(version))


def command_dtype(version: int) -> np.dtype[Any]:
    return packed_dtype(command_fields(version))


def command_list(version: int) -> list[Command]:
    """Commands in wire-id order: ``command_list(v)[i]`` has id ``i``."""
    commands = [Command.CONNECT, Command.MOVE, Command.STOP_MOVE]
    if version <= 5:
        commands.append(Command.GET_CARTESIAN_LIMIT)
    commands += [
        Command.SET_COLLISION_BEHAVIOR,
        Command.SET_JOINT_IMPEDANCE,
        Command.SET_CARTESIAN_IMPEDANCE,
        Command.SET_GUIDING_MODE,
        Command.SET_EE_TO_K,
        Command.SET_F_TO_EE if version == 3 else Command.SET_NE_TO_EE,
        Command.SET_LOAD,
    ]
    if version <= 5:
        commands.append(Command.SET_FILTERS)
    commands.append(Command.AUTOMATIC_ERROR_RECOVERY)
    if version <= 9:
        commands.append(Command.LOAD_MODEL_LIBRARY)
    if version >= 8:
        commands.append(Command.GET_ROBOT_MODEL)
    return commands


_SAFETY_MOVE = (
    MoveStatus.PREEMPTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS,
    MoveStatus.COMMAND_REJECTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS,
)


def status_tables(version: int) -> dict[type, tuple[Any, ...]]:
    """Per status enum, its members in wire order (index = wire value) for ``version``."""
    safety = version >= 6
    move = [
        MoveStatus.SUCCESS,
        MoveStatus.MOTION_STARTED,
        MoveStatus.PREEMPTED,
        *(_SAFETY_MOVE if safety else ()),
        MoveStatus.COMMAND_NOT_POSSIBLE_REJECTED,
        MoveStatus.START_AT_SINGULAR_POSE_REJECTED,
        MoveStatus.INVALID_ARGUMENT_REJECTED,
        MoveStatus.REFLEX_ABORTED,
        MoveStatus.EMERGENCY_ABORTED,
        MoveStatus.INPUT_ERROR_ABORTED,
        MoveStatus.ABORTED,
    ]
    getter_setter = list(GetterSetterStatus)
    stop_move = list(StopMoveStatus)
    recovery = list(ErrorRecoveryStatus)
    base = list(CommandBaseStatus)
    if not safety:
        getter_setter.remove(GetterSetterStatus.COMMAND_REJECTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS)
        stop_move.remove(StopMoveStatus.COMMAND_REJECTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS)
        recovery.remove(ErrorRecoveryStatus.COMMAND_REJECTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS)
        base.remove(CommandBaseStatus.COMMAND_REJECTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS)
    tables: dict[type, tuple[Any, ...]] = {
        ConnectStatus: tuple(ConnectStatus),
        MoveStatus: tuple(move),
        GetterSetterStatus: tuple(getter_setter),
        StopMoveStatus: tuple(stop_move),
        ErrorRecoveryStatus: tuple(recovery),
        CommandBaseStatus: tuple(base),
    }
    if version <= 9:
        tables[LoadModelLibraryStatus] = tuple(LoadModelLibraryStatus)
    return tables


STATUS_TYPES: dict[Command, type] = {
    Command.CONNECT: ConnectStatus,
    Command.MOVE: MoveStatus,
    Command.STOP_MOVE: StopMoveStatus,
    Command.GET_CARTESIAN_LIMIT: GetterSetterStatus,
    Command.SET_COLLISION_BEHAVIOR: GetterSetterStatus,
    Command.SET_JOINT_IMPEDANCE: GetterSetterStatus,
    Command.SET_CARTESIAN_IMPEDANCE: GetterSetterStatus,
    Command.SET_GUIDING_MODE: GetterSetterStatus,
    Command.SET_EE_TO_K: GetterSetterStatus,
    Command.SET_F_TO_EE: GetterSetterStatus,
    Command.SET_NE_TO_EE: GetterSetterStatus,
    Command.SET_LOAD: GetterSetterStatus,
    Command.SET_FILTERS: GetterSetterStatus,
    Command.AUTOMATIC_ERROR_RECOVERY: ErrorRecoveryStatus,
    Command.LOAD_MODEL_LIBRARY: LoadModelLibraryStatus,
    Command.GET_ROBOT_MODEL: CommandBaseStatus,
}

_STATUS: list[FieldSpec] = [("status", "u1")]


def request_codecs(version: int) -> dict[Command, PayloadCodec]:
    """Request payload codecs (without the 12-byte header) of every command of ``version``."""
    move: list[FieldSpec] = [
        ("controller_mode", "<u4"),  # MoveControllerMode
        ("motion_generator_mode", "<u4"),  # MoveMotionGeneratorMode
        ("maximum_path_deviation", "<f8", 3),  # (translation, rotation, elbow)
        ("maximum_goal_pose_deviation", "<f8", 3),  # (translation, rotation, elbow)
    ]
    if version >= 10:
        move += [("use_async_motion_generator", "?"), ("maximum_velocity", "<f8", 7)]
    specs: dict[Command, list[FieldSpec]] = {
        Command.CONNECT: [("version", "<u2"), ("udp_port", "<u2")],
        Command.MOVE: move,
        Command.STOP_MOVE: [],
        Command.GET_CARTESIAN_LIMIT: [("id", "<i4")],
        Command.SET_COLLISION_BEHAVIOR: [
            (name, "<f8", 7 if "torque" in name else 6) for name in COLLISION_THRESHOLD_FIELDS
        ],
        Command.SET_JOINT_IMPEDANCE: [("K_theta", "<f8", 7)],
        Command.SET_CARTESIAN_IMPEDANCE: [("K_x", "<f8", 6)],
        Command.SET_GUIDING_MODE: [("guiding_mode", "?", 6), ("nullspace", "?")],
        Command.SET_EE_TO_K: [("EE_T_K", "<f8", 16)],
        Command.SET_F_TO_EE: [("F_T_EE", "<f8", 16)],
        Command.SET_NE_TO_EE: [("NE_T_EE", "<f8", 16)],
        Command.SET_LOAD: [("m_load", "<f8"), ("F_x_Cload", "<f8", 3), ("I_load", "<f8", 9)],
        Command.SET_FILTERS: [
            ("joint_position_filter_frequency", "<f8"),
            ("joint_velocity_filter_frequency", "<f8"),
            ("cartesian_position_filter_frequency", "<f8"),
            ("cartesian_velocity_filter_frequency", "<f8"),
            ("controller_filter_frequency", "<f8"),
        ],
        Command.AUTOMATIC_ERROR_RECOVERY: [],
        Command.LOAD_MODEL_LIBRARY: [("architecture", "u1"), ("system", "u1")],
        Command.GET_ROBOT_MODEL: [],
    }
    return {c: PayloadCodec(f"{c.value} request", specs[c]) for c in command_list(version)}


def response_codecs(version: int) -> dict[Command, PayloadCodec]:
    """Response payload codecs; ``status`` is the raw u8 (translate with the dialect)."""
    codecs: dict[Command, PayloadCodec] = {}
    for c in command_list(version):
        name = f"{c.value} response"
        if c is Command.CONNECT:
            codecs[c] = PayloadCodec(name, [*_STATUS, ("version", "<u2")])
        elif c is Command.GET_CARTESIAN_LIMIT:
            fields: list[FieldSpec] = [
                *_STATUS,
                ("object_world_size", "<f8", 3),
                ("object_frame", "<f8", 16),
                ("object_activation", "?"),
            ]
            codecs[c] = PayloadCodec(name, fields)
        elif c is Command.LOAD_MODEL_LIBRARY:
            codecs[c] = PayloadCodec(name, _STATUS, tail="library")  # shared-library bytes
        elif c is Command.GET_ROBOT_MODEL:
            codecs[c] = PayloadCodec(name, _STATUS, tail="urdf")  # URDF text, no terminator
        else:
            codecs[c] = PayloadCodec(name, _STATUS)
    return codecs
