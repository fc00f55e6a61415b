"""Round trips and error paths of the robot protocol codecs (payloads, state, command)."""

from __future__ import annotations

import pickle
import struct
from typing import Any

import numpy as np
import pytest

import panda_py.fci as fci
from panda_py.fci import Command, MoveStatus

VERSIONS = fci.SUPPORTED_VERSIONS


def random_fields(codec: fci.PayloadCodec, rng: np.random.Generator) -> dict[str, Any]:
    """Random values for every field of ``codec`` (plus a tail if it has one)."""
    fields: dict[str, Any] = {}
    assert codec.dtype.fields is not None or codec.size == 0
    for name in codec.field_names:
        sub = codec.dtype.fields[name][0]  # type: ignore[index]
        base, shape = sub.base, sub.shape
        if base.kind == "f":
            value: Any = rng.normal(scale=100.0, size=shape)
        elif base.kind == "b":
            value = rng.integers(0, 2, size=shape).astype(bool)
        else:
            info = np.iinfo(base)
            value = rng.integers(info.min, info.max, size=shape, endpoint=True, dtype=base)
        fields[name] = value.item() if shape == () else value
    if codec.tail:
        fields[codec.tail] = rng.bytes(int(rng.integers(0, 5000)))
    return fields


def assert_fields_equal(got: dict[str, Any], expected: dict[str, Any]) -> None:
    assert set(got) == set(expected)
    for key, value in expected.items():
        if isinstance(value, np.ndarray):
            np.testing.assert_array_equal(got[key], value, err_msg=key)
            assert got[key].flags.writeable
        else:
            assert got[key] == value, key
            assert type(got[key]) is type(value), key


@pytest.mark.parametrize("version", VERSIONS)
def test_request_round_trips(version: int) -> None:
    rng = np.random.default_rng(version)
    d = fci.dialect(version)
    for command in d.command_ids:
        codec = d.request_payload(command)
        for _ in range(3):
            fields = random_fields(codec, rng)
            command_id = int(rng.integers(0, 2**32))
            message = d.encode_request(command, command_id, **fields)
            wire, cid, size = fci.decode_header(message)
            assert (wire, cid, size) == (d.command_ids[command], command_id, len(message))
            assert d.command_for_id(wire) is command
            assert_fields_equal(d.decode_request(command, message[12:]), fields)


@pytest.mark.parametrize("version", VERSIONS)
def test_response_round_trips(version: int) -> None:
    rng = np.random.default_rng(100 + version)
    d = fci.dialect(version)
    for command in d.command_ids:
        codec = d.response_payload(command)
        for status in d.status_type(command):
            try:
                d.encode_status(status)
            except ValueError:
                continue  # not in this version
            fields = random_fields(codec, rng)
            del fields["status"]
            message = d.encode_response(command, 42, status, **fields)
            assert fci.decode_header(message) == (d.command_ids[command], 42, len(message))
            got_status, got = d.decode_response(command, message[12:])
            assert got_status is status
            assert_fields_equal(got, fields)


def test_move_request_layout_v5_and_v10() -> None:
    args = dict(
        controller_mode=fci.MoveControllerMode.EXTERNAL_CONTROLLER,
        motion_generator_mode=fci.MoveMotionGeneratorMode.JOINT_VELOCITY,
        maximum_path_deviation=fci.DEFAULT_DEVIATION,
        maximum_goal_pose_deviation=fci.DEFAULT_DEVIATION,
    )
    v5 = fci.dialect(5).encode_request(Command.MOVE, 3, **args)
    assert v5 == struct.pack("<IIIII6d", 1, 3, 68, 2, 1, *fci.DEFAULT_DEVIATION * 2)
    vel = np.arange(1.0, 8.0)
    v10 = fci.dialect(10).encode_request(
        Command.MOVE, 3, use_async_motion_generator=True, maximum_velocity=vel, **args
    )
    deviations = fci.DEFAULT_DEVIATION * 2
    assert v10 == struct.pack("<IIIII6d?7d", 1, 3, 125, 2, 1, *deviations, True, *vel)


