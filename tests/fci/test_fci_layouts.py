"""Golden sizes, offsets, command ids and status numbering of the robot protocol dialects.

Expected values are transcribed from /work/shared/reference/fci-protocol.md (§4-§11) and,
for v3/v4/v6-v9, from libfranka-common's headers at the commits the libfranka releases pin.
"""

from __future__ import annotations

import numpy as np
import pytest

import panda_py.fci as fci
from panda_py.fci import (
    Command,
    CommandBaseStatus,
    ErrorRecoveryStatus,
    GetterSetterStatus,
    MoveStatus,
    StopMoveStatus,
)

VERSIONS = fci.SUPPORTED_VERSIONS

# §8 table: field -> (v5 offset, v10 offset); None = absent
STATE_OFFSETS = {
    "message_id": (0, 0),
    "O_T_EE": (8, 8),
    "O_T_EE_d": (136, 72),
    "F_T_EE": (264, 136),
    "EE_T_K": (392, 200),
    "F_T_NE": (520, 264),
    "NE_T_EE": (648, 328),
    "m_ee": (776, 392),
    "I_ee": (784, 396),
    "F_x_Cee": (856, 432),
    "m_load": (880, 444),
    "I_load": (888, 448),
    "F_x_Cload": (960, 484),
    "elbow": (984, 496),
    "elbow_d": (1000, 504),
    "tau_J": (1016, 512),
    "tau_J_d": (1072, 540),
    "dtau_J": (1128, 568),
    "q": (1184, 596),
    "q_d": (1240, 624),
    "dq": (1296, 652),
    "dq_d": (1352, 680),
    "ddq_d": (1408, 708),
    "joint_contact": (1464, 736),
    "cartesian_contact": (1520, 764),
    "joint_collision": (1568, 788),
    "cartesian_collision": (1624, 816),
    "tau_ext_hat_filtered": (1672, 840),
    "O_F_ext_hat_K": (1728, 868),
    "K_F_ext_hat_K": (1776, 892),
    "O_dP_EE_d": (1824, 916),
    "O_ddP_O": (1872, 940),
    "elbow_c": (1896, 952),
    "delbow_c": (1912, 960),
    "ddelbow_c": (1928, 968),
    "O_T_EE_c": (1944, 976),
    "O_dP_EE_c": (2072, 1040),
    "O_ddP_EE_c": (2120, 1064),
    "theta": (2168, 1088),
    "dtheta": (2224, 1116),
    "accelerometer_top": (None, 1144),
    "accelerometer_bottom": (None, 1216),
    "motion_generator_mode": (2280, 1288),
    "controller_mode": (2281, 1289),
    "errors": (2282, 1290),
    "reflex_reason": (2323, 1331),
    "robot_mode": (2364, 1372),
    "control_command_success_rate": (2365, 1373),
}

# RobotState size per version: 249 floats in v3, +32 (F_T_NE, NE_T_EE) in v4, +3 (O_ddP_O)
# and 2x4 error flags in v5; v10 float32 + 36 accelerometer floats.
STATE_SIZES = {3: 2085, 4: 2341, 5: 2373, 6: 2373, 7: 2373, 8: 2373, 9: 2373, 10: 1377}

V5_IDS = [
    "CONNECT",
    "MOVE",
    "STOP_MOVE",
    "GET_CARTESIAN_LIMIT",
    "SET_COLLISION_BEHAVIOR",
    "SET_JOINT_IMPEDANCE",
    "SET_CARTESIAN_IMPEDANCE",
    "SET_GUIDING_MODE",
    "SET_EE_TO_K",
    "SET_NE_TO_EE",
    "SET_LOAD",
    "SET_FILTERS",
    "AUTOMATIC_ERROR_RECOVERY",
    "LOAD_MODEL_LIBRARY",
]
V6_IDS = [n for n in V5_IDS if n not in ("GET_CARTESIAN_LIMIT", "SET_FILTERS")]
V8_IDS = [*V6_IDS, "GET_ROBOT_MODEL"]
V10_IDS = [n for n in V8_IDS if n != "LOAD_MODEL_LIBRARY"]
V3_IDS = [("SET_F_TO_EE" if n == "SET_NE_TO_EE" else n) for n in V5_IDS]
COMMAND_IDS = {
    3: V3_IDS,
    4: V5_IDS,
    5: V5_IDS,
    6: V6_IDS,
    7: V6_IDS,
    8: V8_IDS,
    9: V8_IDS,
    10: V10_IDS,
}

