"""The Desk's duties beyond taking control: shutdown, the end-effector configuration,
the pack pose, and :meth:`~DeskDuties.bring_up`, which does in order what a robot needs
before control (the self-test and the recoveries are in ``safety.py``).

A mixin of :class:`~panda_py.desk.client.Desk` (it uses the session's requests and
control token); the requests themselves are in ``duty_api.py``.
"""

from __future__ import annotations

import logging
import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

from panda_py import checks
from panda_py.desk import duty_api
from panda_py.desk.end_effector import (
    EndEffectorConfig,
    check_payload,
    from_legacy,
    from_v1,
    legacy_payload_document,
    v1_payload_patch,
)
from panda_py.desk.errors import (
    BrakesError,
    ControlNotGrantedError,
    DeskHTTPError,
    DeskUnsupportedError,
    FCIRefusedError,
    OperatingModeError,
    RecoveryRefusedError,
    TakeControlTimeoutError,
)
from panda_py.desk.safety import SafetyDuties

log = logging.getLogger("panda_py.desk")

PACK_POSE_TIMEOUT = 60.0  # [s] the Desk answers once the arm has reached the pack pose


@dataclass(frozen=True)
class BringUpReport:
    """What :meth:`DeskDuties.bring_up` did: the recoverable errors it confirmed, whether
    it ran the self-test, and how long until the self-test is due [s] (``inf``: this
    robot demands none)."""

    recovered: tuple[str, ...]
    self_test_ran: bool
    self_test_due_in: float