def test_setter_and_tail_layouts() -> None:
    d = fci.dialect(5)
    load = d.encode_request(
        Command.SET_LOAD, 9, m_load=1.5, F_x_Cload=[0.1, 0.2, 0.3], I_load=np.eye(3).ravel()
    )
    assert load == struct.pack("<III13d", 10, 9, 116, 1.5, 0.1, 0.2, 0.3, *np.eye(3).ravel())
    guiding = d.encode_request(
        Command.SET_GUIDING_MODE, 1, guiding_mode=[1, 0, 1, 0, 0, 1], nullspace=True
    )
    assert guiding == struct.pack("<III7?", 7, 1, 19, 1, 0, 1, 0, 0, 1, 1)
    lml = d.encode_request(
        Command.LOAD_MODEL_LIBRARY,
        2,
        architecture=fci.LoadModelLibraryArchitecture.ARM64,
        system=fci.LoadModelLibrarySystem.LINUX,
    )
    assert lml == struct.pack("<IIIBB", 13, 2, 14, 3, 0)
    lib = bytes(range(256)) * 3
    response = d.encode_response(
        Command.LOAD_MODEL_LIBRARY, 2, fci.LoadModelLibraryStatus.SUCCESS, library=lib
    )
    assert response == struct.pack("<IIIB", 13, 2, 13 + len(lib), 0) + lib
    urdf = b'<robot name="fr3"/>'
    d10 = fci.dialect(10)
    response = d10.encode_response(
        Command.GET_ROBOT_MODEL, 5, fci.CommandBaseStatus.SUCCESS, urdf=urdf
    )
    assert response == struct.pack("<IIIB", 11, 5, 13 + len(urdf), 0) + urdf
    assert d10.decode_response(Command.GET_ROBOT_MODEL, response[12:]) == (
        fci.CommandBaseStatus.SUCCESS,
        {"urdf": urdf},
    )
    assert d10.encode_request(Command.GET_ROBOT_MODEL, 5) == struct.pack("<III", 11, 5, 12)


def test_status_wire_value_in_response() -> None:
    assert fci.dialect(5).encode_response(Command.MOVE, 4, MoveStatus.REFLEX_ABORTED)[12] == 6
    assert fci.dialect(10).encode_response(Command.MOVE, 4, MoveStatus.REFLEX_ABORTED)[12] == 8
    with pytest.raises(fci.ProtocolError):
        fci.dialect(5).decode_response(Command.MOVE, bytes([10]))
    with pytest.raises(ValueError, match="must be a MoveStatus"):
        fci.dialect(5).encode_response(Command.MOVE, 4, fci.GetterSetterStatus.SUCCESS)
    with pytest.raises(ValueError, match="does not exist"):
        fci.dialect(5).encode_response(
            Command.MOVE, 4, MoveStatus.PREEMPTED_DUE_TO_ACTIVATED_SAFETY_FUNCTIONS
        )


def test_payload_errors() -> None:
    d = fci.dialect(10)
    codec = d.request_payload(Command.SET_JOINT_IMPEDANCE)
    with pytest.raises(ValueError, match=r"'K_theta' must have shape \(7,\), got shape \(6,\)"):
        codec.encode(K_theta=np.ones(6))
    with pytest.raises(ValueError, match="shape"):
        codec.encode(K_theta=3000.0)  # no silent broadcasting
    with pytest.raises(ValueError, match="unknown field 'K_x'"):
        codec.encode(K_x=np.ones(6))
    with pytest.raises(ValueError, match="cannot hold"):
        d.request_payload(Command.MOVE).encode(controller_mode=-1)
    with pytest.raises(ValueError, match="takes no fields"):
        d.request_payload(Command.STOP_MOVE).encode(x=1)
    with pytest.raises(ValueError, match="urdf must be bytes"):
        d.response_payload(Command.GET_ROBOT_MODEL).encode(status=0, urdf="text")
    with pytest.raises(fci.ProtocolError, match="56 bytes, got 55 bytes"):
        codec.decode(bytes(55))
    with pytest.raises(fci.ProtocolError):
        codec.decode(bytes(57))
    with pytest.raises(fci.ProtocolError):
        d.request_payload(Command.STOP_MOVE).decode(b"\x00")
    with pytest.raises(fci.ProtocolError, match="at least 1 bytes"):
        d.response_payload(Command.GET_ROBOT_MODEL).decode(b"")
    with pytest.raises(ValueError, match="does not exist in robot protocol version 10"):
        d.request_payload(Command.SET_FILTERS)
    with pytest.raises(ValueError, match="command_id"):
        d.encode_request(Command.STOP_MOVE, -1)
    with pytest.raises(ValueError, match="command_id"):
        d.encode_request(Command.STOP_MOVE, 2**32)