# total message sizes incl. the 12-byte header (§5, "observed on the wire")
REQUEST_MESSAGE_SIZES = {
    Command.STOP_MOVE: 12,
    Command.SET_COLLISION_BEHAVIOR: 428,
    Command.SET_JOINT_IMPEDANCE: 68,
    Command.SET_CARTESIAN_IMPEDANCE: 60,
    Command.SET_GUIDING_MODE: 19,
    Command.SET_EE_TO_K: 140,
    Command.SET_NE_TO_EE: 140,
    Command.SET_F_TO_EE: 140,
    Command.SET_LOAD: 116,
    Command.AUTOMATIC_ERROR_RECOVERY: 12,
    Command.LOAD_MODEL_LIBRARY: 14,
    Command.GET_ROBOT_MODEL: 12,
    Command.CONNECT: 16,
    Command.GET_CARTESIAN_LIMIT: 16,
    Command.SET_FILTERS: 52,
}


def test_supported_versions() -> None:
    assert fci.SUPPORTED_VERSIONS == (3, 4, 5, 6, 7, 8, 9, 10)
    assert fci.NEWEST_VERSION == 10 == max(fci.SUPPORTED_VERSIONS)


@pytest.mark.parametrize("version", VERSIONS)
def test_state_and_command_sizes(version: int) -> None:
    d = fci.dialect(version)
    assert d.version == version
    assert d.state_dtype.itemsize == d.state_size == STATE_SIZES[version]
    assert d.command_dtype.itemsize == d.command_size == (370 if version <= 6 else 371)
    assert ("torque_command_finished" in d.command_dtype.names) == (version >= 7)
    assert not d.state_dtype.isalignedstruct


@pytest.mark.parametrize(("column", "version"), [(0, 5), (1, 10)])
def test_state_offsets_match_reference(column: int, version: int) -> None:
    fields = fci.dialect(version).state_dtype.fields
    assert fields is not None
    expected = {k: v[column] for k, v in STATE_OFFSETS.items() if v[column] is not None}
    assert {k: fields[k][1] for k in fields} == expected
    # field order on the wire = offset order
    assert list(fields) == sorted(expected, key=expected.__getitem__)


@pytest.mark.parametrize("version", VERSIONS)
def test_state_field_types(version: int) -> None:
    d = fci.dialect(version)
    fields = d.state_dtype.fields
    assert fields is not None
    f = np.dtype("<f4" if version >= 10 else "<f8")
    assert fields["message_id"][0] == np.dtype("<u8")
    assert fields["O_T_EE"][0].shape == (16,)
    assert fields["O_T_EE"][0].base == f
    assert fields["control_command_success_rate"][0] == f
    for mode in ("motion_generator_mode", "controller_mode", "robot_mode"):
        assert fields[mode][0] == np.dtype("u1")
    n = 37 if version <= 4 else 41
    assert fields["errors"][0].shape == fields["reflex_reason"][0].shape == (n,)
    assert d.errors_count == n
    assert d.error_names == fci.ERROR_NAMES[:n]
    assert ("F_T_NE" in fields) == d.has_F_T_NE == (version >= 4)
    assert ("O_ddP_O" in fields) == d.has_O_ddP_O == (version >= 5)
    assert ("accelerometer_top" in fields) == d.has_accelerometers == (version >= 10)


