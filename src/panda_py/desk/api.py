"""The two Desk dialects as request builders: the legacy web API (FER and older FR3, a
login cookie) and Desk API v1 (FR3 from system 5.8, HTTP Basic on every request).

Each method is one request; the :class:`~panda_py.desk.client.Desk` decides which to send.
Paths and payloads: ``shared/reference/desk-api.md``.
"""

from __future__ import annotations

import base64
import enum
import hashlib
import json
from typing import Any

from panda_py.desk.shapes import array, ident, number, obj
from panda_py.desk.transport import Request

CONTROL_TOKEN_HEADER = "X-Control-Token"


class DeskAPI(enum.Enum):
    """Which web API a robot's Desk speaks: the legacy one (FER, older FR3) or Desk API v1
    (FR3, system 5.8 and later)."""

    LEGACY = "legacy"
    V1 = "v1"


PILOT_EVENTS_PATH = "/desk/api/navigation/events"

# The legacy brake endpoints differ by arm; each robot answers 404 for the other's pair.
BRAKE_PATHS = {
    "fer": {"lock": "/desk/api/robot/close-brakes", "unlock": "/desk/api/robot/open-brakes"},
    "fr3": {"lock": "/desk/api/joints/lock", "unlock": "/desk/api/joints/unlock"},
}


def encode_password(username: str, password: str) -> str:
    """The legacy login's password field: base64 of the comma-joined decimal bytes of
    SHA-256(``password#username@franka``), as the Desk's own page computes it."""
    digest = hashlib.sha256(f"{password}#{username}@franka".encode()).digest()
    return base64.encodebytes(",".join(str(b) for b in digest).encode()).decode()


def _json(method: str, path: str, body: Any, headers: dict[str, str] | None = None) -> Request:
    h = {"Content-Type": "application/json", **(headers or {})}
    return Request(method, path, h, json.dumps(body).encode())


def _multipart_force(force: bool, headers: dict[str, str]) -> Request:
    boundary = "pandapydeskboundary"
    body = (
        f'--{boundary}\r\nContent-Disposition: form-data; name="force"; filename="force"'
        f"\r\n\r\n{force}\r\n--{boundary}--\r\n"
    ).encode()
    h = {"Content-Type": f"multipart/form-data; boundary={boundary}", **headers}
    return Request("POST", "", h, body)


