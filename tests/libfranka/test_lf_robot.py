"""Robot against the lockstep simulator: state decoding in every protocol version,
setters, reflexes and recovery, client-side rejection of bad commands."""

from __future__ import annotations

import struct

import numpy as np
import pytest

from panda_py import fci
from panda_py import libfranka as lf
from panda_py.robots import START_POSE
from panda_py.sim import Simulator, free_loopback_host

pytestmark = pytest.mark.timeout(60)

# Golden sizes from fci-protocol.md §8 (the independent decoder below must reproduce them).
STATE_SIZE = {5: 2373, 10: 1377}


@pytest.fixture(scope="module")
def sim():
    with Simulator(free_loopback_host(), robot="fr3", lockstep=True) as s:
        yield s


@pytest.fixture
def robot(sim):
    r = lf.Robot(sim.host, version=10)
    yield r
    r.close()
    with lf.Robot(sim.host) as cleanup:  # leave the robot idle and error-free
        cleanup.automatic_error_recovery()
    sim.set_joint_positions(START_POSE)


def _layout(version: int) -> list[tuple[str, int]]:
    """RobotState fields and counts in wire order, written from the reference's table."""
    fields = [("message_id", 1), ("O_T_EE", 16), ("O_T_EE_d", 16), ("F_T_EE", 16), ("EE_T_K", 16)]
    if version >= 4:
        fields += [("F_T_NE", 16), ("NE_T_EE", 16)]
    fields += [("m_ee", 1), ("I_ee", 9), ("F_x_Cee", 3), ("m_load", 1), ("I_load", 9),
               ("F_x_Cload", 3), ("elbow", 2), ("elbow_d", 2)]  # fmt: skip
    fields += [(n, 7) for n in ("tau_J", "tau_J_d", "dtau_J", "q", "q_d", "dq", "dq_d", "ddq_d")]
    fields += [("joint_contact", 7), ("cartesian_contact", 6), ("joint_collision", 7),
               ("cartesian_collision", 6), ("tau_ext_hat_filtered", 7), ("O_F_ext_hat_K", 6),
               ("K_F_ext_hat_K", 6), ("O_dP_EE_d", 6)]  # fmt: skip
    if version >= 5:
        fields.append(("O_ddP_O", 3))
    fields += [("elbow_c", 2), ("delbow_c", 2), ("ddelbow_c", 2), ("O_T_EE_c", 16),
               ("O_dP_EE_c", 6), ("O_ddP_EE_c", 6), ("theta", 7), ("dtheta", 7)]  # fmt: skip
    if version >= 10:
        fields += [("accelerometer_top", 18), ("accelerometer_bottom", 18)]
    return fields


def _decode(version: int, data: bytes) -> dict[str, np.ndarray]:
    f = "d" if version <= 9 else "f"
    n_err = 37 if version <= 4 else 41
    floats = sum(n for name, n in _layout(version)[1:])
    fmt = struct.Struct(f"<Q{floats}{f}BB{n_err}s{n_err}sB{f}")
    assert fmt.size == STATE_SIZE.get(version, fmt.size)
    values = fmt.unpack_from(data)
    out: dict[str, np.ndarray] = {"message_id": np.array(values[0])}
    pos = 1
    for name, n in _layout(version)[1:]:
        out[name] = np.array(values[pos : pos + n], dtype=float)
        pos += n
    for name in ("motion_generator_mode", "controller_mode"):
        out[name] = np.array(values[pos])
        pos += 1
    out["errors"] = np.frombuffer(values[pos], dtype=np.uint8)
    out["reflex_reason"] = np.frombuffer(values[pos + 1], dtype=np.uint8)
    out["robot_mode"] = np.array(values[pos + 2])
    out["control_command_success_rate"] = np.array(values[pos + 3])
    return out


def _capture(robot: lf.Robot) -> list[bytes]:
    seen: list[bytes] = []
    net = robot._conn.net
    receive = net.receive_newest

    def keep(last_id: int) -> bytes:
        data = receive(last_id)
        seen.append(data)
        return data

    net.receive_newest = keep  # type: ignore[method-assign]
    return seen