def test_command_offsets() -> None:
    # §10 table
    expected = {
        "message_id": 0,
        "q_c": 8,
        "dq_c": 64,
        "O_T_EE_c": 120,
        "O_dP_EE_c": 248,
        "elbow_c": 296,
        "valid_elbow": 312,
        "motion_generation_finished": 313,
        "tau_J_d": 314,
        "torque_command_finished": 370,
    }
    fields = fci.dialect(10).command_dtype.fields
    assert fields is not None
    assert {k: v[1] for k, v in fields.items()} == expected
    v5 = fci.dialect(5).command_dtype.fields
    assert v5 is not None
    assert {k: v[1] for k, v in v5.items()} == {
        k: v for k, v in expected.items() if k != "torque_command_finished"
    }


def test_error_names() -> None:
    assert len(fci.ERROR_NAMES) == len(set(fci.ERROR_NAMES)) == 41
    # spot checks against the §9 table (libfranka's franka::Errors names)
    spots = {
        0: "joint_position_limits_violation",
        2: "self_collision_avoidance_violation",
        11: "joint_position_motion_generator_start_pose_invalid",
        23: "force_controller_desired_force_tolerance_violation",
        24: "start_elbow_sign_inconsistent",
        25: "communication_constraints_violation",
        31: "cartesian_position_motion_generator_invalid_frame",
        33: "joint_p2p_insufficient_torque_for_planning",
        34: "tau_J_range_violation",
        37: "cartesian_spline_motion_generator_violation",
        38: "joint_via_motion_generator_planning_joint_limit_violation",
        39: "base_acceleration_initialization_timeout",
    }
    assert {i: fci.ERROR_NAMES[i] for i in spots} == spots
    assert fci.ERROR_NAMES[36] == "joint_move_in_wrong_direction"  # last of the v4 flags
    assert fci.ERROR_NAMES[40] == "base_acceleration_invalid_reading"
    diff = [
        i for i, (a, b) in enumerate(zip(fci.ERROR_NAMES, fci.ERROR_STRINGS, strict=True)) if a != b
    ]
    assert diff == [31]


@pytest.mark.parametrize("version", VERSIONS)
def test_command_ids(version: int) -> None:
    d = fci.dialect(version)
    names = COMMAND_IDS[version]
    assert {c.name: i for c, i in d.command_ids.items()} == {n: i for i, n in enumerate(names)}
    for i, name in enumerate(names):
        assert d.command_for_id(i) is Command[name]
    assert d.command_for_id(len(names)) is None
    assert d.command_for_id(-1) is None
    assert d.has_get_cartesian_limit == d.has_set_filters == (version <= 5)
    assert d.has_load_model_library == (version <= 9)
    assert d.has_get_robot_model == (version >= 8)


def test_command_ids_reference_spot_checks() -> None:
    assert fci.dialect(5).command_ids[Command.SET_COLLISION_BEHAVIOR] == 4
    assert fci.dialect(10).command_ids[Command.SET_COLLISION_BEHAVIOR] == 3
    assert fci.dialect(5).command_ids[Command.LOAD_MODEL_LIBRARY] == 13
    assert fci.dialect(7).command_ids[Command.LOAD_MODEL_LIBRARY] == 11
    assert fci.dialect(9).command_ids[Command.GET_ROBOT_MODEL] == 12
    assert fci.dialect(10).command_ids[Command.GET_ROBOT_MODEL] == 11


@pytest.mark.parametrize("version", VERSIONS)
def test_request_message_sizes(version: int) -> None:
    d = fci.dialect(version)
    for command in d.command_ids:
        size = len(d.encode_request(command, 7))
        if command is Command.MOVE:
            assert size == (125 if version >= 10 else 68)
            assert d.move_request_dtype.itemsize == size - 12
        else:
            assert size == REQUEST_MESSAGE_SIZES[command], command
        assert d.request_payload(command).size == size - 12