class LegacyAPI:
    """The undocumented web API: login answers a session token sent back as the
    ``authorization`` cookie."""

    name = "legacy"

    def __init__(self) -> None:
        self.session: str | None = None

    def auth_headers(self) -> dict[str, str]:
        return {"Cookie": f"authorization={self.session}"} if self.session else {}

    def ws_headers(self) -> dict[str, str]:
        return {"authorization": self.session or ""}

    def login(self, username: str, password: str) -> Request:
        body = {"login": username, "password": encode_password(username, password)}
        return _json("POST", "/admin/api/login", body)

    def logout(self) -> Request:
        return Request("POST", "/admin/api/logout")

    def active_token(self) -> Request:
        return Request("GET", "/admin/api/control-token")

    @staticmethod
    def parse_active(body: Any) -> tuple[str, str]:
        """(id, owner) of ``GET /admin/api/control-token``'s ``activeToken`` (("", "")
        when it is null); ``TypeError`` or ``KeyError`` for another shape."""
        active = obj(body).get("activeToken") if body is not None else None
        if not active:  # null (or empty): nobody holds control
            return "", ""
        active = obj(active, "activeToken")
        owner = active.get("ownedBy")
        return ident(active["id"], "activeToken.id"), "" if owner is None else str(owner)

    @staticmethod
    def parse_status(body: Any) -> dict[str, Any]:
        """``GET /admin/api/system-status``'s document, the parts the client reads checked:
        ``TypeError`` or ``ValueError`` naming the first that has another shape."""
        status = obj(body)
        safety = status.get("safety")
        if safety is not None:
            obj(safety, "safety")
            for name, check in (("recoverableErrors", obj), ("brakeState", array)):
                if safety.get(name) is not None:
                    check(safety[name], f"safety.{name}")
            if safety.get("timeToTd2") is not None:
                number(safety["timeToTd2"], "safety.timeToTd2")
        if status.get("derived") is not None:
            obj(status["derived"], "derived")
        return status

    def request_control(self, username: str, force: bool) -> Request:
        path = "/admin/api/control-token/request" + ("?force" if force else "")
        return _json("POST", path, {"requestedBy": username})

    def safety(self) -> Request:
        return Request("GET", "/admin/api/safety")

    def release(self, token: str) -> Request:
        return _json("DELETE", "/admin/api/control-token", {"token": token})

    def brakes(self, platform: str, action: str, token: str, force: bool) -> Request:
        req = _multipart_force(force, {CONTROL_TOKEN_HEADER: token} if token else {})
        req.path = BRAKE_PATHS[platform][action]
        return req

    def fci(self, on: bool, token: str) -> Request:
        return _json("POST" if on else "DELETE", "/admin/api/control-token/fci", {"token": token})

    def reboot(self, token: str) -> Request:
        return Request("POST", "/admin/api/reboot", {CONTROL_TOKEN_HEADER: token})

    def system_status(self) -> Request:
        return Request("GET", "/admin/api/system-status")

    def set_operating_mode(self, mode: str, token: str) -> Request:
        return Request(
            "POST", f"/desk/api/operating-mode/{mode.lower()}", {CONTROL_TOKEN_HEADER: token}
        )


class V1API:
    """Desk API v1: HTTP Basic authentication on every request, control operations carry
    ``X-Control-Token``."""

    name = "v1"

    def __init__(self, username: str, password: str) -> None:
        self._basic = base64.b64encode(f"{username}:{password}".encode()).decode()

    def auth_headers(self) -> dict[str, str]:
        return {"Authorization": f"Basic {self._basic}"}

    ws_headers = auth_headers

    @staticmethod
    def _control(method: str, path: str, token: str, body: Any = None) -> Request:
        headers = {CONTROL_TOKEN_HEADER: token} if token else {}
        if body is None:
            return Request(method, path, headers)
        return _json(method, path, body, headers)

    def system(self) -> Request:
        return Request("GET", "/api/system")

    def active_token(self) -> Request:
        return Request("GET", "/api/system/control-token")

    @staticmethod
    def parse_active(body: Any) -> tuple[str, str]:
        """(id, owner) of ``GET /api/system/control-token`` (("", "") when nobody holds
        it); ``TypeError`` for another shape."""
        if body is None or obj(body).get("tokenId") is None:
            return "", ""
        return ident(body["tokenId"], "tokenId"), str(body.get("owner") or "")

    def take(self, username: str, timeout: float) -> Request:
        return _json(
            "POST", "/api/system/control-token:take", {"owner": username, "timeout": int(timeout)}
        )

    def release(self, token: str) -> Request:
        return self._control("POST", "/api/system/control-token:release", token)

    def brakes(self, action: str, token: str) -> Request:
        return self._control("POST", f"/api/arm/joints:{action}", token)

    def joints(self) -> Request:
        return Request("GET", "/api/arm/joints")

    def fci_status(self) -> Request:
        return Request("GET", "/api/fci")

    def fci(self, on: bool, token: str) -> Request:
        return self._control("POST", "/api/fci:" + ("activate" if on else "deactivate"), token)

    def reboot(self, token: str) -> Request:
        return self._control("POST", "/api/system:reboot", token)

    def operating_mode(self) -> Request:
        return Request("GET", "/api/system/operating-mode")

    def set_operating_mode(self, mode: str, token: str) -> Request:
        body = {"desiredOperatingMode": mode}
        return self._control("POST", "/api/system/operating-mode:change", token, body)