def fill_random(record: np.ndarray, rng: np.random.Generator) -> None:
    for name in record.dtype.names:
        sub = record.dtype.fields[name][0]
        if sub.base.kind == "f":
            record[name] = rng.normal(size=sub.shape)
        elif sub.base.kind == "b":
            record[name] = rng.integers(0, 2, size=sub.shape).astype(bool)
        else:
            record[name] = rng.integers(0, 7, size=sub.shape)


@pytest.mark.parametrize("version", VERSIONS)
def test_state_round_trip(version: int) -> None:
    rng = np.random.default_rng(200 + version)
    d = fci.dialect(version)
    state = d.new_state()
    fill_random(state, rng)
    q = rng.normal(size=7)
    state["q"] = q
    state["message_id"] = 2**40 + 3
    data = d.encode_state(state)
    assert isinstance(data, bytes) and len(data) == d.state_size
    got = d.decode_state(data)
    assert got.tobytes() == data
    for name in d.state_dtype.names:
        np.testing.assert_array_equal(got[name], state[name], err_msg=name)
    assert got["message_id"] == 2**40 + 3
    if version >= 10:  # float32 on the wire: exact only up to float32 rounding
        np.testing.assert_allclose(got["q"], q, rtol=2**-24, atol=0)
        assert not np.array_equal(got["q"].astype(np.float64), q)
    else:
        np.testing.assert_array_equal(got["q"], q)
    # the wire bytes of q are what struct would produce
    offset = d.state_dtype.fields["q"][1]
    fmt = "<7f" if version >= 10 else "<7d"
    np.testing.assert_array_equal(struct.unpack_from(fmt, data, offset), got["q"])


def test_state_matches_reference_struct_format() -> None:
    rng = np.random.default_rng(7)
    for version, fmt in ((5, "<Q284dBB41s41sBd"), (10, "<Q320fBB41s41sBf")):
        d = fci.dialect(version)
        state = d.new_state()
        fill_random(state, rng)
        values = struct.unpack(fmt, d.encode_state(state))
        assert struct.calcsize(fmt) == d.state_size
        assert values[0] == state["message_id"]
        assert values[-1] == state["control_command_success_rate"]
        assert values[-2] == state["robot_mode"]
        assert values[-4] == state["errors"].tobytes()


def test_state_datagram_size_handling() -> None:
    d = fci.dialect(5)
    state = d.new_state()
    state["robot_mode"] = fci.RobotMode.MOVE
    data = d.encode_state(state)
    # longer datagrams are truncated like libfranka does
    got = d.decode_state(data + b"\xff" * 8)
    assert got["robot_mode"] == fci.RobotMode.MOVE
    assert got.tobytes() == data
    with pytest.raises(fci.ProtocolError, match="2373 bytes, got 2372 bytes"):
        d.decode_state(data[:-1])
    with pytest.raises(fci.ProtocolError):
        fci.dialect(10).decode_state(bytes(1376))
    with pytest.raises(ValueError, match="state_dtype"):
        d.encode_state(fci.dialect(10).new_state())
    decoded = d.decode_state(data)
    with pytest.raises(ValueError):  # read-only view of the datagram
        decoded["q"][0] = 1.0