@pytest.mark.parametrize("version", VERSIONS)
def test_response_message_sizes(version: int) -> None:
    d = fci.dialect(version)
    for command in d.command_ids:
        status = next(iter(d.status_type(command)))
        size = len(d.encode_response(command, 1, status))
        expected = {Command.CONNECT: 15, Command.GET_CARTESIAN_LIMIT: 166}.get(command, 13)
        assert size == expected, command


# wire order of every status enum: v3-v5 and v6-v10 (§6, §11)
MOVE_V5 = [
    "SUCCESS",
    "MOTION_STARTED",
    "PREEMPTED",
    "COMMAND_NOT_POSSIBLE_REJECTED",
    "START_AT_SINGULAR_POSE_REJECTED",
    "INVALID_ARGUMENT_REJECTED",
    "REFLEX_ABORTED",
    "EMERGENCY_ABORTED",
    "INPUT_ERROR_ABORTED",
    "ABORTED",
]
MOVE_V6 = [
    *MOVE_V5[:3],
    "PREEMPTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS",
    "COMMAND_REJECTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS",
    *MOVE_V5[3:],
]
SAFETY = "COMMAND_REJECTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS"
STATUS_ORDER = {
    MoveStatus: (MOVE_V5, MOVE_V6),
    GetterSetterStatus: (
        ["SUCCESS", "COMMAND_NOT_POSSIBLE_REJECTED", "INVALID_ARGUMENT_REJECTED"],
        ["SUCCESS", "COMMAND_NOT_POSSIBLE_REJECTED", "INVALID_ARGUMENT_REJECTED", SAFETY],
    ),
    StopMoveStatus: (
        [
            "SUCCESS",
            "COMMAND_NOT_POSSIBLE_REJECTED",
            "EMERGENCY_ABORTED",
            "REFLEX_ABORTED",
            "ABORTED",
        ],
        [
            "SUCCESS",
            "COMMAND_NOT_POSSIBLE_REJECTED",
            SAFETY,
            "EMERGENCY_ABORTED",
            "REFLEX_ABORTED",
            "ABORTED",
        ],
    ),
    ErrorRecoveryStatus: (
        [
            "SUCCESS",
            "COMMAND_NOT_POSSIBLE_REJECTED",
            "MANUAL_ERROR_RECOVERY_REQUIRED_REJECTED",
            "REFLEX_ABORTED",
            "EMERGENCY_ABORTED",
            "ABORTED",
        ],
        [
            "SUCCESS",
            "COMMAND_NOT_POSSIBLE_REJECTED",
            SAFETY,
            "MANUAL_ERROR_RECOVERY_REQUIRED_REJECTED",
            "REFLEX_ABORTED",
            "EMERGENCY_ABORTED",
            "ABORTED",
        ],
    ),
    CommandBaseStatus: (
        ["SUCCESS", "COMMAND_NOT_POSSIBLE_REJECTED"],
        ["SUCCESS", "COMMAND_NOT_POSSIBLE_REJECTED", SAFETY],
    ),
}


@pytest.mark.parametrize("version", VERSIONS)
@pytest.mark.parametrize("enum_cls", list(STATUS_ORDER))
def test_status_numbering(version: int, enum_cls: type) -> None:
    d = fci.dialect(version)
    order = STATUS_ORDER[enum_cls][0 if version <= 5 else 1]
    for wire, name in enumerate(order):
        member = enum_cls[name]
        assert d.encode_status(member) == wire
        assert d.decode_status(enum_cls, wire) is member
    with pytest.raises(fci.ProtocolError):
        d.decode_status(enum_cls, len(order))
    for member in enum_cls:
        if member.name not in order:
            with pytest.raises(ValueError, match="does not exist"):
                d.encode_status(member)


