"""The Desk's duties beyond control (shutdown, end-effector configuration, the pack
pose, self-tests, recoveries) as requests, per dialect, in one table.

Where each endpoint was learned is said beside it. Three have no public source: the
legacy end-effector configuration's path, and the pack pose in both dialects. For
those, a path in the style of its dialect was chosen; correct them here (the simulated
Desk serves the same, in ``sim/desk/duties.py``).
"""

from __future__ import annotations

import json
from typing import Any
from urllib.parse import quote

from panda_py.desk.api import CONTROL_TOKEN_HEADER
from panda_py.desk.transport import Request

# (method, path) per duty and dialect; a dialect without the duty has no entry.
ENDPOINTS: dict[str, dict[str, tuple[str, str]]] = {
    "shutdown": {
        # jk-ethz/franka_lock_unlock franka_shutdown.py (system 4.2.1), body {"token"}
        "legacy": ("POST", "/admin/api/shutdown"),
        # shared/reference/desk-api.md (franky's Desk), X-Control-Token
        "v1": ("POST", "/api/system:shutdown"),
    },
    "end_effector": {
        # No public source for the path; the body is the Desk's end-effector file
        # (frankaemika/external_gripper_example endeffector-config.json).
        "legacy": ("GET", "/desk/api/robot/end-effector"),
        # aiofranka (younghyopark/aiofranka) cli `config`: GET /api/configuration
        "v1": ("GET", "/api/configuration"),
    },
    "set_end_effector": {
        "legacy": ("POST", "/desk/api/robot/end-effector"),  # no public source (see above)
        # aiofranka cli `config`: PATCH /api/configuration with X-Control-Token
        "v1": ("PATCH", "/api/configuration"),
    },
    "pack_pose": {
        # No public source for either; Desk > Settings > System > "Move to Pack Pose"
        # (libfranka issue #64) is the function. Paths chosen in each dialect's style.
        "legacy": ("POST", "/desk/api/robot/pack-pose"),
        "v1": ("POST", "/api/arm:move-to-pack-pose"),
    },
    "self_test_status": {
        # franky's legacy session reads safety.timeToTd2 and safety.recoverableErrors
        "legacy": ("GET", "/admin/api/system-status"),
        # franky's Desk; aiofranka: {"status": OK|Warning|Elapsed|Running, "remaining": s}
        "v1": ("GET", "/api/safety/self-tests"),
    },
    "self_test": {
        "legacy": ("POST", "/admin/api/safety/td2-tests/execute"),  # franky
        "v1": ("POST", "/api/safety/self-tests:execute"),  # franky, aiofranka
    },
    "recovery_status": {
        "legacy": ("GET", "/admin/api/system-status"),  # safety.recoverableErrors (franky)
        "v1": ("GET", "/api/safety/recovery"),  # franky, aiofranka
    },
    "recover": {
        # franky acknowledges error_id=TD2Timeout here; other pending errors are taken to be
        # acknowledged the same way, by their key in safety.recoverableErrors (our reading)
        "legacy": ("POST", "/admin/api/safety/recoverable-safety-errors/acknowledge"),
        "v1": ("POST", "/api/safety/recovery:confirm"),  # franky, aiofranka: {"type", ...}
    },
}

# franky acknowledges the self-test's timeout as TD2Timeout; the status calls it td2Timeout.
TD2_STATUS_KEY = "td2Timeout"
TD2_ERROR_ID = "TD2Timeout"


def request(duty: str, api: str, *, token: str = "", body: Any = None, query: str = "") -> Request:
    """The request for ``duty`` in dialect ``api``, carrying the control token (header)
    if given, a JSON ``body`` if given, and a query string."""
    method, path = ENDPOINTS[duty][api]
    headers = {CONTROL_TOKEN_HEADER: token} if token else {}
    data = None
    if body is not None:
        headers["Content-Type"] = "application/json"
        data = json.dumps(body).encode()
    return Request(method, path + (f"?{query}" if query else ""), headers, data)


def acknowledge_query(error_id: str) -> str:
    return "error_id=" + quote(error_id, safe="")


def has(duty: str, api: str) -> bool:
    return api in ENDPOINTS[duty]


__all__ = ["ENDPOINTS", "TD2_ERROR_ID", "TD2_STATUS_KEY", "acknowledge_query", "has", "request"]
