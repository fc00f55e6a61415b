"""The Desk client's logic against a mock transport: no sockets, no robot."""

from __future__ import annotations

import base64
import json
import stat
from collections.abc import Callable
from pathlib import Path

import pytest

import panda_py.desk as desk_pkg
from panda_py.desk import (
    Desk,
    DeskAPI,
    DeskHTTPError,
    MockTransport,
    NotInControlError,
    Request,
    Response,
    TakeControlTimeoutError,
    Token,
    TokenStore,
    encode_password,
)
from panda_py.desk import client as client_mod
from panda_py.desk.transport import split_host

HOST = "robot.test"


def _json(status: int, body: object) -> Response:
    return Response(status, {"content-type": "application/json"}, json.dumps(body).encode())


class FakeLegacy:
    """A scripted legacy Desk: enough state to exercise the client's decisions."""

    def __init__(self, arm: str = "fer") -> None:
        self.arm = arm
        self.active: dict[str, object] | None = None
        self.next_id = 7
        self.grant_after: int | None = None  # forced take: granted after N polls
        self.polls = 0
        self.brakes = "Locked"
        self.fci = False
        self.pending: dict[str, object] | None = None

    def __call__(self, req: Request) -> Response:
        path = req.path
        if path == "/api/system":
            return Response(404, {}, b"File not found")
        if path == "/admin/api/login":
            body = json.loads(req.body or b"{}")
            if body["password"] != encode_password("franka", "secret"):
                return Response(401, {}, b"Unauthorized")
            return Response(200, {"content-type": "text/plain"}, b"SESSION")
        if req.headers.get("Cookie") != "authorization=SESSION":
            return Response(401, {}, b"Unauthorized")
        if path == "/admin/api/control-token" and req.method == "GET":
            if self.pending is not None:
                self.polls += 1
                if self.grant_after is not None and self.polls >= self.grant_after:
                    self.active, self.pending = self.pending, None
            active = None if self.active is None else {k: self.active[k] for k in ("id", "ownedBy")}
            return _json(200, {"activeToken": active})
        if path.startswith("/admin/api/control-token/request"):
            token = {"id": self.next_id, "token": f"T{self.next_id}", "ownedBy": "franka"}
            self.next_id += 1
            if self.active is None:
                self.active = token
            else:
                self.pending = token
            return _json(200, {"id": token["id"], "token": token["token"]})
        if path == "/admin/api/safety":
            return _json(200, {"tokenForceTimeout": 0.3})
        token_ok = self.active is not None and (
            req.headers.get("X-Control-Token") == self.active["token"]
            or json.loads(req.body or b"{}").get("token") == self.active["token"]
        )
        mine = {"fer": "/desk/api/robot/", "fr3": "/desk/api/joints/"}[self.arm]
        if path.startswith("/desk/api/robot/") or path.startswith("/desk/api/joints/"):
            if not path.startswith(mine):
                return Response(404, {}, b"No handler accepted")
            if not token_ok:
                return Response(423, {}, b'{"code":"ControlTokenInvalid"}')
            self.brakes = "Unlocked" if path.endswith(("open-brakes", "unlock")) else "Locked"
            return Response(200)
        if path == "/admin/api/control-token/fci":
            if not token_ok:
                return Response(423, {}, b"")
            if req.method == "POST" and self.brakes == "Locked":
                return _json(424, {"code": "BrakesClosed"})
            self.fci = req.method == "POST"
            return Response(200)
        if path == "/admin/api/control-token" and req.method == "DELETE":
            if not token_ok:
                return _json(403, {"code": "ControlTokenUnknown"})
            self.active = None
            return Response(204)
        return Response(404, {}, b"File not found")


def make(handler: Callable[[Request], Response], tmp_path: Path, **kw: object) -> Desk:
    return Desk(
        HOST, "franka", "secret", transport=MockTransport(handler), token_dir=str(tmp_path), **kw
    )  # type: ignore[arg-type]


