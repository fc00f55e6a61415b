"""``Desk``: log into a robot's Desk, take control, unlock, activate the FCI.

panda-py 1.1.1's ``Desk`` API (the same methods, arguments and constructor behaviour),
speaking whichever Desk API the robot serves: Desk API v1 where it answers (FR3 from
system 5.8), else the legacy web API (FER, older FR3). Safer than the original: the
certificate is pinned on first use, tokens live in a private file, every request has a
timeout, and no request that changes the robot is ever retried behind the caller's back.
"""

from __future__ import annotations

import logging
import time
from collections.abc import Callable
from typing import Any

from panda_py import checks
from panda_py.desk import answers
from panda_py.desk.api import V1API, DeskAPI, LegacyAPI, encode_password
from panda_py.desk.duties import DeskDuties
from panda_py.desk.errors import (
    DeskError,
    DeskHTTPError,
    DeskUnsupportedError,
    NotInControlError,
    TakeControlTimeoutError,
)
from panda_py.desk.excerpt import redact, request_secrets
from panda_py.desk.pilot import PilotEvents
from panda_py.desk.shapes import array, header_token, ident, obj, seconds, text
from panda_py.desk.store import Token, TokenStore
from panda_py.desk.transport import (
    DEFAULT_TIMEOUT,
    HTTPSTransport,
    Request,
    Response,
    Transport,
)

log = logging.getLogger("panda_py.desk")

POLL_PERIOD = 0.1  # [s] between checks whether a forced take has been confirmed
V1_FORCE_TIMEOUT = 30.0  # [s] how long a v1 take is queued when forced (franky's default)

_PLATFORMS = {
    "panda": "fer", "fer": "fer", "franka_emika_robot": "fer", "frankaemikarobot": "fer",
    "fr3": "fr3", "frankaresearch3": "fr3", "franka_research_3": "fr3",
}  # fmt: skip


