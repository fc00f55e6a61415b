"""The simulated Desk as an ASGI application: both web APIs, the websockets, the page.

Every request is bounded: bodies over ``BODY_LIMIT`` answer 413 unread, a body that does
not arrive within ``BODY_TIMEOUT`` answers 408, malformed JSON 400, unknown paths 404
(each arm's own wording), missing or wrong credentials 401. A refused request changes
nothing. The FER serves the legacy API only (and its own brake endpoints); the FR3 serves
the legacy API with its brake endpoints and Desk API v1.
"""

from __future__ import annotations

import asyncio
import base64
import inspect
import json
import logging
from collections.abc import Awaitable, Callable
from dataclasses import dataclass
from importlib import resources
from typing import Any
from urllib.parse import parse_qs, unquote

from panda_py.sim.desk.duties import duty_routes
from panda_py.sim.desk.reply import Reply, error
from panda_py.sim.desk.state import PILOT_BUTTONS, DeskState

log = logging.getLogger("panda_py.sim.desk")

BODY_LIMIT = 64 * 1024  # [bytes] larger request bodies answer 413
BODY_TIMEOUT = 5.0  # [s] a body slower than this answers 408
CONFIGURATION_PERIOD = 0.1  # [s] /desk/api/robot/configuration pushes at 10 Hz
V1_TAKE_POLL = 0.02  # [s] a queued v1 take checks whether it was granted this often
V1_TAKE_MAX = 300.0  # [s] longest wait a v1 take may ask for

Scope = dict[str, Any]
Receive = Callable[[], Awaitable[dict[str, Any]]]
Send = Callable[[dict[str, Any]], Awaitable[None]]

PAGE_FILES = {"/": "index.html", "/desk.js": "desk.js", "/desk.css": "desk.css"}
CONTENT_TYPES = {".html": "text/html; charset=utf-8", ".js": "text/javascript", ".css": "text/css"}


class _BadRequest(Exception):
    def __init__(self, reply: Reply) -> None:
        self.reply = reply


@dataclass
class HttpRequest:
    method: str
    path: str
    query: dict[str, list[str]]
    headers: dict[str, str]
    body: bytes
    user: str | None = None
    session: str | None = None

    def json(self) -> Any:
        if not self.body:
            return {}
        ctype = self.headers.get("content-type", "")
        if "x-www-form-urlencoded" in ctype:
            return {k: v[-1] for k, v in parse_qs(self.body.decode("latin-1")).items()}
        if "multipart/form-data" in ctype:
            return {}  # the FER's brake calls send a 'force' form field; nothing to read
        try:
            return json.loads(self.body)
        except ValueError as exc:
            raise _BadRequest(error(400, "BadRequest", "malformed JSON body")) from exc

    def control_token(self) -> str | None:
        token = self.headers.get("x-control-token")
        if token:
            return token
        body = self.json()
        value = body.get("token") if isinstance(body, dict) else None
        if not isinstance(value, str):
            return None
        if "x-www-form-urlencoded" in self.headers.get("content-type", ""):
            try:  # franky's legacy session sends the token base64-encoded in a form
                return base64.b64decode(value, validate=True).decode()
            except ValueError:
                return value
        return value


def _headers(scope: Scope) -> dict[str, str]:
    return {k.decode("latin-1").lower(): v.decode("latin-1") for k, v in scope["headers"]}


def _cookie(headers: dict[str, str], name: str) -> str | None:
    for part in headers.get("cookie", "").split(";"):
        key, _, value = part.strip().partition("=")
        if key == name:
            return value
    return None


