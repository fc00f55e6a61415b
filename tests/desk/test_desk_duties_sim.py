"""The Desk's duties against the simulated Desk, in every dialect each robot speaks:
shutdown, the end-effector configuration, the pack pose, the self-test, recoveries, and
bring_up with its blockers one by one."""

from __future__ import annotations

import itertools
import pickle
import threading
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from panda_py import libfranka as lf
from panda_py.desk import (
    BrakesError,
    BringUpError,
    BringUpStep,
    ControlNotGrantedError,
    Desk,
    DeskAPI,
    DeskHTTPError,
    DeskUnsupportedError,
    FCIRefusedError,
    NotInControlError,
    RecoveryRefusedError,
    SelfTestFailedError,
)
from panda_py.robots.end_effectors import EndEffector, end_effector_F_T_NE
from panda_py.robots.params import START_POSE
from panda_py.sim import Simulator
from panda_py.sim.desk import DeskProcess
from panda_py.sim.desk.duties import PACK_POSE, SELF_TEST_PERIOD

pytestmark = pytest.mark.timeout(120)
USER, PASSWORD = "franka", "franka123"
DIALECTS = [("fer", "legacy"), ("fr3", "legacy"), ("fr3", "v1")]
FULL_DAY = SELF_TEST_PERIOD - 60.0  # [s] "just after a self-test", with a minute's slack


def ready(sim: Simulator) -> DeskProcess:
    """The robot as after power-up, every fault switch off, its self-test just passed."""
    assert sim.desk is not None
    sim.desk.power_cycle()
    sim.desk.fail_next_self_test(False)
    sim.desk.jam_brakes(False)
    sim.desk.install_fci(True)
    sim.desk.make_self_test_due(SELF_TEST_PERIOD)
    return sim.desk


def desk(sim: Simulator, tokens: str, api: str) -> Desk:
    assert sim.desk is not None
    d = Desk(sim.desk.hostname, USER, PASSWORD, token_dir=tokens, api=None if api == "v1" else api)
    assert d.api == DeskAPI(api)
    return d


def robot(request: pytest.FixtureRequest, name: str) -> Simulator:
    sim: Simulator = request.getfixturevalue(name)
    return sim


@pytest.mark.parametrize(("name", "api"), DIALECTS)
def test_shutdown_silences_the_robot_until_power_cycled(
    name: str, api: str, tokens: str, request: pytest.FixtureRequest
) -> None:
    sim = robot(request, name)
    handle = ready(sim)
    d = desk(sim, tokens, api)
    d.unlock()
    d.shutdown()
    status = handle.status()
    assert status["safety"]["brakeState"] == ["Locked"] * 7 and not status["fci"]["active"]
    with pytest.raises(DeskHTTPError) as info:
        d.login()
    assert (info.value.status, info.value.code) == (503, "SystemOff")
    handle.power_cycle()
    d.login()
    assert d.take_control()


