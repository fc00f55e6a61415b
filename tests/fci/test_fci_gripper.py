"""Gripper v3 and vacuum gripper v1 wire formats."""

from __future__ import annotations

import struct

import numpy as np
import pytest

import panda_py.fci as fci
from panda_py.fci import gripper, vacuum
from panda_py.fci.gripper import GripperCommand, GripperStatus


def test_gripper_constants() -> None:
    assert gripper.GRIPPER_VERSION == 3
    assert gripper.GRIPPER_COMMAND_PORT == 1338
    assert gripper.GRIPPER_HEADER.size == 10
    assert gripper.GRIPPER_CONNECT_REQUEST.size == gripper.GRIPPER_CONNECT_RESPONSE.size == 14
    assert gripper.GRIPPER_STATE_DTYPE.itemsize == 23
    assert [int(c) for c in GripperCommand] == [0, 1, 2, 3, 4]
    assert [s.name for s in GripperStatus] == ["SUCCESS", "FAIL", "UNSUCCESSFUL", "ABORTED"]
    sizes = {c: gripper.GRIPPER_REQUESTS[c].size for c in GripperCommand}
    assert sizes == {
        GripperCommand.CONNECT: 4,
        GripperCommand.HOMING: 0,
        GripperCommand.GRASP: 40,
        GripperCommand.MOVE: 16,
        GripperCommand.STOP: 0,
    }


def test_gripper_connect() -> None:
    request = gripper.encode_gripper_connect_request(4321)
    assert request == struct.pack("<HIIHH", 0, 0, 14, 3, 4321)
    assert gripper.decode_gripper_connect_request(request) == (0, 3, 4321)
    response = gripper.encode_gripper_connect_response(0, gripper.GripperConnectStatus.SUCCESS)
    assert response == struct.pack("<HIIHH", 0, 0, 14, 0, 3)
    assert gripper.decode_gripper_connect_response(response) == (
        0,
        gripper.GripperConnectStatus.SUCCESS,
        3,
    )
    with pytest.raises(fci.ProtocolError):
        gripper.decode_gripper_connect_request(request[:-1])
    with pytest.raises(fci.ProtocolError, match="GripperConnectStatus"):
        gripper.decode_gripper_connect_response(struct.pack("<HIIHH", 0, 0, 14, 7, 3))
    with pytest.raises(fci.ProtocolError, match="command 0"):
        gripper.decode_gripper_connect_request(struct.pack("<HIIHH", 2, 0, 14, 3, 1))


def test_gripper_grasp_and_move_round_trip() -> None:
    rng = np.random.default_rng(21)
    grasp = gripper.GRIPPER_REQUESTS[GripperCommand.GRASP]
    values = dict(zip(grasp.field_names, rng.uniform(0, 0.08, size=5).tolist(), strict=True))
    message = fci.encode_gripper_message(GripperCommand.GRASP, 6, grasp.encode(**values))
    assert len(message) == 50
    assert message[:10] == struct.pack("<HII", 2, 6, 50)
    assert struct.unpack("<5d", message[10:]) == tuple(
        values[k] for k in ("width", "epsilon_inner", "epsilon_outer", "speed", "force")
    )
    assert grasp.decode(message[10:]) == values
    move = gripper.GRIPPER_REQUESTS[GripperCommand.MOVE]
    assert move.encode(width=0.04, speed=0.1) == struct.pack("<2d", 0.04, 0.1)


def test_gripper_response_and_framer() -> None:
    responses = [
        fci.encode_gripper_message(
            GripperCommand.HOMING, 1, gripper.GRIPPER_RESPONSE.encode(status=0)
        ),
        fci.encode_gripper_message(
            GripperCommand.GRASP, 2, gripper.GRIPPER_RESPONSE.encode(status=2)
        ),
        fci.encode_gripper_message(GripperCommand.STOP, 3, b""),
    ]
    assert [len(r) for r in responses] == [12, 12, 10]
    stream = b"".join(responses)
    reader = fci.GripperMessageReader()
    got: list[fci.Message] = []
    for i in range(0, len(stream), 5):
        got += reader.feed(stream[i : i + 5])
    assert [m.raw for m in got] == responses
    assert [m.command for m in got] == [1, 2, 4]
    assert gripper.decode_gripper_status(got[1].payload) is GripperStatus.UNSUCCESSFUL
    with pytest.raises(fci.ProtocolError, match="GripperStatus"):
        gripper.decode_gripper_status(struct.pack("<H", 4))
    with pytest.raises(fci.ProtocolError, match=r"10\.\.1024"):
        fci.GripperMessageReader(max_size=1024).feed(struct.pack("<HII", 1, 1, 9))


def test_gripper_state() -> None:
    state = np.zeros((), gripper.GRIPPER_STATE_DTYPE)
    state["message_id"] = 77
    state["width"] = 0.0412
    state["max_width"] = 0.0801
    state["is_grasped"] = True
    state["temperature"] = 31
    data = gripper.encode_gripper_state(state)
    assert data == struct.pack("<Idd?H", 77, 0.0412, 0.0801, True, 31)
    got = gripper.decode_gripper_state(data + b"junk")  # longer: truncated
    assert (int(got["message_id"]), float(got["width"]), bool(got["is_grasped"])) == (
        77,
        0.0412,
        True,
    )
    with pytest.raises(fci.ProtocolError, match="23 bytes"):
        gripper.decode_gripper_state(data[:-1])
    with pytest.raises(ValueError, match="GRIPPER_STATE_DTYPE"):
        gripper.encode_gripper_state(np.zeros((), np.float64))


def test_vacuum() -> None:
    assert vacuum.VACUUM_COMMAND_PORT == 1339
    assert vacuum.VACUUM_STATE_DTYPE.itemsize == 16
    req = vacuum.VACUUM_REQUESTS[vacuum.VacuumCommand.VACUUM]
    payload = req.encode(vacuum=100, profile=vacuum.VacuumProfile.P2, timeout=-5)
    assert payload == struct.pack("<BBq", 100, 2, -5)
    message = vacuum.encode_vacuum_message(vacuum.VacuumCommand.VACUUM, 3, payload)
    assert message[:10] == struct.pack("<HII", 1, 3, 20)
    assert req.decode(payload) == {"vacuum": 100, "profile": 2, "timeout": -5}
    drop = vacuum.VACUUM_REQUESTS[vacuum.VacuumCommand.DROP_OFF]
    assert drop.encode(timeout=1000) == struct.pack("<q", 1000)
    status = vacuum.decode_vacuum_status(vacuum.VACUUM_RESPONSE.encode(status=3))
    assert status is vacuum.VacuumStatus.ABORTED
    connect = gripper.encode_gripper_connect_request(9, version=vacuum.VACUUM_VERSION)
    assert gripper.decode_gripper_connect_request(connect) == (0, 1, 9)
    state = np.zeros((), vacuum.VACUUM_STATE_DTYPE)
    state["part_present"] = True
    state["device_status"] = vacuum.VacuumDeviceStatus.ORANGE
    state["vacuum"] = -700
    data = vacuum.encode_vacuum_state(state)
    assert data == struct.pack("<I???Bii", 0, False, False, True, 2, 0, -700)
    assert int(vacuum.decode_vacuum_state(data)["vacuum"]) == -700
    with pytest.raises(fci.ProtocolError):
        vacuum.decode_vacuum_state(data[:15])