def test_legacy_login_take_unlock_activate(tmp_path: Path) -> None:
    robot = FakeLegacy()
    desk = make(robot, tmp_path)
    assert desk.api == DeskAPI.LEGACY
    assert desk.has_control()
    desk.unlock()
    desk.activate_fci()
    assert (robot.brakes, robot.fci) == ("Unlocked", True)
    desk.deactivate_fci()
    desk.lock()
    desk.release_control()
    assert robot.active is None and not desk.token


def test_legacy_fr3_brakes_detected_from_404(tmp_path: Path) -> None:
    robot = FakeLegacy(arm="fr3")
    transport = MockTransport(robot)
    desk = Desk(HOST, "franka", "secret", transport=transport, token_dir=str(tmp_path))
    desk.unlock()
    desk.lock()
    paths = [r.path for r in transport.requests if "/desk/api/" in r.path]
    # the FER pair is tried once, then the detected FR3 pair is used directly
    assert paths == [
        "/desk/api/robot/open-brakes",
        "/desk/api/joints/unlock",
        "/desk/api/joints/lock",
    ]


def test_token_reused_across_sessions_and_stored_privately(tmp_path: Path) -> None:
    robot = FakeLegacy()
    first = make(robot, tmp_path)
    second = make(robot, tmp_path)
    assert second.token == first.token and second.has_control()
    store = TokenStore(tmp_path)
    assert stat.S_IMODE(store.path.stat().st_mode) == 0o600
    assert stat.S_IMODE(tmp_path.stat().st_mode) == 0o700
    assert "T7" not in repr(first.token) and "secret" not in repr(first)


def test_second_user_does_not_take_control(tmp_path: Path) -> None:
    robot = FakeLegacy()
    make(robot, tmp_path / "a")
    other = make(robot, tmp_path / "b")
    assert not other.has_control() and not other.token
    with pytest.raises(NotInControlError):
        other.unlock()