@pytest.mark.parametrize("version", fci.SUPPORTED_VERSIONS)
def test_every_state_field_decodes_to_what_the_simulator_sent(sim_for_version, version):
    sim = sim_for_version(version)
    with lf.Robot(sim.host, version=version) as robot:
        assert robot.server_version() == version
        robot.set_load(0.4, [0.01, -0.02, 0.05], np.diag([1e-3, 2e-3, 3e-3]))
        robot.set_k(np.array([[1, 0, 0, 0.01], [0, 1, 0, 0.02], [0, 0, 1, 0.03], [0, 0, 0, 1.0]]))
        sim.inject_reflex("joint_reflex", "power_limit_violation")
        robot.read(lambda s: s.robot_mode != lf.RobotMode.kReflex)  # states already queued
        seen = _capture(robot)
        state = robot.read_once()
        raw = _decode(version, seen[-1])
        for name, _ in _layout(version):
            if name.startswith("accelerometer"):
                np.testing.assert_array_equal(getattr(state, name).reshape(18), raw[name])
            elif name != "message_id":
                np.testing.assert_array_equal(getattr(state, name), raw[name], err_msg=name)
        assert state.time.to_msec() == int(raw["message_id"]) > 0
        assert state.robot_mode == lf.RobotMode.kReflex == int(raw["robot_mode"])
        assert state.current_errors.active == ("joint_reflex", "power_limit_violation")
        assert state.last_motion_errors == lf.Errors(raw["reflex_reason"])
        assert state.control_command_success_rate == float(raw["control_command_success_rate"])
        # what the simulator holds, up to the float32 rounding of v10 and what the arm at
        # rest drifts between the two reads (1e-12 rad seen: the simulator runs on)
        truth = sim.state()
        tol = 1e-6 if version >= 10 else 1e-9
        for name in ("q", "F_T_EE", "EE_T_K", "I_load", "F_x_Cload", "m_ee"):
            np.testing.assert_allclose(getattr(state, name), truth[name].reshape(-1) if
                                       name != "m_ee" else truth[name][0], atol=tol)  # fmt: skip
        assert state.m_total == pytest.approx(truth["m_ee"][0] + 0.4, abs=tol)
        if version < 5:  # fields older protocols lack read as libfranka documents them
            np.testing.assert_array_equal(state.O_ddP_O, [0.0, 0.0, -9.81])
        if version < 10:
            np.testing.assert_array_equal(state.accelerometer_top, np.zeros((6, 3)))
        robot.automatic_error_recovery()
        robot.read(lambda s: bool(s.current_errors))  # states sent before the recovery
        assert robot.read_once().robot_mode == lf.RobotMode.kIdle


def test_setters_are_visible_in_the_state(robot):
    NE_T_EE = np.eye(4)
    NE_T_EE[:3, 3] = (0.0, 0.0, 0.05)
    robot.set_ee(NE_T_EE)
    robot.set_k(np.eye(4))
    robot.set_load(0.5, [0.0, 0.0, 0.1], np.eye(3) * 1e-3)
    robot.read(lambda s: s.m_load != 0.5)  # states sent before the setters took effect
    s = robot.read_once()
    np.testing.assert_allclose(s.NE_T_EE.reshape(4, 4, order="F"), NE_T_EE, atol=1e-7)
    F_T_EE = s.F_T_NE.reshape(4, 4, order="F") @ NE_T_EE
    np.testing.assert_allclose(s.F_T_EE.reshape(4, 4, order="F"), F_T_EE, atol=1e-6)
    assert s.m_load == 0.5
    np.testing.assert_allclose(s.F_x_Ctotal, (0.5 * np.array([0, 0, 0.1]) + s.m_ee *
                                              s.F_x_Cee) / s.m_total, atol=1e-7)  # fmt: skip
    # the model on a state agrees with the simulator's own forward kinematics
    model = robot.load_model()
    np.testing.assert_allclose(model.pose(lf.Frame.kEndEffector, s), s.O_T_EE, atol=1e-6)
    robot.set_collision_behavior([20.0] * 7, [30.0] * 7, [20.0] * 6, [30.0] * 6)
    robot.set_collision_behavior(*([[25.0] * 7] * 4 + [[25.0] * 6] * 4))
    robot.set_joint_impedance([3000, 3000, 3000, 2500, 2500, 2000, 2000])
    robot.set_cartesian_impedance([3000, 3000, 3000, 300, 300, 300])
    robot.set_guiding_mode([True, True, True, False, False, False], False)
    with pytest.raises(lf.CommandException, match="Set Load command rejected: invalid argument"):
        robot.set_load(0.5, [0, 0, 0], [[1, 2, 0], [0, 1, 0], [0, 0, 1]])  # not symmetric
    with pytest.raises(lf.InvalidOperationException, match="SetFilters"):
        robot.set_filters(100, 100, 100, 100, 100)  # v10 has none
    with pytest.raises(ValueError, match="K_theta"):
        robot.set_joint_impedance([1.0] * 6)
    with pytest.raises(ValueError, match="4 or 8 arguments"):
        robot.set_collision_behavior([1.0] * 7)


