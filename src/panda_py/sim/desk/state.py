"""The simulated Desk's robot: users, sessions, the control token, brakes, FCI, operating
mode, recoverable safety errors and the Pilot buttons (the self-test, end-effector
configuration, pack pose and shutdown are in ``duties.py``). No I/O: the web app
calls these methods, each answering an HTTP status and a body, and nothing changes when
the answer is an error.

Status codes as the real Desk (shared/reference/desk-api.md): 401 bad login, 403 no
permission, 423 bad or missing control token, 424 blocked by the system state.
"""

from __future__ import annotations

import base64
import hashlib
import math
import secrets
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from panda_py.robots.end_effectors import EndEffector
from panda_py.sim.desk.duties import DeskDuties, initial_end_effector
from panda_py.sim.desk.link import DeskLink
from panda_py.sim.desk.reply import Reply, error

PILOT_BUTTONS = ("circle", "cross", "check", "left", "right", "down", "up")
SELF_TEST_DURATION = 1.0  # [s] the simulated safety self-test takes this long


def encode_password(username: str, password: str) -> str:
    """What the Desk's login page sends for a password (legacy API)."""
    digest = hashlib.sha256(f"{password}#{username}@franka".encode()).digest()
    return base64.encodebytes(",".join(str(b) for b in digest).encode()).decode()


@dataclass
class ControlToken:
    id: int
    token: str
    owner: str
    deadline: float = float("inf")  # [s, clock] a queued request expires then
    needs_button: bool = False  # forced: granted only on a Pilot press