def test_forced_take_waits_for_the_pilot_and_times_out(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setattr(client_mod, "POLL_PERIOD", 0.01)
    robot = FakeLegacy()
    make(robot, tmp_path / "a")
    other = make(robot, tmp_path / "b")
    robot.grant_after = 3
    assert other.take_control(force=True)
    assert other.has_control()
    robot.grant_after = None  # nobody presses the button
    third = make(robot, tmp_path / "c")
    with pytest.raises(TakeControlTimeoutError):
        third.take_control(force=True)
    assert not third.token


def test_http_errors_carry_method_path_status_and_code_and_are_not_retried(tmp_path: Path) -> None:
    robot = FakeLegacy()
    transport = MockTransport(robot)
    desk = Desk(HOST, "franka", "secret", transport=transport, token_dir=str(tmp_path))
    n = len(transport.requests)
    with pytest.raises(DeskHTTPError) as info:
        desk.activate_fci()  # brakes still closed
    err = info.value
    assert (err.method, err.path, err.status, err.code) == (
        "POST",
        "/admin/api/control-token/fci",
        424,
        "BrakesClosed",
    )
    assert isinstance(err, ConnectionError)  # panda-py's scripts catch ConnectionError
    assert len(transport.requests) == n + 1


def test_wrong_password_is_an_http_error(tmp_path: Path) -> None:
    with pytest.raises(DeskHTTPError) as info:
        Desk(
            HOST, "franka", "wrong", transport=MockTransport(FakeLegacy()), token_dir=str(tmp_path)
        )
    assert info.value.status == 401
    assert "wrong" not in str(info.value)


class FakeV1:
    def __init__(self) -> None:
        self.owner: str | None = None
        self.calls: list[tuple[str, str, str | None]] = []
        self.take_status: Response | None = None

    def __call__(self, req: Request) -> Response:
        basic = "Basic " + base64.b64encode(b"franka:secret").decode()
        if req.headers.get("Authorization") != basic:
            return _json(401, {"code": "Unauthorized"})
        self.calls.append((req.method, req.path, req.headers.get("X-Control-Token")))
        if req.path == "/api/system":
            return _json(200, {"controlToken": {"owner": self.owner}})
        if req.path == "/api/system/control-token":
            return _json(200, {"owner": self.owner, "tokenId": 1 if self.owner else None})
        if req.path == "/api/system/control-token:take":
            if self.take_status is not None:
                return self.take_status
            self.owner = json.loads(req.body or b"{}")["owner"]
            return _json(200, {"token": "V1TOKEN", "tokenId": 1})
        if req.path == "/api/system/operating-mode":
            return _json(200, {"status": "Execution"})
        if req.path == "/api/safety/recovery":
            return _json(200, {"recovery": {"type": "SafetyError", "safetyErrors": []}})
        return Response(204)


def test_v1_is_chosen_and_every_control_request_carries_the_token(tmp_path: Path) -> None:
    robot = FakeV1()
    desk = make(robot, tmp_path)
    assert desk.api == DeskAPI.V1 and desk.has_control()
    desk.unlock()
    desk.activate_fci()
    desk.set_operating_mode("Execution")
    assert desk.operating_mode() == "Execution"
    assert desk.recover()
    desk.reboot()
    control = [c for c in robot.calls if c[0] == "POST" and not c[1].endswith(":take")]
    assert [c[1] for c in control] == [
        "/api/arm/joints:unlock", "/api/fci:activate", "/api/system/operating-mode:change",
        "/api/safety/recovery:confirm", "/api/system:reboot",
    ]  # fmt: skip
    assert all(c[2] == "V1TOKEN" for c in control)


def test_v1_take_timeout(tmp_path: Path) -> None:
    robot = FakeV1()
    robot.owner = "someone"
    desk = make(robot, tmp_path)
    assert not desk.token
    robot.take_status = _json(424, {"code": "Timeout"})
    with pytest.raises(TakeControlTimeoutError):
        desk.take_control(force=True)


def test_split_host() -> None:
    assert split_host("robot") == ("robot", 443)
    assert split_host("10.0.0.2:8443") == ("10.0.0.2", 8443)
    assert split_host("[::1]:444") == ("::1", 444)
    with pytest.raises(ValueError, match="port"):
        split_host("robot:x")


def test_all_is_honest() -> None:
    for name in desk_pkg.__all__:
        assert hasattr(desk_pkg, name), name
    assert Token("1", "a", "s")


def test_a_lost_answer_to_a_control_request_is_raised_not_retried(tmp_path: Path) -> None:
    from panda_py.desk import DeskConnectionError

    robot = FakeLegacy()
    calls: list[str] = []

    def flaky(req: Request) -> Response:
        calls.append(req.path)
        if req.path == "/desk/api/robot/open-brakes":
            raise DeskConnectionError("connection reset")
        return robot(req)

    desk = make(flaky, tmp_path)
    with pytest.raises(DeskConnectionError):
        desk.unlock()
    assert calls.count("/desk/api/robot/open-brakes") == 1


def test_every_request_gets_a_timeout(tmp_path: Path) -> None:
    seen: list[float] = []

    class Timed(MockTransport):
        def request(self, request: Request, *, timeout: float) -> Response:
            seen.append(timeout)
            return super().request(request, timeout=timeout)

    Desk(
        HOST,
        "franka",
        "secret",
        transport=Timed(FakeLegacy()),
        token_dir=str(tmp_path),
        timeout=2.5,
    )
    assert seen and all(t == 2.5 for t in seen)


def test_a_desk_older_than_control_tokens_needs_none(tmp_path: Path) -> None:
    robot = FakeLegacy()

    def old(req: Request) -> Response:
        if req.path.startswith("/admin/api/control-token"):
            return Response(404, {}, b"File not found")
        if req.path == "/desk/api/robot/open-brakes":  # no token on such a Desk
            assert "X-Control-Token" not in req.headers
            robot.brakes = "Unlocked"
            return Response(200)
        return robot(req)

    desk = make(old, tmp_path)
    assert desk.take_control() and desk.has_control()
    desk.unlock()
    desk.activate_fci()  # nothing to do on such a Desk
    desk.release_control()
    assert robot.brakes == "Unlocked"