def test_set_filters_exists_up_to_protocol_v5(sim_for_version):
    with lf.Robot(sim_for_version(5).host, version=5) as robot:
        robot.set_filters(1000, 1000, 1000, 1000, 1000)


def test_reflex_aborts_a_motion_with_control_exception_then_recovery(robot, sim):
    ticks = []

    def torque(state, dt):
        ticks.append(dt.to_msec())
        if len(ticks) == 50:
            sim.inject_reflex("joint_reflex")
        return lf.Torques(np.zeros(7))

    with pytest.raises(lf.ControlException) as info:
        robot.control(torque)
    msg = str(info.value)
    expected = 'libfranka: Move command aborted: motion aborted by reflex! ["joint_reflex"]'
    assert msg.startswith(expected)
    assert "control_command_success_rate: " in msg
    assert info.value.reflex_reason == ("joint_reflex",)
    assert len(info.value.log) == 50 and info.value.log[-1].robot_mode == lf.RobotMode.kMove
    assert ticks[0] == 0 and set(ticks[1:]) == {1}
    state = robot.read_once()  # the first state after the abort already shows the reflex
    assert state.robot_mode == lf.RobotMode.kReflex and state.current_errors.joint_reflex
    with pytest.raises(lf.CommandException, match=r'current mode \("Reflex"\)'):
        robot.control(torque)
    robot.automatic_error_recovery()
    robot.read(lambda s: s.robot_mode == lf.RobotMode.kReflex)
    state = robot.read_once()
    assert state.robot_mode == lf.RobotMode.kIdle and not state.current_errors
    assert state.last_motion_errors.joint_reflex


def test_a_torque_step_is_reported_as_controller_torque_discontinuity(robot):
    n = [0]

    def step(state, dt):
        n[0] += 1
        return lf.Torques([5.0 if n[0] > 10 else 0.0, 0, 0, 0, 0, 0, 0])

    with pytest.raises(lf.ControlException, match="controller_torque_discontinuity") as info:
        robot.control(step, limit_rate=False, cutoff_frequency=1000.0)
    assert "controller_torque_discontinuity" in info.value.reflex_reason
    robot.automatic_error_recovery()
    n[0] = 0
    sent = []

    def limited(state, dt):  # the same step, rate-limited by the client: accepted
        n[0] += 1
        sent.append(state.tau_J_d[0])
        out = lf.Torques([5.0 if n[0] > 10 else 0.0, 0, 0, 0, 0, 0, 0])
        out.motion_finished = n[0] >= 60
        return out

    robot.control(limited)  # default limit_rate=True: at most 1 Nm per 1 ms tick
    steps = np.diff(sent)
    assert steps.max() == pytest.approx(1.0, abs=1e-3) and sent[-1] > 4.0


def test_a_joint_jump_is_reported_by_the_robot(robot):
    q0 = robot.read_once().q
    n = [0]

    def jump(state, dt):
        n[0] += 1
        q = q0.copy()
        if n[0] > 5:
            q[3] += 0.05  # 50 rad/s for one tick
        return lf.JointPositions(q)

    with pytest.raises(lf.ControlException, match="joint_motion_generator") as info:
        robot.control_joint_position(jump, limit_rate=False, cutoff_frequency=1000.0)
    assert any(r.startswith("joint_motion_generator_") for r in info.value.reflex_reason)