@pytest.mark.parametrize(("name", "api"), DIALECTS)
def test_the_payload_written_persists_and_every_dialect_reads_it(
    name: str, api: str, tokens: str, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    sim = robot(request, name)
    handle = ready(sim)
    d = desk(sim, tokens, api)
    before = d.end_effector()
    assert before.name == "Franka Hand"
    assert np.allclose(before.F_T_EE, end_effector_F_T_NE(EndEffector.HAND), atol=1e-9)
    inertia = np.array([[0.02, 0.001, 0.0], [0.001, 0.03, 0.0], [0.0, 0.0, 0.025]])
    try:
        stored = d.set_payload(1.5, (0.0, 0.01, 0.06), inertia)
        assert stored.mass == 1.5 and np.allclose(stored.inertia, inertia)
        readers = [Desk(handle.hostname, USER, PASSWORD, token_dir=str(tmp_path), api=api)]
        if name == "fr3":  # the same configuration through the other dialect
            other = "legacy" if api == "v1" else "v1"
            readers.append(desk(sim, str(tmp_path / "other"), other))
        for reader in readers:
            again = reader.end_effector()
            assert again.mass == 1.5 and np.allclose(again.center_of_mass, [0.0, 0.01, 0.06])
            assert np.allclose(again.inertia, inertia)
            assert np.allclose(again.F_T_EE, before.F_T_EE, atol=1e-9)
        assert handle.end_effector()["mass"] == 1.5
        with pytest.raises(ValueError, match="mass"):
            d.set_payload(-1.0, (0.0, 0.0, 0.0), inertia)
        assert handle.end_effector()["mass"] == 1.5
    finally:
        d.set_payload(before.mass, before.center_of_mass, before.inertia)


def test_the_robot_reports_the_end_effector_its_desk_configures(
    fr3: Simulator, tokens: str
) -> None:
    # as a real robot: RobotState's m_ee, F_x_Cee, I_ee and F_T_NE (and so O_T_EE) are
    # the Desk's end-effector configuration, applied between motions
    from panda_py.desk import duty_api
    from panda_py.desk.end_effector import legacy_payload_document

    sim = fr3
    ready(sim)
    sim.set_joint_positions(START_POSE)
    d = desk(sim, tokens, "legacy")
    d.unlock()
    d.activate_fci()
    before = d.end_effector()
    inertia = np.array([[0.02, 0.001, 0.0], [0.001, 0.03, 0.0], [0.0, 0.0, 0.025]])
    try:
        with lf.Robot(sim.host) as r:
            s0 = r.read_once()
            assert s0.m_ee == pytest.approx(before.mass)
            d.set_payload(1.5, (0.0, 0.01, 0.06), inertia)
            s1 = r.read_once()
            deadline = time.monotonic() + 5.0
            while s1.m_ee != 1.5 and time.monotonic() < deadline:
                s1 = r.read_once()
            assert s1.m_ee == 1.5
            np.testing.assert_allclose(s1.F_x_Cee, [0.0, 0.01, 0.06])
            np.testing.assert_allclose(np.asarray(s1.I_ee).reshape(3, 3, order="F"), inertia)
            # a longer tool: 5 cm further along the flange's z axis
            doc = legacy_payload_document(before, 1.5, np.array([0.0, 0.01, 0.06]), inertia)
            T = np.array(doc["transformation"], dtype=float).reshape(4, 4, order="F")
            T[2, 3] += 0.05
            doc["transformation"] = T.reshape(16, order="F").tolist()
            d._send(duty_api.request("set_end_effector", "legacy", token=d._need_token(),
                                     body=doc))  # fmt: skip
            s2 = r.read_once()
            while not np.allclose(s2.F_T_NE, T.reshape(16, order="F")):
                assert time.monotonic() < deadline + 5.0, "the frame never arrived"
                s2 = r.read_once()
            O0 = np.asarray(s0.O_T_EE).reshape(4, 4, order="F")
            O2 = np.asarray(s2.O_T_EE).reshape(4, 4, order="F")
            # the same arm: O_T_EE moved 5 cm along the EE's own z axis
            np.testing.assert_allclose(O2[:3, 3], O0[:3, 3] + 0.05 * O0[:3, 2], atol=2e-4)
    finally:
        d._send(duty_api.request("set_end_effector", "legacy", token=d._need_token(),
                                 body=before.raw))  # fmt: skip


@pytest.mark.parametrize(("name", "api"), DIALECTS)
def test_the_arm_goes_to_the_pack_pose(
    name: str, api: str, tokens: str, request: pytest.FixtureRequest
) -> None:
    sim = robot(request, name)
    ready(sim)
    sim.set_joint_positions(START_POSE)
    d = desk(sim, tokens, api)
    with pytest.raises(DeskHTTPError) as info:
        d.move_to_pack_pose()
    assert (info.value.status, info.value.reason) == (424, "BrakesClosed")
    d.unlock()
    d.activate_fci()
    with pytest.raises(DeskHTTPError) as info:
        d.move_to_pack_pose()
    assert (info.value.status, info.value.reason) == (424, "FciActive")
    assert not np.allclose(sim.q(), PACK_POSE[name], atol=1e-3)
    d.deactivate_fci()
    seen: list[np.ndarray] = []
    times: list[float] = []  # [s] of the robot's clock

    def watch_arm() -> None:
        for _ in range(40):
            state = sim.state()
            seen.append(np.asarray(state["q"]))
            times.append(float(state["time"]))
            time.sleep(0.05)

    watch = threading.Thread(target=watch_arm)
    watch.start()
    d.move_to_pack_pose()  # answers once the arm is there
    watch.join()
    assert np.allclose(sim.q(), PACK_POSE[name], atol=2e-3)
    # driven, not placed: the arm passed through the poses between, no joint faster than
    # its limit between two looks (however far apart a loaded machine made them)
    speeds = [
        float(np.abs(b - a).max()) / max(t1 - t0, 1e-3)
        for (a, t0), (b, t1) in itertools.pairwise(zip(seen, times, strict=True))
    ]
    assert max(speeds) < 2.2, speeds  # [rad/s] (FER and FR3 joints 1-4: 2.175 or more)
    assert any(0.05 < np.abs(q - PACK_POSE[name]).max() < 0.5 for q in seen)
    d.release_control()
    with pytest.raises(NotInControlError):
        d.move_to_pack_pose()


@pytest.mark.parametrize("api", ["legacy", "v1"])
def test_the_self_test_falls_due_blocks_unlocking_and_passes_or_fails(
    api: str, fr3: Simulator, tokens: str
) -> None:
    handle = ready(fr3)
    d = desk(fr3, tokens, api)
    assert d.self_test_due_in() > FULL_DAY and d.self_test_status()["status"] == "OK"
    handle.make_self_test_due(1800.0)
    # v1 warns before it is due; the legacy status tells the time left only
    assert d.self_test_status()["status"] == ("Warning" if api == "v1" else "OK")
    assert 1700 < d.self_test_due_in() <= 1800
    handle.make_self_test_due()
    assert d.self_test_due_in() == 0.0
    with pytest.raises(DeskHTTPError) as info:
        d.unlock()
    assert (info.value.status, info.value.reason) == (424, "SelfTestDue")
    assert d.self_test(wait=10.0) > FULL_DAY
    d.unlock()
    d.lock()
    handle.make_self_test_due()
    handle.fail_next_self_test()
    with pytest.raises(SelfTestFailedError) as failed:
        d.self_test(wait=10.0)
    assert failed.value.due_in == 0.0 and failed.value.step is BringUpStep.SELF_TEST
    assert d.self_test_due_in() == 0.0


def test_the_fer_demands_no_self_test(fer: Simulator, tokens: str) -> None:
    ready(fer)
    d = desk(fer, tokens, "legacy")
    for duty in (d.self_test_due_in, d.self_test):
        with pytest.raises(DeskUnsupportedError) as info:
            duty()
        assert (info.value.feature, info.value.api) == ("self_test", "legacy")


@pytest.mark.parametrize(("name", "api"), DIALECTS)
def test_a_pending_recovery_blocks_unlocking_until_confirmed(
    name: str, api: str, tokens: str, request: pytest.FixtureRequest
) -> None:
    sim = robot(request, name)
    handle = ready(sim)
    d = desk(sim, tokens, api)
    assert d.pending_recoveries() == [] and not d.recover()
    handle.inject_safety_error()
    assert d.pending_recoveries() == ["SafetyError"]
    with pytest.raises(DeskHTTPError) as info:
        d.unlock()
    assert (info.value.status, info.value.code) == (424, "SafetyError")
    assert d.recover()
    assert d.pending_recoveries() == []
    d.unlock()


@pytest.mark.parametrize(("name", "api"), DIALECTS)
def test_bring_up_from_power_up_with_a_safety_error_and_the_self_test_due(
    name: str, api: str, tokens: str, request: pytest.FixtureRequest
) -> None:
    sim = robot(request, name)
    handle = ready(sim)
    handle.make_self_test_due()
    handle.inject_safety_error()
    d = Desk(handle.hostname, USER, PASSWORD, token_dir=tokens, api=api, connect=False)
    with pytest.raises(lf.NetworkException):
        lf.Robot(sim.host)  # the FCI is inactive
    report = d.bring_up()  # logs in and takes control first
    assert d.api == DeskAPI(api) and d.has_control()
    assert report.recovered == ("SafetyError",)
    assert report.self_test_ran == (name == "fr3")
    assert report.self_test_due_in > FULL_DAY
    status = handle.status()
    assert status["safety"]["brakeState"] == ["Unlocked"] * 7 and status["fci"]["active"]
    with lf.Robot(sim.host) as arm:
        assert arm.read_once().robot_mode == lf.RobotMode.kIdle
    again = d.bring_up()  # ready already: nothing to do
    assert again.recovered == () and not again.self_test_ran


def _other_holds_control(sim: Simulator, tmp: Path, api: str) -> None:
    desk(sim, str(tmp / "holder"), api)


BLOCKERS: dict[str, tuple[Callable[[Simulator, Path, str], None], type[BringUpError]]] = {
    "control": (_other_holds_control, ControlNotGrantedError),
    "recovery": (
        lambda s, t, a: s.desk.inject_safety_error(confirmable=False),  # type: ignore[union-attr]
        RecoveryRefusedError,
    ),
    "self_test": (
        lambda s, t, a: (s.desk.make_self_test_due(), s.desk.fail_next_self_test()),  # type: ignore[union-attr]
        SelfTestFailedError,
    ),
    "brakes": (lambda s, t, a: s.desk.jam_brakes(), BrakesError),  # type: ignore[union-attr]
    "fci": (lambda s, t, a: s.desk.install_fci(False), FCIRefusedError),  # type: ignore[union-attr]
}


@pytest.mark.parametrize("blocker", list(BLOCKERS))
@pytest.mark.parametrize(("name", "api"), DIALECTS)
def test_bring_up_names_each_blocker(
    name: str, api: str, blocker: str, tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    if blocker == "self_test" and name == "fer":
        pytest.skip("the FER demands no self-test")
    sim = robot(request, name)
    handle = ready(sim)
    block, expected = BLOCKERS[blocker]
    block(sim, tmp_path, api)
    d = desk(sim, str(tmp_path / "me"), api)
    with pytest.raises(expected) as info:
        d.bring_up()
    e = info.value
    assert e.host == handle.hostname and e.step is BringUpStep(blocker)
    copy = pickle.loads(pickle.dumps(e))
    assert type(copy) is type(e) and str(copy) == str(e) and vars(copy) == vars(e)
    if isinstance(e, ControlNotGrantedError):
        assert e.holder == USER and isinstance(e, NotInControlError)
    elif isinstance(e, RecoveryRefusedError):
        assert (e.kind, e.status, e.reason) == ("SafetyError", 424, "RecoveryNotPossible")
    elif isinstance(e, SelfTestFailedError):
        assert e.due_in == 0.0
    elif isinstance(e, BrakesError):
        assert e.brakes == ("Locked",) * 7 and e.status is None
    else:
        assert (e.status, e.reason) == (424, "FeatureMissing")
    status = handle.status()
    assert not status["fci"]["active"]
    if blocker != "fci":  # the brakes open only in the last step but one
        assert status["safety"]["brakeState"] == ["Locked"] * 7
