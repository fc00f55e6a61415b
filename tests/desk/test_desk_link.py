"""The shared block between the simulated Desk and the FCI loop, and the Desk's robot
logic, without processes or sockets."""

from __future__ import annotations

import numpy as np

from panda_py.sim.desk.link import PUBLISH_EVERY, DeskLink, accept_fci_connect, may_start_move
from panda_py.sim.desk.state import DeskState, encode_password


def test_switches_gate_connects_and_moves() -> None:
    assert accept_fci_connect(None) and may_start_move(None)  # no Desk: always ready
    link = DeskLink.create(locked=True)
    assert not accept_fci_connect(link) and not may_start_move(link)
    link.set_switches(brakes_open=True, fci_active=False)
    assert may_start_move(link) and not accept_fci_connect(link)
    ready = DeskLink.create(locked=False)
    assert accept_fci_connect(ready) and may_start_move(ready)


def test_published_pose_reaches_the_snapshot_at_20_hz() -> None:
    link = DeskLink.create(locked=False)
    assert link.snapshot() is None
    state = {"q": np.arange(7.0), "O_T_EE": np.eye(4).ravel(order="F")}
    link.publish(PUBLISH_EVERY + 1, state, 1)  # not a publishing tick
    assert link.snapshot() is None
    link.publish(PUBLISH_EVERY, state, 2)
    snap = link.snapshot()
    assert snap is not None
    assert snap["q"] == list(range(7)) and snap["O_T_EE"][15] == 1.0 and snap["robot_mode"] == 2


def test_refused_requests_change_nothing() -> None:
    now = [0.0]
    state = DeskState("fer", {"franka": "pw"}, DeskLink.create(locked=True), clock=lambda: now[0])
    assert state.login("franka", encode_password("franka", "bad")).status == 401
    assert not state.sessions
    assert state.login("franka", encode_password("franka", "pw")).status == 200
    assert state.fci(True).status == 424 and not state.fci_active
    first = state.request_control("a", force=False).body
    forced = state.request_control("b", force=True).body
    assert state.active_token().id == first["id"]  # type: ignore[union-attr]
    now[0] = state.token_force_timeout + 1  # nobody pressed the circle in time
    state.press("circle")
    assert state.active_token().id == first["id"] and not state.queue  # type: ignore[union-attr]
    assert state.release("wrong").status == 403
    assert state.release(first["token"]).status == 204
    assert state.release(forced["token"]).status == 403