@pytest.mark.parametrize(
    "bad",
    [
        lambda s: lf.Torques(np.full(7, np.nan)),
        lambda s: lf.JointPositions(s.q),  # the wrong type for a torque loop
        lambda s: lf.motion_finished(lf.Torques(np.zeros(7))).__class__(np.inf * np.ones(7)),
    ],
)
def test_bad_commands_are_rejected_before_anything_is_sent(robot, sim, bad):
    sim.reset_stats()
    with pytest.raises(ValueError):
        robot.control(lambda s, dt: bad(s))
    assert sim.stats()["commands_received"] == 0
    assert robot.read_once().robot_mode == lf.RobotMode.kIdle  # the Move was cancelled
    mutated = lf.Torques(np.zeros(7))
    mutated.tau_J[0] = np.nan  # changed after construction: the loop still checks
    with pytest.raises(ValueError, match="infinite or NaN"):
        robot.control(lambda s, dt: mutated)
    assert sim.stats()["commands_received"] == 0


def test_starting_a_second_motion_is_refused(robot):
    active = robot.start_torque_control()
    with pytest.raises(lf.InvalidOperationException, match="Attempted to start multiple motions"):
        robot.control(lambda s, dt: lf.Torques(np.zeros(7)))
    with pytest.raises(lf.InvalidOperationException):
        robot.read_once()
    active.cancel()
    assert robot.read_once().robot_mode == lf.RobotMode.kIdle


def test_read_calls_back_until_false(robot):
    times: list[int] = []

    def cb(state):
        times.append(state.time.to_msec())
        return len(times) < 5

    robot.read(cb)
    assert len(times) == 5 and bool(np.all(np.diff(times) > 0))


def test_the_states_a_late_read_passes_over_are_counted(robot):
    """A read hands the newest state (as libfranka's): a callback that takes 30 ms lets
    about 30 queue, and the read passes over all but the newest. ``skipped_states``
    counts them, so on loopback (no datagram lost) the gaps in the states' times from the
    first state on are exactly the states passed over since it (the states queued before
    the read began are passed over too, before the first)."""
    import time

    times: list[int] = []
    counted: list[int] = []

    def cb(state):
        times.append(state.time.to_msec())
        counted.append(robot.skipped_states)
        if len(times) == 3:
            time.sleep(0.03)
        return len(times) < 6

    robot.read(cb)
    skipped = counted[-1] - counted[0]
    gaps = int(np.sum(np.diff(times) - 1))
    assert skipped >= 10  # (the lockstep simulator's idle clock runs at the wall's)
    assert gaps == skipped


@pytest.mark.parametrize("version", [5, 10])
def test_read_once_after_a_setter_shows_the_new_value(sim_for_version, version):
    """read_once discards queued states first (libfranka's readOnce), so a setter's effect
    is visible in the very next read_once, as panda-python sees it."""
    with lf.Robot(sim_for_version(version).host, version=version) as robot:
        for mass in (0.25, 0.5, 0.0):
            robot.set_load(mass, [0.0, 0.0, 0.05], np.eye(3) * 1e-3)
            assert robot.read_once().m_load == pytest.approx(mass)
        for k in (0.01, 0.0):
            EE_T_K = np.eye(4)
            EE_T_K[2, 3] = k
            robot.set_k(EE_T_K)
            assert robot.read_once().EE_T_K[14] == pytest.approx(k, abs=1e-7)


def test_the_owning_loop_api_takes_raw_states_and_refuses_bad_input(sim_for_version) -> None:
    """Robot.fileno / receive_raw_state / decode_state (what Panda's control process
    waits on), RobotState.raw_fields, and start_torque_control's state_type."""
    import select

    from panda_py.libfranka.state import TickState

    sim = sim_for_version(10)
    with lf.Robot(sim.host) as robot:
        assert select.select([robot.fileno()], [], [], 1.0)[0]  # states arrive there
        data = robot.receive_raw_state()
        assert len(data) >= robot.state_dtype.itemsize
        state = robot.decode_state(data, TickState)
        assert isinstance(state, TickState) and state.raw == data
        assert state.q is state.q and not state.q.flags.writeable  # decoded once, read-only
        np.testing.assert_array_equal(robot.decode_state(data).q, state.q)
        both = state.raw_fields(("m_ee", "m_load"))
        assert both == state.raw_fields(("m_ee",)) + state.raw_fields(("m_load",))
        with pytest.raises(ValueError, match=r"data: expected a RobotState v10 of \d+ bytes"):
            robot.decode_state(data[:100])
        with pytest.raises(ValueError, match="data: expected a raw state"):
            robot.decode_state([1, 2, 3])  # type: ignore[arg-type]
        with pytest.raises(ValueError, match="state_type: expected RobotState"):
            robot.decode_state(data, dict)  # type: ignore[arg-type]
        with pytest.raises(ValueError, match="state_type: expected RobotState"):
            robot.start_torque_control(state_type=int)  # type: ignore[arg-type]
        with pytest.raises(ValueError, match="names: expected a tuple of the state's field"):
            state.raw_fields(("q", "no_such_field"))


