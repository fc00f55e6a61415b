"""The Move request value (v10's asynchronous generator fields) and libfranka's
client-side TargetStatus rule."""

from __future__ import annotations

import struct

import pytest

import panda_py.fci as fci
from panda_py.fci import Command, MoveControllerMode, MoveRequest, RobotMode, TargetStatus

JP = fci.MoveMotionGeneratorMode.JOINT_POSITION
VELOCITY = (0.655, 0.655, 0.655, 0.655, 1.315, 1.315, 1.315)  # pylibfranka's example


def round_trip(version: int, request: MoveRequest) -> tuple[bytes, MoveRequest]:
    d = fci.dialect(version)
    message = d.encode_request(Command.MOVE, 7, **request.fields(d))
    return message, MoveRequest.from_fields(d.decode_request(Command.MOVE, message[12:]))


def test_async_move_round_trips_in_v10_with_its_velocities() -> None:
    request = MoveRequest(MoveControllerMode.JOINT_IMPEDANCE, JP, maximum_velocity=VELOCITY)
    message, back = round_trip(10, request)
    assert back == request and back.is_async
    assert len(message) == 125  # as libfranka 0.21 sends it (fci-protocol.md section 5)
    assert message[12 + 56] == 1  # use_async_motion_generator
    assert struct.unpack_from("<7d", message, 12 + 57) == VELOCITY


@pytest.mark.parametrize("version", fci.SUPPORTED_VERSIONS)
def test_synchronous_move_round_trips_in_every_version(version: int) -> None:
    request = MoveRequest(MoveControllerMode.CARTESIAN_IMPEDANCE, JP, (1.0, 2.0, 3.0))
    message, back = round_trip(version, request)
    assert back == request and not back.is_async
    if version >= 10:  # flag off, velocities zero (libfranka's default-constructed array)
        assert message[12 + 56 :] == b"\x00" * 57


def test_async_move_needs_v10_and_seven_velocities() -> None:
    request = MoveRequest(MoveControllerMode.JOINT_IMPEDANCE, JP, maximum_velocity=VELOCITY)
    with pytest.raises(ValueError, match="protocol v10 or later, got v9"):
        request.fields(fci.dialect(9))
    with pytest.raises(ValueError, match=r"expected 7 joint velocities.*got 6"):
        MoveRequest(MoveControllerMode.JOINT_IMPEDANCE, JP, maximum_velocity=VELOCITY[:6])


def test_unknown_mode_in_a_decoded_move_is_a_value_error() -> None:
    d = fci.dialect(10)
    fields = MoveRequest(MoveControllerMode.JOINT_IMPEDANCE, JP).fields(d)
    fields["motion_generator_mode"] = 9
    with pytest.raises(ValueError, match="9"):
        MoveRequest.from_fields(fields)


def test_target_status_follows_libfranka_feedback_rule() -> None:
    q = [0.1] * 7
    still = [0.0] * 7
    near = [0.1 + 0.0003] * 7  # norm 7.9e-4 < 1e-3
    assert fci.target_status(RobotMode.MOVE, q, still, None) == TargetStatus.IDLE
    assert fci.target_status(RobotMode.MOVE, q, still, near) == TargetStatus.TARGET_REACHED
    assert fci.target_status(RobotMode.IDLE, q, still, near) == TargetStatus.TARGET_REACHED
    moving = [0.005] * 7  # norm 0.013 rad/s: not yet at rest
    assert fci.target_status(RobotMode.MOVE, q, moving, near) == TargetStatus.EXECUTING
    far = [0.1 + 0.001] * 7
    assert fci.target_status(RobotMode.MOVE, q, still, far) == TargetStatus.EXECUTING
    assert fci.target_status(RobotMode.MOVE, q, still, far, 0.01) == TargetStatus.TARGET_REACHED
    for mode in (RobotMode.REFLEX, RobotMode.USER_STOPPED):
        assert fci.target_status(mode, q, still, near) == TargetStatus.ABORTED
    assert fci.target_status(RobotMode.GUIDING, q, still, near) == TargetStatus.IDLE