class Desk(DeskDuties, PilotEvents):
    """A session with a robot's Desk (``hostname`` may carry a port: ``"robot:8443"``).

    As panda-py's, the constructor logs in and tries to take control (without force);
    ``platform`` (``"panda"``/``"fer"`` or ``"fr3"``) is only a hint for the legacy brake
    endpoints, which are detected. ``api`` pins the dialect (``"legacy"`` or ``"v1"``);
    by default it is detected from what the robot serves. ``timeout`` [s] (finite, at
    most a day) bounds every request, as a deadline for the whole of it, and the Pilot
    event stream's opening and closing; ``token_dir`` holds the token and certificate
    store (0700 directory, 0600 file); ``repin`` accepts a changed robot certificate once
    and pins it. ``transport`` replaces the network (tests).
    """

    def __init__(
        self,
        hostname: str,
        username: str,
        password: str,
        platform: str | None = None,
        *,
        api: str | DeskAPI | None = None,
        timeout: float = DEFAULT_TIMEOUT,
        token_dir: str | None = None,
        repin: bool = False,
        transport: Transport | None = None,
        connect: bool = True,
    ) -> None:
        if platform is not None and platform.lower() not in _PLATFORMS:
            raise ValueError(
                f"platform: expected one of {sorted(_PLATFORMS)} or None, got {platform!r}"
            )
        timeout = checks.timeout("timeout", timeout)
        self._hostname = hostname
        self._username = username
        self._password = password
        self._platform_given = platform is not None
        self._platform = _PLATFORMS[platform.lower()] if platform else "fer"
        self._api_choice = DeskAPI(api) if api is not None else None
        self.timeout = timeout
        self._store = TokenStore(token_dir)
        self._transport: Transport = transport or HTTPSTransport(hostname, self._store, repin=repin)
        self._legacy = LegacyAPI()
        self._v1 = V1API(username, password)
        self._api: DeskAPI | None = None
        self._logged_in = False
        # Desks older than control tokens answer 404 for them: then, as panda-py does,
        # taking control, releasing it and the FCI calls do nothing.
        self._tokenless = False
        self._token = self._store.token(hostname, username)
        if connect:
            self.login()
            self.take_control()

    def __repr__(self) -> str:
        api = self._api.value if self._api else "?"
        return f"Desk({self._hostname!r}, {self._username!r}, api={api})"

    # -- plumbing ------------------------------------------------------------------------

    @property
    def api(self) -> DeskAPI | None:
        """The Desk API spoken with this robot (known after :meth:`login`)."""
        return self._api

    @property
    def token(self) -> Token:
        """This session's control token (its secret is hidden in ``repr``)."""
        return self._token

    def _auth(self) -> dict[str, str]:
        return self._v1.auth_headers() if self._api == DeskAPI.V1 else self._legacy.auth_headers()

    def _secrets(self) -> list[str]:
        """What must never show in an error, besides the credentials of the request."""
        return [
            self._password,
            encode_password(self._username, self._password),
            self._legacy.session or "",
            self._token.token,
        ]

    def _send(
        self, request: Request, *, check: bool = True, timeout: float | None = None
    ) -> Response:
        """One request, never retried (a control request may have reached the robot)."""
        request.headers = {**self._auth(), **request.headers}
        response = self._transport.request(request, timeout=timeout or self.timeout)
        response.request = request
        if check and not 200 <= response.status < 300:
            raise self._refusal(response)
        return response

    def _refusal(self, response: Response) -> DeskHTTPError:
        """The error for an answer with an error status (its text, credentials hidden)."""
        request = response.request or Request("?", "?")
        secrets = [*self._secrets(), *request_secrets(request.headers, request.body)]
        text = redact(response.text, secrets)
        return DeskHTTPError(request.method, request.path, response.status, text)

    def _parse(self, response: Response, expected: str = "JSON", read: Any = None) -> Any:
        """``read`` (by default nothing) applied to the answer's JSON; a
        :class:`~panda_py.desk.errors.DeskAnswerError` if it is not of the ``expected``
        shape."""
        return answers.parse(response, expected, read or (lambda body: body), self._secrets())

    def _read(
        self,
        request: Request,
        expected: str = "JSON",
        read: Any = None,
        *,
        timeout: float | None = None,
    ) -> Any:
        """:meth:`_send` ``request``, then :meth:`_parse` its answer."""
        return self._parse(self._send(request, timeout=timeout), expected, read)

    def _need_login(self) -> DeskAPI:
        if self._api is None or not self._logged_in:
            raise DeskError("not logged in: call login() first")
        return self._api

    def _need_token(self) -> str:
        if self._tokenless:
            return ""
        if not self._token:
            raise NotInControlError(
                f"this session holds no control token for {self._hostname}: take_control() first"
            )
        return self._token.token

    def _set_token(self, token: Token) -> None:
        self._token = token
        self._store.save_token(self._hostname, self._username, token)

    # -- session -------------------------------------------------------------------------

    def login(self) -> None:
        """Check the credentials and choose the Desk API (v1 if the robot serves it)."""
        choice = self._api_choice
        if choice in (None, DeskAPI.V1):
            self._api = DeskAPI.V1
            response = self._send(self._v1.system(), check=False)
            is_json = "json" in response.headers.get("content-type", "")
            if 200 <= response.status < 300 and is_json:
                self._logged_in = True
                log.info("logged into the Desk at %s (Desk API v1)", self._hostname)
                return
            # A legacy-only Desk answers 404 (or its page) for the v1 paths.
            legacy_only = response.status in (404, 405) or response.status < 300
            if choice == DeskAPI.V1 or not legacy_only:
                raise self._refusal(response)
        self._api = DeskAPI.LEGACY
        self._legacy.session = None
        response = self._send(self._legacy.login(self._username, self._password))
        self._legacy.session = answers.session_of(response, self._secrets())
        self._logged_in = True
        log.info("logged into the Desk at %s (legacy web API)", self._hostname)

    def logout(self) -> None:
        """End the session; later calls need :meth:`login` again."""
        if self._need_login() == DeskAPI.LEGACY:
            self._send(self._legacy.logout())
            self._legacy.session = None
        self._logged_in = False
        log.info("logged out of the Desk at %s", self._hostname)

    # -- control token -------------------------------------------------------------------

    def _active(self) -> tuple[str, str]:
        """(id, owner) of the robot's active control token; ("", "") if none."""
        if self._need_login() == DeskAPI.V1:
            return self._read(
                self._v1.active_token(), "an object with the active 'tokenId'", V1API.parse_active
            )
        return self._read(
            self._legacy.active_token(), "an object with an 'activeToken' object or null",
            LegacyAPI.parse_active,
        )  # fmt: skip

    def has_control(self) -> bool:
        """Whether this session's token is the robot's active one."""
        if self._tokenless:
            return True
        active_id, _ = self._active()
        return bool(self._token) and active_id == self._token.id

    def take_control(self, force: bool = False) -> bool:
        """Take control. Retakes it with the stored token if that is still the active one.
        If someone else holds control, returns False unless ``force``: then the robot
        grants it once somebody at the robot presses the Pilot's circle (FER) or top
        button (FR3) within the robot's force timeout; :class:`TakeControlTimeoutError`
        otherwise."""
        api = self._need_login()
        if self._tokenless:
            return True
        try:
            active_id, owner = self._active()
        except DeskHTTPError as exc:
            if api != DeskAPI.LEGACY or exc.status != 404:
                raise
            log.info("the Desk at %s predates control tokens: none needed", self._hostname)
            self._tokenless = True
            return True
        if active_id and self._token and active_id == self._token.id:
            log.info("retaken control of %s", self._hostname)
            return True
        if active_id and not force:
            log.warning("cannot take control of %s: user %s is in control", self._hostname, owner)
            return False
        if api == DeskAPI.V1:
            wait = V1_FORCE_TIMEOUT if force else self.timeout
            # The robot holds the request until it is granted: allow for that, plus margin.
            try:
                request = self._v1.take(self._username, wait)
                token = self._read(
                    request, "an object with 'tokenId' and 'token'", self._taken("tokenId"),
                    timeout=wait + self.timeout,
                )  # fmt: skip
            except DeskHTTPError as exc:
                if exc.status == 424 and exc.code == "Timeout":
                    raise TakeControlTimeoutError(
                        f"control of {self._hostname} was not granted within {wait:.0f} s: "
                        "press the Pilot's top button, or ask the holder to release it"
                    ) from exc
                raise
            self._set_token(token)
            log.info("taken control of %s", self._hostname)
            return True
        token = self._read(
            self._legacy.request_control(self._username, force),
            "an object with 'id' and 'token'", self._taken("id"),
        )  # fmt: skip
        if force:
            limit = self._read(
                self._legacy.safety(), "an object with 'tokenForceTimeout' [s]",
                lambda body: seconds(body["tokenForceTimeout"], "tokenForceTimeout"),
            )  # fmt: skip
            log.warning(
                "you have %.0f s to confirm control by pressing the circle (FER) or top (FR3) "
                "button on the robot's Pilot",
                limit,
            )
            deadline = time.monotonic() + limit
            while self._active()[0] != token.id:
                if time.monotonic() >= deadline:
                    raise TakeControlTimeoutError(
                        f"control of {self._hostname} was not confirmed on the Pilot within "
                        f"{limit:.0f} s"
                    )
                time.sleep(POLL_PERIOD)
        self._set_token(token)
        log.info("taken control of %s", self._hostname)
        return True

    def _taken(self, id_field: str) -> Callable[[Any], Token]:
        """Reads the token a granted take answers (its id in ``id_field``)."""

        def read(body: Any) -> Token:
            token = header_token(body["token"], "token")
            return Token(ident(body[id_field], id_field), self._username, token)

        return read

    def release_control(self) -> None:
        """Give control back (the next queued user, if any, gets it)."""
        api = self._need_login()
        if self._tokenless:
            return
        token = self._need_token()
        log.info("releasing control of %s", self._hostname)
        request = self._v1.release(token) if api == DeskAPI.V1 else self._legacy.release(token)
        try:
            self._send(request)
        except DeskHTTPError as exc:
            if exc.status not in (403, 423):  # the token was no longer the active one
                raise
            log.warning("control release of %s failed: not in control", self._hostname)
        self._set_token(Token())

    # -- brakes, FCI, power --------------------------------------------------------------

    def lock(self, force: bool = True) -> None:
        """Close the brakes (returns when they are closed)."""
        self._brakes("lock", force)

    def unlock(self, force: bool = True) -> None:
        """Open the brakes (returns when they are open)."""
        self._brakes("unlock", force)

    def _brakes(self, action: str, force: bool) -> None:
        token = self._need_token()
        if self._need_login() == DeskAPI.V1:
            self._send(self._v1.brakes(action, token))
            return
        other = "fr3" if self._platform == "fer" else "fer"
        for platform in (self._platform, other):
            response = self._send(self._legacy.brakes(platform, action, token, force), check=False)
            if response.status == 404:  # the other arm's endpoint: nothing happened
                continue
            if not 200 <= response.status < 300:
                raise self._refusal(response)
            if platform != self._platform:
                if self._platform_given:
                    log.warning(
                        "the robot serves the %s brake endpoints, not %s's",
                        platform,
                        self._platform,
                    )
                self._platform = platform
            return
        raise DeskError(f"the Desk at {self._hostname} serves neither arm's brake endpoints")

    def activate_fci(self) -> None:
        """Activate the FCI (the brakes must be open)."""
        self._fci(True)

    def deactivate_fci(self) -> None:
        """Deactivate the FCI: the robot closes the connected client's connection and refuses
        new ones."""
        self._fci(False)

    def _fci(self, on: bool) -> None:
        if self._tokenless:  # these Desks have no FCI switch
            return
        token = self._need_token()
        if self._need_login() == DeskAPI.V1:
            self._send(self._v1.fci(on, token))
        else:
            self._send(self._legacy.fci(on, token))

    def reboot(self) -> None:
        """Reboot the robot's control unit (drops every connection)."""
        token = self._need_token()
        if self._need_login() == DeskAPI.V1:
            self._send(self._v1.reboot(token))
        else:
            self._send(self._legacy.reboot(token))

    # -- status (v1; system status and operating mode on legacy too) ---------------------

    def system_status(self) -> dict[str, Any]:
        """The robot's status document (``GET /api/system`` or ``/admin/api/system-status``)."""
        if self._need_login() == DeskAPI.V1:
            return dict(self._read(self._v1.system(), "an object", obj))
        return dict(self._read(self._legacy.system_status(), "an object", LegacyAPI.parse_status))

    def operating_mode(self) -> str:
        """``"Execution"`` or ``"Programming"``."""
        if self._need_login() == DeskAPI.V1:
            request = self._v1.operating_mode()
            return str(self._read(request, "an object with a text 'status'", _status))
        return str(
            self._read(
                self._legacy.system_status(), "an object with a text 'derived.operatingMode'",
                lambda body: text(body["derived"]["operatingMode"], "derived.operatingMode"),
            )
        )  # fmt: skip

    def set_operating_mode(self, mode: str) -> None:
        """Switch to ``"Execution"`` (FCI and tasks) or ``"Programming"`` (guiding)."""
        if mode not in ("Execution", "Programming"):
            raise ValueError(f"mode: expected 'Execution' or 'Programming', got {mode!r}")
        token = self._need_token()
        if self._need_login() == DeskAPI.V1:
            self._send(self._v1.set_operating_mode(mode, token))
        else:
            self._send(self._legacy.set_operating_mode(mode, token))

    def _require_v1(self, what: str) -> None:
        api = self._need_login()
        if api != DeskAPI.V1:
            raise DeskUnsupportedError(
                what, api.value, "it needs Desk API v1 (an FR3 on system 5.8 or newer)"
            )

    def fci_status(self) -> str:
        """``"Active"`` or ``"Inactive"`` (v1)."""
        self._require_v1("fci_status")
        return str(self._read(self._v1.fci_status(), "an object with a text 'status'", _status))

    def brake_states(self) -> list[str]:
        """Per joint ``"Locked"`` or ``"Unlocked"`` (v1)."""
        self._require_v1("brake_states")
        return list(
            self._read(
                self._v1.joints(), "a list of joints, each with a text 'brakeStatus'",
                lambda body: [text(j["brakeStatus"], "brakeStatus") for j in array(body)],
            )
        )  # fmt: skip


def _status(body: Any) -> str:
    return text(obj(body)["status"], "status")


__all__ = ["Desk", "DeskAPI"]
