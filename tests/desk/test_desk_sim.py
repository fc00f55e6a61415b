"""The Desk client against the simulated Desk: every method on both APIs, the coupling
to the FCI, forced takes, token reuse, certificate pinning."""

from __future__ import annotations

import os
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from desk_support import desk_sim, press_when_requested

from panda_py import libfranka as lf
from panda_py.desk import (
    CertificateChangedError,
    Desk,
    DeskAPI,
    DeskHTTPError,
    TakeControlTimeoutError,
)
from panda_py.sim import Simulator

pytestmark = pytest.mark.timeout(120)
USER, PASSWORD = "franka", "franka123"


def fresh(sim: Simulator) -> str:
    assert sim.desk is not None
    sim.desk.power_cycle()
    return sim.desk.hostname


def desk(sim: Simulator, tokens: str, **kw: object) -> Desk:
    assert sim.desk is not None
    return Desk(sim.desk.hostname, USER, PASSWORD, token_dir=tokens, **kw)  # type: ignore[arg-type]


@pytest.mark.parametrize(("robot", "api"), [("fer", "legacy"), ("fr3", "legacy"), ("fr3", "v1")])
def test_every_method(robot: str, api: str, tokens: str, request: pytest.FixtureRequest) -> None:
    sim: Simulator = request.getfixturevalue(robot)
    fresh(sim)
    d = desk(sim, tokens, api=None if api == "v1" else api)
    assert d.api == DeskAPI(api) and d.has_control()
    with pytest.raises(DeskHTTPError) as info:
        d.activate_fci()  # brakes closed
    assert info.value.status == 424
    d.unlock()
    d.activate_fci()
    status = sim.desk.status()  # type: ignore[union-attr]
    assert status["safety"]["brakeState"] == ["Unlocked"] * 7 and status["fci"]["active"]
    assert d.operating_mode() == "Execution"
    assert d.system_status()
    d.deactivate_fci()
    d.set_operating_mode("Programming")
    d.set_operating_mode("Execution")
    d.lock()
    status = sim.desk.status()  # type: ignore[union-attr]
    assert status["safety"]["brakeState"] == ["Locked"] * 7 and not status["fci"]["active"]
    d.release_control()
    assert not d.has_control()
    assert d.take_control()
    d.reboot()  # ends every session and control
    d.login()
    assert not d.has_control()
    d.logout()


def test_v1_self_test_and_recovery(fr3: Simulator, tokens: str) -> None:
    fresh(fr3)
    d = desk(fr3, tokens)
    assert d.api == DeskAPI.V1
    assert d.execute_self_test(wait=5.0) == "OK"
    assert d.recovery_status() is None and not d.recover()
    fr3.desk.inject_safety_error()  # type: ignore[union-attr]
    assert d.recovery_status() == {"type": "SafetyError", "safetyErrors": ["SimulatedSafetyError"]}
    with pytest.raises(DeskHTTPError) as info:
        d.unlock()
    assert (info.value.status, info.value.code) == (424, "SafetyError")
    assert d.recover()
    d.unlock()
    assert d.brake_states() == ["Unlocked"] * 7
    assert d.fci_status() == "Inactive"
    d.release_control()


def test_fci_refused_while_inactive_and_moves_while_braked(fer: Simulator, tokens: str) -> None:
    fresh(fer)
    with pytest.raises(lf.NetworkException):
        lf.Robot(fer.host)
    d = desk(fer, tokens)
    d.unlock()
    d.activate_fci()
    with lf.Robot(fer.host) as robot:
        assert robot.read_once().robot_mode == lf.RobotMode.kIdle
        d.lock()
        with pytest.raises(lf.CommandException):
            robot.control(lambda s, dt: lf.Torques(np.zeros(7)))
        d.unlock()
        robot.automatic_error_recovery()
    d.release_control()


def test_forced_take_completes_on_the_pilot_and_times_out_without(
    fer: Simulator, tmp_path: Path
) -> None:
    fresh(fer)
    holder = desk(fer, str(tmp_path / "a"))
    other = desk(fer, str(tmp_path / "b"))
    assert holder.has_control() and not other.has_control()
    assert other.take_control() is False  # without force: refused, nothing changed
    presser = press_when_requested(fer, "circle")
    assert other.take_control(force=True)
    presser.join()
    assert other.has_control() and not holder.has_control()
    t0 = time.monotonic()
    with pytest.raises(TakeControlTimeoutError):
        holder.take_control(force=True)  # nobody presses the circle
    assert time.monotonic() - t0 >= 1.4
    assert other.has_control()
    other.release_control()