class DeskDuties(SafetyDuties):
    """Shutdown, end-effector configuration, pack pose, and the bring-up."""

    if TYPE_CHECKING:
        _tokenless: bool
        _logged_in: bool
        timeout: float

        def login(self) -> None: ...
        def _active(self) -> tuple[str, str]: ...
        def has_control(self) -> bool: ...
        def take_control(self, force: bool = False) -> bool: ...
        def unlock(self, force: bool = True) -> None: ...
        def activate_fci(self) -> None: ...
        def deactivate_fci(self) -> None: ...
        def operating_mode(self) -> str: ...
        def set_operating_mode(self, mode: str) -> None: ...
        def brake_states(self) -> list[str]: ...
        def fci_status(self) -> str: ...

    # -- power -------------------------------------------------------------------------

    def shutdown(self) -> None:
        """Shut the robot's control unit down (needs control). Every connection drops;
        the robot is off until its power switch is cycled."""
        token = self._need_token()
        if self._dialect() == "v1":
            self._send(duty_api.request("shutdown", "v1", token=token))
        else:  # the token travels in the body (jk-ethz/franka_lock_unlock)
            self._send(duty_api.request("shutdown", "legacy", body={"token": token}))
        log.warning("the robot at %s is shutting down", self._hostname)

    # -- end effector ------------------------------------------------------------------

    def end_effector(self) -> EndEffectorConfig:
        """The end-effector configuration the Desk stores: ``mass`` [kg],
        ``center_of_mass`` [m], ``inertia`` [kg m^2], ``F_T_EE`` (flange to EE), ``name``."""
        api = self._dialect()
        read = from_v1 if api == "v1" else from_legacy
        request = duty_api.request("end_effector", api)
        return self._read(request, f"an end-effector configuration ({api})", read)

    def set_payload(self, mass: float, center_of_mass: Any, inertia: Any) -> EndEffectorConfig:
        """Store what the flange carries: ``mass`` [kg] (0 to the robot's 3 kg payload),
        ``center_of_mass`` (3,) [m] in the flange frame, ``inertia`` (3, 3) [kg m^2]
        about the centre of mass (symmetric, positive semi-definite). The end effector's
        name and frame stay as stored. Checked before any request: bad values raise
        ``ValueError`` naming the argument. Needs control; returns the configuration as
        the robot stored it."""
        m, com, inertia_m = check_payload(mass, center_of_mass, inertia)
        token = self._need_token()
        api = self._dialect()
        current = self.end_effector()
        if api == "v1":
            body = v1_payload_patch(current, m, com, inertia_m)
        else:
            body = legacy_payload_document(current, m, com, inertia_m)
        self._send(duty_api.request("set_end_effector", api, token=token, body=body))
        log.info("stored a payload of %.3f kg on %s", m, self._hostname)
        return self.end_effector()

    # -- pack pose ---------------------------------------------------------------------

    def move_to_pack_pose(self) -> None:
        """Move the arm to its pack (transport) pose, as Desk's Settings > System > Move
        to Pack Pose does (needs control, the brakes open and the FCI inactive). Returns
        once the robot answers; allow up to ``PACK_POSE_TIMEOUT`` [s] for the motion."""
        token = self._need_token()
        request = duty_api.request("pack_pose", self._dialect(), token=token)
        self._send(request, timeout=max(self.timeout, PACK_POSE_TIMEOUT))

    # -- bring-up ------------------------------------------------------------------------

    def _brake_states_or_none(self) -> list[str] | None:
        if self._dialect() == "v1":
            return self.brake_states()
        status = self._legacy_status()
        states = ((status or {}).get("safety") or {}).get("brakeState")
        return [str(s) for s in states] if isinstance(states, list) else None

    def bring_up(
        self, *, force: bool = False, self_test_within: float = 0.0, self_test_wait: float = 300.0
    ) -> BringUpReport:
        """Make the robot ready for control, in order: log in if need be, take control
        (``force``: confirm on the Pilot), confirm pending recoverable errors, run the
        self-test if it is due within ``self_test_within`` [s] (waiting up to
        ``self_test_wait`` [s]), switch to Execution, open the brakes, activate the FCI.
        Steps already done are skipped.

        Each blocker raises its :class:`~panda_py.desk.errors.BringUpError`:
        :class:`ControlNotGrantedError`, :class:`RecoveryRefusedError`,
        :class:`SelfTestFailedError`, :class:`OperatingModeError`, :class:`BrakesError`,
        :class:`FCIRefusedError` (each with the robot's ``status``/``code``/``reason``)."""
        host = self._hostname
        self_test_within = checks.number("self_test_within", self_test_within, "[s]", low=0.0)
        self_test_wait = checks.timeout("self_test_wait", self_test_wait)
        if not self._logged_in:
            self.login()
        api = self._dialect()
        # 1. control
        if not self._tokenless and not self.has_control():
            try:
                granted = self.take_control(force=force)
            except TakeControlTimeoutError as exc:
                raise ControlNotGrantedError(
                    host, "nobody confirmed the forced take on the Pilot in time", reason="Timeout"
                ) from exc
            if not granted:
                _, holder = self._active()
                raise ControlNotGrantedError(
                    host,
                    f"{holder or 'another user'} is in control (bring_up(force=True) takes it "
                    "once somebody confirms on the Pilot)",
                    holder=holder,
                )
        # 2. recoveries
        pending = self._pending()
        for recovery in pending:
            kind = str(recovery["type"])
            try:
                self._confirm(recovery)
            except DeskHTTPError as exc:
                raise RecoveryRefusedError.from_http(
                    host, f"the robot refused to confirm the safety error {kind}", exc, kind=kind
                ) from exc
        recovered = tuple(str(p["type"]) for p in pending)
        left = self.pending_recoveries()
        if left:
            raise RecoveryRefusedError(
                host,
                f"the safety error {left[0]} is still pending after confirmation",
                kind=left[0],
            )
        # 3. self-test
        try:
            due = self.self_test_due_in()
        except DeskUnsupportedError:
            due = math.inf
        ran = due <= self_test_within
        if ran:
            self.deactivate_fci()  # the self-test does not run with the FCI active
            due = self.self_test(wait=self_test_wait)
        # 4. operating mode (the FCI runs in Execution only)
        if api == "v1" or self._legacy_status() is not None:
            try:
                if self.operating_mode() != "Execution":
                    self.set_operating_mode("Execution")
            except DeskHTTPError as exc:
                raise OperatingModeError.from_http(
                    host, "the robot would not switch to Execution", exc
                ) from exc
        # 5. brakes
        states = self._brake_states_or_none()
        if states is None or any(s != "Unlocked" for s in states):
            try:
                self.unlock()
            except DeskHTTPError as exc:
                raise BrakesError.from_http(
                    host, "the robot refused to open the brakes", exc
                ) from exc
            states = self._brake_states_or_none()
            if states is not None and any(s != "Unlocked" for s in states):
                raise BrakesError(
                    host, "the brakes are still locked after unlocking", brakes=tuple(states)
                )
        # 6. FCI
        if api != "v1" or self.fci_status() != "Active":
            try:
                self.activate_fci()
            except DeskHTTPError as exc:
                raise FCIRefusedError.from_http(
                    host, "the robot refused to activate the FCI", exc
                ) from exc
            if api == "v1" and self.fci_status() != "Active":
                raise FCIRefusedError(host, "the FCI is still inactive after activating it")
        log.info("%s is ready for control", host)
        return BringUpReport(recovered, ran, due)


__all__ = ["PACK_POSE_TIMEOUT", "BringUpReport", "DeskDuties"]