def test_status_spot_checks() -> None:
    d5, d10 = fci.dialect(5), fci.dialect(10)
    assert d5.encode_status(MoveStatus.REFLEX_ABORTED) == 6
    assert d10.encode_status(MoveStatus.REFLEX_ABORTED) == 8
    assert d5.encode_status(MoveStatus.COMMAND_NOT_POSSIBLE_REJECTED) == 3
    assert d10.encode_status(MoveStatus.COMMAND_NOT_POSSIBLE_REJECTED) == 5
    assert d10.decode_status(GetterSetterStatus, 3).name == SAFETY
    assert d5.decode_status(GetterSetterStatus, 2) is GetterSetterStatus.INVALID_ARGUMENT_REJECTED
    for d in (d5, d10):
        assert d.encode_status(fci.ConnectStatus.INCOMPATIBLE_LIBRARY_VERSION) == 1
    assert d5.encode_status(fci.LoadModelLibraryStatus.ERROR) == 1
    with pytest.raises(ValueError, match="does not exist"):
        d10.encode_status(fci.LoadModelLibraryStatus.ERROR)  # no LoadModelLibrary in v10


def test_status_types() -> None:
    d = fci.dialect(5)
    assert d.status_type(Command.MOVE) is MoveStatus
    assert d.status_type(Command.SET_LOAD) is GetterSetterStatus
    assert d.status_type(Command.GET_CARTESIAN_LIMIT) is GetterSetterStatus
    assert d.status_type(Command.AUTOMATIC_ERROR_RECOVERY) is ErrorRecoveryStatus
    assert d.status_type(Command.LOAD_MODEL_LIBRARY) is fci.LoadModelLibraryStatus
    assert fci.dialect(10).status_type(Command.GET_ROBOT_MODEL) is CommandBaseStatus
    with pytest.raises(ValueError, match="does not exist"):
        d.status_type(Command.GET_ROBOT_MODEL)


def test_decode_status_rejects_bad_arguments() -> None:
    d = fci.dialect(10)
    with pytest.raises(fci.ProtocolError, match=r"0\.\.11"):
        d.decode_status(MoveStatus, 12)
    with pytest.raises(fci.ProtocolError):
        d.decode_status(MoveStatus, -1)
    with pytest.raises(ValueError, match="status enum"):
        d.decode_status(fci.RobotMode, 0)
    with pytest.raises(ValueError, match="does not exist"):
        d.encode_status(fci.RobotMode.IDLE)


def test_move_enums() -> None:
    assert int(fci.MoveMotionGeneratorMode.NONE) == 4
    assert int(fci.MotionGeneratorMode.NONE) == 5
    # request enum = state enum - 1 (the state has IDLE at 0)
    for m in fci.MoveMotionGeneratorMode:
        assert fci.MotionGeneratorMode[m.name] == m + 1
    assert fci.dialect(6).has_motion_generator_none is False
    assert fci.dialect(7).has_motion_generator_none is True
    assert fci.dialect(7).has_torque_command_finished is True
    assert fci.dialect(9).has_async_motion_generator is False
    assert fci.dialect(10).has_async_motion_generator is True


@pytest.mark.parametrize("bad", [0, 1, 2, 11, -5])
def test_unsupported_version(bad: int) -> None:
    with pytest.raises(fci.ProtocolError, match=r"\(3, 4, 5, 6, 7, 8, 9, 10\)"):
        fci.dialect(bad)


def test_dialect_is_singleton_and_frozen() -> None:
    d = fci.dialect(5)
    assert fci.dialect(5) is d
    with pytest.raises(AttributeError):
        d.version = 6  # type: ignore[misc]
    with pytest.raises(TypeError):
        d.command_ids[Command.MOVE] = 3  # type: ignore[index]
    with pytest.raises(ValueError, match="version must be an int"):
        fci.dialect("5")  # type: ignore[arg-type]


def test_all_is_honest() -> None:
    for name in fci.__all__:
        assert hasattr(fci, name), name
    public = {n for n in dir(fci) if not n.startswith("_")}
    modules = {"codec", "enums", "gripper", "layouts", "move", "robot", "vacuum", "annotations"}
    assert public - modules == set(fci.__all__)