def test_v1_take_is_confirmed_with_the_fr3_top_button_or_times_out(
    fr3: Simulator, tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    import panda_py.desk.client as client_mod

    monkeypatch.setattr(client_mod, "V1_FORCE_TIMEOUT", 1.5)
    fresh(fr3)
    holder = desk(fr3, str(tmp_path / "a"))
    other = desk(fr3, str(tmp_path / "b"))
    presser = press_when_requested(fr3, "top")
    assert other.take_control(force=True)
    presser.join()
    assert other.has_control() and not holder.has_control()
    with pytest.raises(TakeControlTimeoutError):
        holder.take_control(force=True)
    other.release_control()


def test_token_reused_across_sessions(fr3: Simulator, tokens: str) -> None:
    fresh(fr3)
    first = desk(fr3, tokens)
    first.unlock()
    second = desk(fr3, tokens)  # a new process, the same user's store
    assert second.token == first.token and second.has_control()
    second.lock()
    second.release_control()
    assert not first.has_control()


def test_pilot_events_reach_listen(
    fer: Simulator, tokens: str, caplog: pytest.LogCaptureFixture
) -> None:
    fresh(fer)
    d = desk(fer, tokens)
    events: list[dict[str, bool]] = []
    got = threading.Event()

    def cb(event: dict[str, bool]) -> None:
        events.append(event)
        if event == {"check": False}:
            got.set()

    d.listen(cb)
    try:
        for _ in range(50):  # the first event (the full key map) says we are subscribed
            if events:
                break
            time.sleep(0.05)
        fer.press_pilot_button("check")
        assert got.wait(5)
    finally:
        d.stop_listen()
    # stop_listen closes the stream itself (at once, not at the listener's next timeout):
    # no warning that the Desk closed it, and the listener has ended
    assert "closed the Pilot event stream" not in caplog.text
    assert not any(t.name == "panda-py-desk-listen" for t in threading.enumerate())
    assert events[0] == dict.fromkeys(
        ("circle", "cross", "check", "left", "right", "down", "up"), False
    )
    assert events[1:] == [{"check": True}, {"check": False}]


def test_a_changed_certificate_is_refused_then_repinned(tmp_path: Path, tokens: str) -> None:
    with desk_sim("fer", tmp_path / "cert1") as sim:
        assert sim.desk is not None
        host, port, pinned = sim.host, sim.desk.port, sim.desk.fingerprint
        first = desk(sim, tokens).token
    # the same address and port, another certificate
    with desk_sim("fer", tmp_path / "cert2", host=host, port=port) as sim2:
        assert sim2.desk is not None
        presented = sim2.desk.fingerprint
        assert presented != pinned
        fds = len(os.listdir("/proc/self/fd"))
        with pytest.raises(CertificateChangedError) as info:
            desk(sim2, tokens)
        assert pinned in str(info.value) and presented in str(info.value)
        # the refused connection is closed, not held open by the error (the Desk's stop
        # then waited 10 s for it, and left its process running)
        assert len(os.listdir("/proc/self/fd")) == fds
        again = desk(sim2, tokens, repin=True)
        assert again.has_control() and again.token != first
        assert desk(sim2, tokens).has_control()  # pinned anew: accepted from now on


@pytest.mark.parametrize("robot", ["fer", "fr3"])
def test_a_safety_error_ends_a_running_motion(
    robot: str, tokens: str, request: pytest.FixtureRequest
) -> None:
    """A robot's safety error closes the brakes: the running motion ends there (libfranka's
    ControlException, the arm held), not when the client gives up."""
    sim: Simulator = request.getfixturevalue(robot)
    fresh(sim)
    d = desk(sim, tokens)
    d.unlock()
    d.activate_fci()
    assert sim.desk is not None
    ticks = 0

    def loop(state: lf.RobotState, dt: lf.Duration) -> lf.Torques:
        nonlocal ticks
        ticks += 1
        if ticks == 50:
            sim.desk.inject_safety_error()  # type: ignore[union-attr]
        if ticks > 2000:  # the motion would run on: finish so the test fails, not hangs
            return lf.MotionFinished(lf.Torques(np.zeros(7)))
        return lf.Torques(np.zeros(7))

    with lf.Robot(sim.host) as robot_:
        version = robot_.server_version()
        with pytest.raises(lf.ControlException) as info:
            robot_.control(loop)
        assert 50 <= ticks < 100
    # libfranka's MoveStatus from v6 on has a code for it; older robots abort
    expected = "kPreemptedDueToActivatedSafetyFunctions" if version >= 6 else "kAborted"
    assert info.value.status is not None and info.value.status.value == expected
    # the FCI went off with the safety error: nobody connects until it is active again
    with pytest.raises(lf.NetworkException):
        lf.Robot(sim.host)
    with pytest.raises(DeskHTTPError):
        d.unlock()  # not before the safety error is confirmed
    fresh(sim)  # power-cycled, as a person would recover here
    d = desk(sim, tokens)
    d.unlock()
    d.activate_fci()
    with lf.Robot(sim.host) as robot_:
        assert robot_.read_once().robot_mode == lf.RobotMode.kIdle
    d.release_control()


def test_deactivating_the_fci_drops_the_connected_client(fer: Simulator, tokens: str) -> None:
    fresh(fer)
    d = desk(fer, tokens)
    d.unlock()
    d.activate_fci()
    with lf.Robot(fer.host) as robot:
        robot.read_once()
        d.deactivate_fci()
        with pytest.raises(lf.NetworkException):
            for _ in range(100):  # the loop closes it on its next tick
                robot.read_once()
                time.sleep(0.01)
    with pytest.raises(lf.NetworkException):
        lf.Robot(fer.host)
    d.activate_fci()
    with lf.Robot(fer.host) as robot:
        assert robot.read_once().robot_mode == lf.RobotMode.kIdle
    d.release_control()
