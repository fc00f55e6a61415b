"""VacuumGripper against a scripted Cobot Pump (the simulator has none)."""

from __future__ import annotations

import datetime
import socket
import threading

import numpy as np
import pytest

from panda_py import fci
from panda_py import libfranka as lf
from panda_py.fci import vacuum as vp
from panda_py.sim import free_loopback_host

pytestmark = pytest.mark.timeout(30)


ANSWERS = {
    vp.VacuumCommand.VACUUM: vp.VacuumStatus.SUCCESS,
    vp.VacuumCommand.DROP_OFF: vp.VacuumStatus.UNSUCCESSFUL,
    vp.VacuumCommand.STOP: vp.VacuumStatus.FAIL,
}


class _FakePump:
    """Connect, a state datagram every 10 ms, and answers to Vacuum/DropOff/Stop with
    fixed statuses."""

    def __init__(self) -> None:
        self.host = free_loopback_host()
        self.listener = socket.create_server((self.host, vp.VACUUM_COMMAND_PORT))
        self.requests: list[tuple[vp.VacuumCommand, dict]] = []
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _stream(self, udp: socket.socket, to: tuple[str, int]) -> None:
        state = np.zeros((), vp.VACUUM_STATE_DTYPE)
        state["message_id"], state["part_present"] = 7, True
        state["device_status"], state["vacuum"] = 1, 750
        while not self.done.wait(0.01):
            try:
                udp.sendto(vp.encode_vacuum_state(state), to)
            except OSError:
                return

    def _serve(self) -> None:
        conn, addr = self.listener.accept()
        reader = fci.GripperMessageReader()
        udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        udp.bind((self.host, 0))  # states come from the device's address, as on a robot
        with conn, udp:
            while True:
                data = conn.recv(4096)
                if not data:
                    return
                for msg in reader.feed(data):
                    if msg.command == 0:
                        cid, version, port = fci.decode_gripper_connect_request(msg.raw)
                        assert version == vp.VACUUM_VERSION
                        conn.sendall(fci.encode_gripper_connect_response(
                            cid, fci.GripperConnectStatus.SUCCESS, version=1))  # fmt: skip
                        threading.Thread(
                            target=self._stream, args=(udp, (addr[0], port)), daemon=True
                        ).start()
                        continue
                    command = vp.VacuumCommand(msg.command)
                    self.requests.append((command, vp.VACUUM_REQUESTS[command].decode(msg.payload)))
                    payload = vp.VACUUM_RESPONSE.encode(status=int(ANSWERS[command]))
                    conn.sendall(vp.encode_vacuum_message(command, msg.command_id, payload))

    def close(self) -> None:
        self.done.set()
        self.listener.close()


@pytest.fixture
def pump():
    p = _FakePump()
    yield p
    p.close()


def test_vacuum_gripper_commands_state_and_statuses(pump):
    with lf.VacuumGripper(pump.host) as g:
        assert g.server_version() == 1
        state = g.read_once()
        assert state.part_present and state.vacuum == 750 and state.time.to_msec() == 7
        assert state.device_status == lf.VacuumGripperDeviceStatus.kYellow
        assert g.vacuum(100, datetime.timedelta(seconds=1.5),
                        lf.VacuumGripperProductionSetupProfile.kP2) is True  # fmt: skip
        assert g.drop_off(lf.Duration(200)) is False
        with pytest.raises(lf.CommandException, match="Stop command failed"):
            g.stop()
        with pytest.raises(ValueError, match="vacuum"):
            g.vacuum(300, 100)
    assert pump.requests[0] == (
        vp.VacuumCommand.VACUUM,
        {"vacuum": 100, "profile": 2, "timeout": 1500},
    )
    assert pump.requests[1] == (vp.VacuumCommand.DROP_OFF, {"timeout": 200})
    assert len(pump.requests) == 3  # the bad setpoint was never sent


class _StreamingPump:
    """Connect, then a state every 10 ms, numbered 1, 2, ... (``sent``: how many went out,
    counted after each send)."""

    def __init__(self) -> None:
        self.host = free_loopback_host()
        self.listener = socket.create_server((self.host, vp.VACUUM_COMMAND_PORT))
        self.sent = 0
        self.three_sent = threading.Event()
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    def _serve(self) -> None:
        conn, addr = self.listener.accept()
        udp = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        udp.bind((self.host, 0))
        with conn, udp:
            msg = fci.GripperMessageReader().feed(conn.recv(64))[0]
            cid, _, port = fci.decode_gripper_connect_request(msg.raw)
            conn.sendall(fci.encode_gripper_connect_response(
                cid, fci.GripperConnectStatus.SUCCESS, version=1))  # fmt: skip
            state = np.zeros((), vp.VACUUM_STATE_DTYPE)
            while not self.done.wait(0.01):
                state["message_id"] = self.sent + 1
                udp.sendto(vp.encode_vacuum_state(state), (addr[0], port))
                self.sent += 1
                if self.sent == 3:
                    self.three_sent.set()

    def close(self) -> None:
        self.done.set()
        self.listener.close()


def test_read_once_waits_for_a_state_sent_after_the_call():
    """libfranka's readOnce "waits for a vacuum gripper state update": the states queued
    before the call are not it."""
    pump = _StreamingPump()
    try:
        with lf.VacuumGripper(pump.host) as g:
            assert pump.three_sent.wait(5)
            before = pump.sent  # these are queued (loopback delivers as it sends)
            state = g.read_once()
            assert state.time.to_msec() > before
            assert g.readOnce().time.to_msec() > state.time.to_msec()
    finally:
        pump.close()


@pytest.mark.parametrize("cls", [lf.Gripper, lf.VacuumGripper])
@pytest.mark.parametrize("timeout", [0, -1.0, "5", True, float("inf"), 1e300, float("nan")])
def test_hand_clients_reject_a_bad_timeout_before_connecting(cls, timeout):
    with pytest.raises(ValueError, match=r"timeout: expected a (number|finite number in .*) \[s\]"):
        cls("127.0.0.1", timeout=timeout)  # nothing listens there: no connect attempted