def test_the_compiled_loops_seam_refuses_what_it_cannot_take(sim_for_version) -> None:
    """ActiveControl.torque_io / caught_up / read_received (what the control process's
    compiled ticks use): a motion with a filter, no state read yet, a datagram that is not
    one are refused by name; a state taken elsewhere is read as readOnce reads it."""
    from panda_py.libfranka.limits import MAX_CUTOFF_FREQUENCY

    sim = sim_for_version(10)
    with lf.Robot(sim.host) as robot:
        with robot.start_torque_control(cutoff_frequency=100.0) as filtered:
            filtered.readOnce()
            with pytest.raises(lf.InvalidOperationException, match="without filter"):
                filtered.torque_io()
        with robot.start_torque_control(cutoff_frequency=MAX_CUTOFF_FREQUENCY) as active:
            with pytest.raises(lf.InvalidOperationException, match="readOnce"):
                active.torque_io()
            state, _ = active.readOnce()
            io = active.torque_io()
            assert io.udp == robot.fileno() and io.last_data == state.raw
            for bad, got in ((state.raw[:100], "100 bytes"), ([1, 2], "list")):
                with pytest.raises(
                    ValueError, match=f"data: expected a state datagram of \\d+ bytes, got {got}"
                ):
                    active.caught_up(bad)  # type: ignore[arg-type]
                with pytest.raises(ValueError, match=f"got {got}"):
                    active.read_received(bad)  # type: ignore[arg-type]
            again, dt = active.read_received(state.raw)
            assert again.raw == state.raw and dt.to_msec() == 0
            active.write_torques([0.0] * 7)


def test_rigid_errors_refuses_what_is_not_a_transform() -> None:
    from panda_py import checks

    assert float(checks.rigid_errors(np.eye(4))) == 0.0
    assert checks.rigid_errors(np.stack([np.eye(4)] * 3)).shape == (3,)
    with pytest.raises(ValueError, match=r"T: expected shape \(4, 4\) or \(N, 4, 4\)"):
        checks.rigid_errors(np.eye(3))
    with pytest.raises(ValueError, match="T: expected 4x4 transforms"):
        checks.rigid_errors("eye")


def test_write_torques_sends_what_write_once_sends_and_refuses_bad_input(robot, sim) -> None:
    """ActiveControl.write_torques (the owning loop's write: a list, no Torques object):
    the robot gets the same torques as from writeOnce(Torques(...)); bad input is refused
    with a clear error and nothing is sent, the motion going on."""
    tau = [0.05, -0.1, 0.15, -0.2, 0.25, -0.3, 0.35]  # (steps within the rate limit)
    active = robot.start_torque_control()
    try:
        active.readOnce()
        active.write_torques(tau)
        state, _ = active.readOnce()
        np.testing.assert_allclose(state.tau_J_d, tau, atol=1e-12)
        active.writeOnce(lf.Torques([-t for t in tau]))
        state, _ = active.readOnce()
        np.testing.assert_allclose(state.tau_J_d, [-t for t in tau], atol=1e-12)
        received = sim.stats()["commands_received"]
        for bad in (tau[:6], [*tau[:6], float("nan")], [*tau[:6], float("inf")],
                    [*tau[:6], "0.1"], None):  # fmt: skip
            with pytest.raises(ValueError, match="tau_J: expected 7 finite torques"):
                active.write_torques(bad)
        assert sim.stats()["commands_received"] == received
        active.write_torques(tau, motion_finished=True)  # still running: ends it
        assert active.finished
    finally:
        active.cancel()
    with pytest.raises(lf.InvalidOperationException, match="already finished"):
        active.write_torques(tau)
    moving = robot.start_joint_position_control()
    try:
        moving.readOnce()
        with pytest.raises(lf.InvalidOperationException, match="is for torque control"):
            moving.write_torques(tau)
    finally:
        moving.cancel()
