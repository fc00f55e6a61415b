"""panda-python 1.1.1's Desk against the simulated Desk: login (constructor), take control,
unlock, activate FCI, deactivate, lock, release. After each step the test reports the
simulated robot's state (event ``status``).

Usage: pp_desk.py HOST[:PORT] USER PASSWORD
"""

from __future__ import annotations

import sys

from peer_io import Scenarios, event

import panda_py

HOST, USER, PASSWORD = sys.argv[1:4]
s = Scenarios()
state: dict[str, object] = {}


def construct() -> dict[str, object]:
    state["desk"] = panda_py.Desk(HOST, USER, PASSWORD)
    return {"has_control": state["desk"].has_control(), "robot": event("status")}


def step(name: str):
    def run() -> dict[str, object]:
        getattr(state["desk"], name)()
        return {"robot": event("status")}

    return run


s.run("construct", construct)
for name in ("unlock", "activate_fci", "deactivate_fci", "lock"):
    s.run(name, step(name))
s.run("release_control", step("release_control"))
s.run("has_control_after", lambda: {"has_control": state["desk"].has_control()})
s.finish()