@pytest.mark.parametrize("version", VERSIONS)
def test_command_round_trip(version: int) -> None:
    rng = np.random.default_rng(300 + version)
    d = fci.dialect(version)
    command = d.new_command()
    fill_random(command, rng)
    data = d.encode_command(command)
    assert len(data) == d.command_size
    got = d.decode_command(data)
    for name in d.command_dtype.names:
        np.testing.assert_array_equal(got[name], command[name], err_msg=name)
    with pytest.raises(fci.ProtocolError):
        d.decode_command(data[:-1])
    with pytest.raises(fci.ProtocolError):
        d.decode_command(data + b"\x00")
    with pytest.raises(ValueError, match="command_dtype"):
        d.encode_command(d.new_state())


def test_command_matches_reference_struct_format() -> None:
    rng = np.random.default_rng(11)
    d = fci.dialect(10)
    command = d.new_command()
    fill_random(command, rng)
    values = struct.unpack("<Q7d7d16d6d2d??7d?", d.encode_command(command))
    assert values[0] == command["message_id"]
    np.testing.assert_array_equal(values[1:8], command["q_c"])
    assert values[-1] == command["torque_command_finished"]
    np.testing.assert_array_equal(values[-8:-1], command["tau_J_d"])
    assert struct.calcsize("<Q7d7d16d6d2d??7d") == fci.dialect(5).command_size


def test_active_errors() -> None:
    d = fci.dialect(10)
    flags = np.zeros(41, np.uint8)
    flags[[6, 25]] = 1
    assert d.active_errors(flags) == ("joint_reflex", "communication_constraints_violation")
    with pytest.raises(ValueError, match=r"shape \(37,\)"):
        fci.dialect(4).active_errors(flags)


def test_connect_messages() -> None:
    request = fci.encode_connect_request(10, 40123)
    assert request == struct.pack("<IIIHH", 0, 0, 16, 10, 40123)
    assert fci.decode_connect_request(request) == (0, 10, 40123)
    response = fci.encode_connect_response(0, fci.ConnectStatus.INCOMPATIBLE_LIBRARY_VERSION, 9)
    assert response == struct.pack("<IIIBH", 0, 0, 15, 1, 9)
    assert fci.CONNECT_REQUEST.size == 16 and fci.CONNECT_RESPONSE.size == 15
    assert fci.decode_connect_response(response) == (
        0,
        fci.ConnectStatus.INCOMPATIBLE_LIBRARY_VERSION,
        9,
    )
    # the dialect's Connect codecs agree with the version-invariant structs
    for version in VERSIONS:
        d = fci.dialect(version)
        assert d.encode_request(Command.CONNECT, 0, version=version, udp_port=5) == (
            fci.encode_connect_request(version, 5)
        )
    with pytest.raises(fci.ProtocolError):
        fci.decode_connect_request(request[:-1])
    with pytest.raises(fci.ProtocolError, match="command 0"):
        fci.decode_connect_request(struct.pack("<IIIHH", 1, 0, 16, 10, 1))
    with pytest.raises(fci.ProtocolError, match="ConnectStatus"):
        fci.decode_connect_response(struct.pack("<IIIBH", 0, 0, 15, 3, 9))  # 2: busy
    with pytest.raises(ValueError, match="udp_port"):
        fci.encode_connect_request(10, 70000)
    with pytest.raises(ValueError, match="status"):
        fci.encode_connect_response(0, 0, 10)  # type: ignore[arg-type]


def test_protocol_error_is_structured() -> None:
    err = fci.ProtocolError("thing", "1 byte", "2 bytes")
    # corrupt wire data is not a caller's ValueError; it is this package's error
    assert isinstance(err, fci.FciError) and not isinstance(err, ValueError)
    assert str(err) == "thing: expected 1 byte, got 2 bytes"
    assert (err.what, err.expected, err.got) == ("thing", "1 byte", "2 bytes")
    back = pickle.loads(pickle.dumps(err))
    assert (type(back), str(back), back.what, back.got) == (
        fci.ProtocolError,
        str(err),
        "thing",
        "2 bytes",
    )