@dataclass
class DeskState(DeskDuties):
    """One robot's Desk. ``robot``: ``"fer"`` (legacy API only) or ``"fr3"`` (both).

    Test switches (fields a test may set): ``fail_next_self_test``, ``brakes_jammed`` (the
    brakes do not open, though the unlock is answered), ``fci_installed`` (False: the FCI
    feature is missing and its activation refused)."""

    robot: str
    users: dict[str, str]
    link: DeskLink
    token_force_timeout: float = 10.0  # [s] press the Pilot within this after a forced take
    clock: Callable[[], float] = time.monotonic
    sessions: dict[str, str] = field(default_factory=dict)  # session token -> user
    active: ControlToken | None = None
    queue: list[ControlToken] = field(default_factory=list)
    operating_mode: str = "Execution"
    recovery: dict[str, Any] | None = None
    recovery_confirmable: bool = True
    self_test_duration: float = SELF_TEST_DURATION  # [s]
    last_self_test: float = math.nan  # [s, clock] when the last self-test passed (now)
    self_test_until: float = 0.0  # [s, clock] the running self-test ends then (0: none)
    self_test_passes: bool = True
    self_test_reopens: bool = False  # the brakes were open when the self-test began
    fail_next_self_test: bool = False
    td2_acknowledged: bool = False
    end_effector: dict[str, Any] = field(
        default_factory=lambda: initial_end_effector(EndEffector.HAND)
    )
    powered_off: bool = False
    brakes_jammed: bool = False
    fci_installed: bool = True
    listeners: list[Callable[[dict[str, bool]], None]] = field(default_factory=list)
    _next_id: int = 1

    def __post_init__(self) -> None:
        if math.isnan(self.last_self_test):
            self.last_self_test = self.clock()

    @property
    def brakes_open(self) -> bool:
        return bool(self.link.view[0] != 0.0)

    @property
    def fci_active(self) -> bool:
        return bool(self.link.view[1] != 0.0)

    def _switch(self, *, brakes_open: bool | None = None, fci_active: bool | None = None) -> None:
        self.link.set_switches(
            brakes_open=self.brakes_open if brakes_open is None else brakes_open,
            fci_active=self.fci_active if fci_active is None else fci_active,
        )

    # -- authentication ----------------------------------------------------------------

    def login(self, login: Any, password: Any) -> Reply:
        user = login if isinstance(login, str) else None
        expected = self.users.get(user) if user is not None else None
        if (
            expected is None
            or not isinstance(password, str)
            or not secrets.compare_digest(
                "".join(password.split()).encode(),
                "".join(encode_password(user or "", expected).split()).encode(),
            )
        ):
            return error(401, "Unauthorized", "wrong user name or password")
        session = secrets.token_urlsafe(24)
        self.sessions[session] = user or ""
        return Reply(200, session)

    def logout(self, session: str | None) -> Reply:
        self.sessions.pop(session or "", None)
        return Reply(200)

    def check_basic(self, user: str, password: str) -> str | None:
        expected = self.users.get(user)
        if expected is not None and secrets.compare_digest(password.encode(), expected.encode()):
            return user
        return None

    # -- the control token -------------------------------------------------------------

    def _expire(self) -> None:
        now = self.clock()
        self.queue = [t for t in self.queue if t.deadline > now]
        if self.active is None and self.queue:
            waiting = [t for t in self.queue if not t.needs_button]
            if waiting:
                self.active = waiting[0]
                self.queue.remove(waiting[0])

    def _new_token(self, owner: str, *, deadline: float, needs_button: bool) -> ControlToken:
        token = ControlToken(
            self._next_id, secrets.token_urlsafe(24), owner, deadline, needs_button
        )
        self._next_id += 1
        return token

    def active_token(self) -> ControlToken | None:
        self._expire()
        return self.active

    def request_control(self, owner: str, *, force: bool) -> Reply:
        """Legacy: granted at once when free; else queued until the holder releases, or,
        forced, until the Pilot confirms within ``token_force_timeout``."""
        self._expire()
        if self.active is None:
            self.active = self._new_token(owner, deadline=float("inf"), needs_button=False)
            return Reply(200, {"id": self.active.id, "token": self.active.token})
        deadline = self.clock() + (self.token_force_timeout if force else 3600.0)
        token = self._new_token(owner, deadline=deadline, needs_button=force)
        self.queue.append(token)
        return Reply(200, {"id": token.id, "token": token.token})

    def take_v1(self, owner: str, timeout: float) -> tuple[Reply | None, ControlToken | None]:
        """v1: granted at once when free (reply), else queued: the caller waits for
        :meth:`granted` until the deadline, then calls :meth:`take_timed_out`."""
        self._expire()
        if self.active is None:
            self.active = self._new_token(owner, deadline=float("inf"), needs_button=False)
            return Reply(200, {"token": self.active.token, "tokenId": self.active.id}), None
        # A queued v1 take is granted on release, or when the top button confirms presence.
        token = self._new_token(owner, deadline=self.clock() + timeout, needs_button=False)
        self.queue.append(token)
        return None, token

    def granted(self, token: ControlToken) -> Reply | None:
        self._expire()
        if self.active is token:
            return Reply(200, {"token": token.token, "tokenId": token.id})
        return None

    def take_timed_out(self, token: ControlToken) -> Reply:
        if token in self.queue:
            self.queue.remove(token)
        return error(424, "Timeout", "control was not released within the timeout")

    def token_valid(self, token: str | None) -> bool:
        self._expire()
        return (
            self.active is not None
            and token is not None
            and secrets.compare_digest(token.encode(), self.active.token.encode())
        )

    def release(self, token: str | None) -> Reply:
        if not self.token_valid(token):
            return error(403, "ControlTokenUnknown", "this token is not in control")
        self.active = None
        self._expire()  # the next queued request takes over
        return Reply(204)

    # -- Pilot ---------------------------------------------------------------------------

    def confirm_button(self) -> str:
        """The Pilot button that confirms a forced take: the circle on the FER, the top
        button on the FR3 (which, unlike the others, is not sent over the websocket)."""
        return "circle" if self.robot == "fer" else "top"

    def press(self, button: str) -> None:
        """Press and release a Pilot button (``circle``, ..., or the FR3's ``top``)."""
        if button not in (*PILOT_BUTTONS, "top"):
            raise ValueError(f"button: expected one of {[*PILOT_BUTTONS, 'top']}, got {button!r}")
        if button in PILOT_BUTTONS:
            for pressed in (True, False):
                for listener in list(self.listeners):
                    listener({button: pressed})
        if button == self.confirm_button() or (button == "top" and self.robot == "fr3"):
            self._expire()
            # Physical presence confirms the oldest waiting request, forced or queued (v1).
            for token in list(self.queue):
                self.queue.remove(token)
                self.active = token
                token.deadline = float("inf")
                break

    # -- brakes, FCI, mode ---------------------------------------------------------------

    def _blocked(self) -> Reply | None:
        if self.recovery is not None:
            return error(424, "SafetyError", "confirm the safety error first", reason="SafetyError")
        if self.self_test_running():
            return error(424, "ActionUnavailable", "self-test running", reason="SelfTestRunning")
        if self.self_test_elapsed():
            return error(
                424, "ActionUnavailable", "the safety self-test is due", reason="SelfTestDue"
            )
        return None

    def brakes(self, open_: bool) -> Reply:
        if open_:
            blocked = self._blocked()
            if blocked is not None:
                return blocked
            if self.brakes_jammed:  # a fault the answer does not tell: they stay closed
                return Reply(200)
        self._switch(brakes_open=open_)
        return Reply(200)

    def fci(self, on: bool) -> Reply:
        if on:
            if not self.brakes_open:
                return error(
                    424, "ActionUnavailable", "the brakes are closed", reason="BrakesClosed"
                )
            if self.operating_mode != "Execution":
                return error(424, "ActionUnavailable", "not in Execution mode", reason="WrongMode")
            blocked = self._blocked()
            if blocked is not None:
                return blocked
            if not self.fci_installed:
                return error(
                    424, "ActionUnavailable", "the FCI feature is not installed",
                    reason="FeatureMissing",
                )  # fmt: skip
        self._switch(fci_active=on)
        return Reply(200)

    def set_mode(self, mode: Any) -> Reply:
        if mode not in ("Execution", "Programming"):
            return error(400, "InvalidArgument", "expected Execution or Programming")
        if mode != self.operating_mode and self.fci_active:
            return error(424, "ActionUnavailable", "deactivate the FCI first", reason="FciActive")
        self.operating_mode = mode
        return Reply(200)

    # -- safety ----------------------------------------------------------------------------

    def inject_safety_error(self, kind: str = "SafetyError", *, confirmable: bool = True) -> None:
        """A recoverable safety error: the brakes close, the FCI stops, until confirmed
        (``confirmable=False``: its cause persists, and confirming it is refused)."""
        self.recovery = {"type": kind, "safetyErrors": ["SimulatedSafetyError"]}
        self.recovery_confirmable = confirmable
        self._switch(brakes_open=False, fci_active=False)

    def confirm_recovery(self, body: Any) -> Reply:
        if self.recovery is None:
            return error(424, "ActionUnavailable", "no recovery pending", reason="NoRecovery")
        if not isinstance(body, dict) or body.get("type") != self.recovery["type"]:
            return error(400, "InvalidArgument", f"expected type {self.recovery['type']!r}")
        if not self.recovery_confirmable:
            return error(
                424, "ActionUnavailable", "the cause of the safety error persists",
                reason="RecoveryNotPossible",
            )  # fmt: skip
        self.recovery = None
        return Reply(200)

    def reboot(self) -> None:
        """As after power-up: brakes closed, FCI off, nobody in control or logged in."""
        self._switch(brakes_open=False, fci_active=False)
        self.active = None
        self.queue.clear()
        self.sessions.clear()
        self.operating_mode = "Execution"

    # -- views -----------------------------------------------------------------------------

    def brake_states(self) -> list[str]:
        return ["Unlocked" if self.brakes_open else "Locked"] * 7

    def legacy_status(self) -> dict[str, Any]:
        active = self.active_token()
        errors: dict[str, bool] = {}
        safety: dict[str, Any] = {"brakeState": self.brake_states()}
        if self.has_self_test:  # franky reads these two of an FR3
            safety["timeToTd2"] = round(self.self_test_remaining())
            errors["td2Timeout"] = self.self_test_elapsed() and not self.td2_acknowledged
        if self.recovery is not None:
            errors[str(self.recovery["type"])] = True
        safety.update(
            recoverableErrors=errors,
            safetyControllerStatus="SelfTest" if self.self_test_running() else "Idle",
            recovery=self.recovery,
        )
        return {
            "controlToken": {
                "activeToken": None
                if active is None
                else {"id": active.id, "ownedBy": active.owner},
            },
            "safety": safety,
            "derived": {"operatingMode": self.operating_mode},
            "fci": {"active": self.fci_active},
            "robot": self.robot,
            "pilotConfirmButton": self.confirm_button(),
            "pendingControlRequests": len(self.queue),
            "arm": self.link.snapshot(),
        }

    def v1_system(self) -> dict[str, Any]:
        active = self.active_token()
        return {
            "controlToken": {
                "owner": None if active is None else active.owner,
                "tokenId": None if active is None else active.id,
            },
            "operatingMode": self.operating_mode,
            "brakeStatus": "Unlocked" if self.brakes_open else "Locked",
            "fci": "Active" if self.fci_active else "Inactive",
            "recovery": self.recovery,
            "selfTest": self.self_test_state(),
        }