class DeskApp:
    """ASGI app over one :class:`DeskState` (all state touched on the event loop only)."""

    def __init__(self, state: DeskState, *, page: bool = True) -> None:
        self.state = state
        self.page = page
        legacy: dict[tuple[str, str], Callable[[HttpRequest], Any]] = {
            ("POST", "/admin/api/logout"): lambda r: self.state.logout(r.session),
            ("GET", "/admin/api/control-token"): self._legacy_active,
            ("POST", "/admin/api/control-token/request"): self._legacy_request,
            ("DELETE", "/admin/api/control-token"): lambda r: self.state.release(r.control_token()),
            ("GET", "/admin/api/safety"): lambda r: Reply(
                200, {"tokenForceTimeout": self.state.token_force_timeout}
            ),
            ("POST", "/admin/api/control-token/fci"): self._control(lambda r: self.state.fci(True)),
            ("DELETE", "/admin/api/control-token/fci"): self._control(
                lambda r: self.state.fci(False)
            ),
            ("POST", "/desk/api/system/fci"): self._control(lambda r: self.state.fci(True)),
            ("GET", "/admin/api/system-status"): lambda r: Reply(200, self.state.legacy_status()),
            ("POST", "/desk/api/operating-mode/programming"): self._control(
                lambda r: self.state.set_mode("Programming")
            ),
            ("POST", "/desk/api/operating-mode/execution"): self._control(
                lambda r: self.state.set_mode("Execution")
            ),
            ("POST", "/admin/api/safety/recoverable-safety-errors/acknowledge"): self._control(
                self._legacy_acknowledge
            ),
            ("POST", "/admin/api/reboot"): self._control(self._reboot),
        }
        if state.robot == "fer":
            lock, unlock = "/desk/api/robot/close-brakes", "/desk/api/robot/open-brakes"
        else:
            lock, unlock = "/desk/api/joints/lock", "/desk/api/joints/unlock"
        legacy[("POST", unlock)] = self._control(lambda r: self.state.brakes(True))
        legacy[("POST", lock)] = self._lock_legacy
        self.routes = legacy
        if state.robot == "fr3":
            self.routes.update(
                {
                    ("GET", "/api/system"): lambda r: Reply(200, self.state.v1_system()),
                    ("GET", "/api/system/control-token"): self._v1_active,
                    ("POST", "/api/system/control-token:release"): lambda r: self.state.release(
                        r.control_token()
                    ),
                    ("GET", "/api/system/operating-mode"): lambda r: Reply(
                        200, {"status": self.state.operating_mode}
                    ),
                    ("POST", "/api/system/operating-mode:change"): self._control(
                        lambda r: self.state.set_mode(r.json().get("desiredOperatingMode"))
                    ),
                    ("GET", "/api/arm"): lambda r: Reply(
                        200,
                        {
                            "brakeStatus": self.state.brake_states()[0],
                            "arm": self.state.link.snapshot(),
                        },
                    ),
                    ("GET", "/api/arm/joints"): lambda r: Reply(
                        200, [{"brakeStatus": s} for s in self.state.brake_states()]
                    ),
                    ("POST", "/api/arm/joints:unlock"): self._control(
                        lambda r: self.state.brakes(True)
                    ),
                    ("POST", "/api/arm/joints:lock"): self._control(
                        lambda r: self.state.brakes(False)
                    ),
                    ("GET", "/api/fci"): lambda r: Reply(
                        200, {"status": "Active" if self.state.fci_active else "Inactive"}
                    ),
                    ("POST", "/api/fci:activate"): self._control(lambda r: self.state.fci(True)),
                    ("POST", "/api/fci:deactivate"): self._control(lambda r: self.state.fci(False)),
                    ("GET", "/api/safety/recovery"): lambda r: Reply(
                        200, {"recovery": self.state.recovery}
                    ),
                    # franky sends these two without a control token; a given one must be valid.
                    ("POST", "/api/safety/recovery:confirm"): self._optional_control(
                        lambda r: self.state.confirm_recovery(r.json())
                    ),
                    ("POST", "/api/system:reboot"): self._optional_control(self._reboot),
                }
            )
        self.routes.update(duty_routes(state, self._control, self._optional_control))
        self.paths = {path for _, path in self.routes}

    # -- handlers --------------------------------------------------------------------------

    def _control(self, fn: Callable[[HttpRequest], Any]) -> Callable[[HttpRequest], Any]:
        def handler(r: HttpRequest) -> Any:
            if not self.state.token_valid(r.control_token()):
                return error(423, "ControlTokenInvalid", "missing or invalid control token")
            return fn(r)

        return handler

    def _optional_control(self, fn: Callable[[HttpRequest], Any]) -> Callable[[HttpRequest], Any]:
        def handler(r: HttpRequest) -> Any:
            token = r.control_token()
            if token is not None and not self.state.token_valid(token):
                return error(423, "ControlTokenInvalid", "invalid control token")
            return fn(r)

        return handler

    def _lock_legacy(self, r: HttpRequest) -> Reply:
        # panda-py closes the brakes without a token (the safe direction); a token given
        # must be valid.
        token = r.control_token()
        if token is not None and not self.state.token_valid(token):
            return error(423, "ControlTokenInvalid", "invalid control token")
        return self.state.brakes(False)

    def _reboot(self, r: HttpRequest) -> Reply:
        self.state.reboot()
        return Reply(200)

    def _legacy_active(self, r: HttpRequest) -> Reply:
        active = self.state.active_token()
        body = None if active is None else {"id": active.id, "ownedBy": active.owner}
        return Reply(200, {"activeToken": body})

    def _v1_active(self, r: HttpRequest) -> Reply:
        active = self.state.active_token()
        if active is None:
            return Reply(200, {"owner": None, "tokenId": None})
        return Reply(200, {"owner": active.owner, "tokenId": active.id})

    def _legacy_request(self, r: HttpRequest) -> Reply:
        body = r.json()
        owner = body.get("requestedBy") if isinstance(body, dict) else None
        if not isinstance(owner, str) or not owner:
            return error(400, "InvalidArgument", "expected {'requestedBy': name}")
        return self.state.request_control(owner, force="force" in r.query)

    def _legacy_acknowledge(self, r: HttpRequest) -> Reply:
        """``?error_id=TD2Timeout`` (self-test due) or the pending safety error's type."""
        error_id = r.query.get("error_id", [""])[-1]
        if error_id == "TD2Timeout":
            self.state.acknowledge_td2()
            return Reply(200, {"code": "SuccessResponse"})
        reply = self.state.confirm_recovery({"type": error_id})
        return Reply(200, {"code": "SuccessResponse"}) if reply.status == 200 else reply

    async def _v1_take(self, r: HttpRequest) -> Reply:
        body = r.json()
        owner = body.get("owner") if isinstance(body, dict) else None
        timeout = body.get("timeout", 30) if isinstance(body, dict) else None
        if (
            not isinstance(owner, str)
            or not owner
            or not isinstance(timeout, int | float)
            or not 0 <= timeout <= V1_TAKE_MAX
        ):
            return error(400, "InvalidArgument", "expected {'owner': name, 'timeout': s}")
        reply, queued = self.state.take_v1(owner, float(timeout))
        if queued is None:
            assert reply is not None
            return reply
        loop = asyncio.get_running_loop()
        deadline = loop.time() + float(timeout)
        while loop.time() < deadline:
            granted = self.state.granted(queued)
            if granted is not None:
                return granted
            await asyncio.sleep(V1_TAKE_POLL)
        return self.state.granted(queued) or self.state.take_timed_out(queued)

    # -- plumbing ----------------------------------------------------------------------------

    def _authenticate(self, headers: dict[str, str]) -> tuple[str | None, str | None]:
        """(user, legacy session) from Basic auth, the ``authorization`` cookie or header."""
        auth = headers.get("authorization", "")
        if auth.lower().startswith("basic "):
            try:
                user, _, password = (
                    base64.b64decode(auth[6:], validate=True).decode().partition(":")
                )
            except (ValueError, UnicodeDecodeError):
                return None, None
            return self.state.check_basic(user, password), None
        session = _cookie(headers, "authorization") or auth or None
        if session is not None and session in self.state.sessions:
            return self.state.sessions[session], session
        return None, None

    async def __call__(self, scope: Scope, receive: Receive, send: Send) -> None:
        if scope["type"] == "http":
            await self._http(scope, receive, send)
        elif scope["type"] == "websocket":
            await self._websocket(scope, receive, send)

    async def _read_body(self, headers: dict[str, str], receive: Receive) -> bytes | Reply:
        length = headers.get("content-length")
        if length is not None and (not length.isdigit() or int(length) > BODY_LIMIT):
            return error(
                413, "PayloadTooLarge", f"request bodies are limited to {BODY_LIMIT} bytes"
            )
        chunks, size = [], 0
        while True:
            try:
                message = await asyncio.wait_for(receive(), BODY_TIMEOUT)
            except asyncio.TimeoutError:
                return error(408, "RequestTimeout", "the request body was too slow")
            if message["type"] == "http.disconnect":
                return Reply(499)
            chunk = message.get("body", b"")
            size += len(chunk)
            if size > BODY_LIMIT:
                return error(
                    413, "PayloadTooLarge", f"request bodies are limited to {BODY_LIMIT} bytes"
                )
            chunks.append(chunk)
            if not message.get("more_body", False):
                return b"".join(chunks)

    async def _http(self, scope: Scope, receive: Receive, send: Send) -> None:
        headers = _headers(scope)
        method, path = scope["method"], scope["path"]
        body = await self._read_body(headers, receive)
        if isinstance(body, Reply):
            if body.status != 499:
                await self._respond(send, body, close=True)
            return
        try:
            reply = await self._route(method, path, scope, headers, body)
        except _BadRequest as exc:
            reply = exc.reply
        except Exception:  # the server keeps serving; the robot state was not changed
            log.exception("error serving %s %s", method, path)
            reply = error(500, "InternalError")
        if reply.status >= 400:
            log.info("%s %s -> %d", method, path, reply.status)
        await self._respond(send, reply)

    async def _route(
        self, method: str, path: str, scope: Scope, headers: dict[str, str], body: bytes
    ) -> Reply:
        if self.state.powered_off:  # shut down: nothing answers until a power cycle
            return error(503, "SystemOff", "the robot is shut down")
        if self.page and method == "GET" and path in PAGE_FILES:
            return Reply(200, ("page", PAGE_FILES[path]))
        query = parse_qs(scope.get("query_string", b"").decode("latin-1"), keep_blank_values=True)
        request = HttpRequest(method, path, query, headers, body)
        if (method, path) == ("POST", "/admin/api/login"):
            data = request.json()
            if not isinstance(data, dict):
                return error(400, "BadRequest", "expected {'login', 'password'}")
            return self.state.login(data.get("login"), data.get("password"))
        is_take = self.state.robot == "fr3" and path == "/api/system/control-token:take"
        is_pilot = path.startswith("/desk/api/sim/pilot/")
        if path not in self.paths and not is_take and not is_pilot:
            return self._not_found(path)
        request.user, request.session = self._authenticate(headers)
        if request.user is None:
            return error(401, "Unauthorized", "log in first")
        if is_take:
            if method != "POST":
                return error(405, "MethodNotAllowed")
            return await self._v1_take(request)
        if is_pilot:
            # The page's Pilot: a simulated person at the robot presses a button.
            button = unquote(path.rsplit("/", 1)[1])
            if method != "POST" or button not in (*PILOT_BUTTONS, "top"):
                return self._not_found(path)
            self.state.press(button)
            return Reply(200)
        handler = self.routes.get((method, path))
        if handler is None:
            return error(405, "MethodNotAllowed")
        reply = handler(request)
        if inspect.isawaitable(reply):  # a duty that waits for the arm (the pack pose)
            reply = await reply
        return reply

    def _not_found(self, path: str) -> Reply:
        if self.state.robot == "fer":
            return Reply(404, "File not found")
        return Reply(404, f'No handler accepted "{path}"')

    async def _respond(self, send: Send, reply: Reply, *, close: bool = False) -> None:
        body: bytes
        if isinstance(reply.body, tuple):
            name = reply.body[1]
            body = resources.files("panda_py.sim.desk").joinpath("page").joinpath(name).read_bytes()
            ctype = CONTENT_TYPES["." + name.rsplit(".", 1)[1]]
        elif reply.body is None:
            body, ctype = b"", "text/plain"
        elif isinstance(reply.body, str):
            body, ctype = reply.body.encode(), "text/plain; charset=utf-8"
        else:
            body, ctype = json.dumps(reply.body).encode(), "application/json"
        headers = [(b"content-type", ctype.encode()), (b"cache-control", b"no-store")]
        if close:
            headers.append((b"connection", b"close"))
        if reply.status == 204:
            body = b""
        else:
            headers.append((b"content-length", str(len(body)).encode()))
        await send({"type": "http.response.start", "status": reply.status, "headers": headers})
        await send({"type": "http.response.body", "body": body})

    # -- websockets ----------------------------------------------------------------------------

    async def _websocket(self, scope: Scope, receive: Receive, send: Send) -> None:
        path = scope["path"]
        user, _ = self._authenticate(_headers(scope))
        message = await receive()  # websocket.connect
        if message["type"] != "websocket.connect":
            return
        if (
            user is None
            or self.state.powered_off
            or path
            not in (
                "/desk/api/navigation/events",
                "/desk/api/robot/configuration",
            )
        ):
            await send({"type": "websocket.close", "code": 1008})
            return
        await send({"type": "websocket.accept"})
        queue: asyncio.Queue[dict[str, Any]] = asyncio.Queue(maxsize=256)
        listener = None
        if path == "/desk/api/navigation/events":
            await queue.put({b: False for b in PILOT_BUTTONS})

            def listener(event: dict[str, bool]) -> None:
                if not queue.full():  # a client that stopped reading loses events
                    queue.put_nowait(event)

            self.state.listeners.append(listener)
        receiver = asyncio.ensure_future(self._until_closed(receive))
        try:
            while not receiver.done():
                if listener is not None:
                    getter = asyncio.ensure_future(queue.get())
                    done, _ = await asyncio.wait(
                        {getter, receiver}, return_when=asyncio.FIRST_COMPLETED
                    )
                    if getter not in done:
                        getter.cancel()
                        break
                    payload = getter.result()
                else:
                    payload = self._configuration()
                    try:
                        await asyncio.wait_for(asyncio.shield(receiver), CONFIGURATION_PERIOD)
                        break
                    except asyncio.TimeoutError:
                        pass
                await send({"type": "websocket.send", "text": json.dumps(payload)})
        except OSError:
            pass
        finally:
            receiver.cancel()
            if listener is not None and listener in self.state.listeners:
                self.state.listeners.remove(listener)

    @staticmethod
    async def _until_closed(receive: Receive) -> None:
        while (await receive())["type"] != "websocket.disconnect":
            pass

    def _configuration(self) -> dict[str, Any]:
        arm = self.state.link.snapshot() or {}
        status = self.state.legacy_status()
        return {
            "jointAngles": arm.get("q"),
            "cartesianPose": arm.get("O_T_EE"),
            "robotMode": arm.get("robot_mode"),
            "time": arm.get("time"),
            "brakes": status["safety"]["brakeState"][0],
            "fci": self.state.fci_active,
            "operatingMode": self.state.operating_mode,
            "controlToken": status["controlToken"]["activeToken"],
            "recovery": self.state.recovery,
        }
