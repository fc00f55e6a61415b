"""franky-control 2.0.0's Desk (API v1, on an FR3) or DeskWebSession (legacy web API)
against the simulated Desk. After each step the test reports the simulated robot's state
(event ``status``); event ``safety_error`` makes it raise a recoverable safety error,
event ``press`` press a Pilot button.

Usage: franky_desk.py HOST[:PORT] USER PASSWORD v1|legacy
"""

from __future__ import annotations

import sys

from franky import Desk, DeskWebSession
from peer_io import Scenarios, event

HOST, USER, PASSWORD, API = sys.argv[1:5]
s = Scenarios()
session = (Desk if API == "v1" else DeskWebSession)(HOST, USER, PASSWORD)


def take() -> dict[str, object]:
    session.open()
    session.take_control(wait_timeout=5.0)
    return {"has_control": session.has_control, "robot": event("status")}


def modes() -> dict[str, object]:
    if API == "legacy":
        session.set_mode_programming()
        programming = session.operating_mode.value
    else:
        programming = None
    session.set_mode_execution()
    return {"programming": programming, "execution": session.operating_mode.value}


def unlock_and_fci() -> dict[str, object]:
    session.unlock_brakes()
    brakes = session.brake_state.value
    session.enable_fci()
    out = {"brakes": brakes, "robot": event("status")}
    if API == "v1":
        out["fci"] = session.get_fci_status()
        session.disable_fci()
        out["fci_after"] = session.get_fci_status()
    return out


def self_test() -> dict[str, object]:
    if API == "legacy":
        return {"skipped": "the legacy session cannot deactivate the FCI"}
    session.execute_self_test()
    return {"robot": event("status")}


def recovery() -> dict[str, object]:
    if API == "legacy":
        return {"skipped": "v1 only"}
    event("safety_error")
    pending = session.get_recovery_status()
    session.recover()
    return {"pending": pending, "after": session.get_recovery_status()}


def buttons() -> dict[str, object]:
    first = session.poll_buttons(timeout=5.0)  # the full key map, all released
    event("press", "check")
    later: list[object] = []
    for _ in range(20):
        later += session.poll_buttons(timeout=0.5)
        if len(later) >= 2:
            break
    return {
        "first": sorted((e.button.value, e.pressed) for e in first),
        "later": [(e.button.value, e.pressed) for e in later],  # type: ignore[attr-defined]
    }


def lock_and_release() -> dict[str, object]:
    session.lock_brakes()
    brakes = session.brake_state.value
    session.release_control()
    out = {"brakes": brakes, "has_control": session.has_control, "robot": event("status")}
    session.close()
    return out


for name, fn in [
    ("take", take), ("modes", modes), ("unlock_and_fci", unlock_and_fci),
    ("self_test", self_test), ("recovery", recovery), ("buttons", buttons),
    ("lock_and_release", lock_and_release),
]:  # fmt: skip
    s.run(name, fn)
s.finish()
