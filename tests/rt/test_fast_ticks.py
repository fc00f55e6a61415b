"""The control loop's compiled ticks (rt/_tick.py, rt/fastloop.py) against the Python tick
they replace, on states sent over a real UDP socket as a robot sends them: the same
commands (to 1e-9), the same hand-backs to Python (a request, a changed load or
impedance, a robot that left the motion, silence), the same errors (non-finite torques),
the state published and logged as the Python tick publishes and logs it."""

from __future__ import annotations

import dataclasses
import socket
import time
from collections.abc import Iterator
from typing import Any

import numpy as np
import pytest

from panda_py import fci, kinematics
from panda_py.controllers import (
    AppliedForce,
    AppliedTorque,
    CartesianImpedance,
    CartesianTarget,
    Force,
    IntegratedVelocity,
    JointPosition,
    JointTarget,
    TorqueController,
    conditions,
    laws,
)
from panda_py.controllers.conditions import Distance, Elapsed, Errors, Field, when
from panda_py.controllers.finalize import Finalize
from panda_py.controllers.model import ControlModel
from panda_py.controllers.moves import JointMove, tracker_for
from panda_py.controllers.plans import JointPlan, PosePlan
from panda_py.libfranka import ControlException, RobotMode, TorqueIO
from panda_py.libfranka.state import TickState
from panda_py.motion import rotation
from panda_py.motion.online import OnlineLimits
from panda_py.robots.params import START_POSE, get_robot
from panda_py.rt import fastloop
from panda_py.rt.shm import HEADER, LOG_FIELDS, LogRing, SharedBlock, anonymous_file

pytestmark = pytest.mark.skipif(fastloop.kernels() is None, reason="numba runs the ticks")

MG, CTRL = 5, 2  # the running modes the states carry (any values: the kernel compares)
MOVE = int(RobotMode.kMove.value)
SPEC = get_robot("fer")
MODEL = ControlModel(SPEC)
KIN = kinematics.get_kinematics(SPEC)


# another end effector: 12 cm further along the flange's z, turned 90 degrees about it
OTHER_EE = np.array([[0.0, -1.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.12],
                     [0.0, 0.0, 0.0, 1.0]])  # fmt: skip


def _state(dialect: Any, mid: int, q: np.ndarray, dq: np.ndarray, tau_J_d: np.ndarray,
           *, mode: int = MOVE, load: float = 0.0, tau_J: np.ndarray | None = None,
           F_T_EE: np.ndarray | None = None, force: Any = None,
           error: int | None = None) -> bytes:  # fmt: skip
    r = np.zeros((), dialect.state_dtype)
    if force is not None:  # the external wrench (a guarded move's conditions read it)
        r["O_F_ext_hat_K"] = force
    if error is not None:
        r["errors"][error] = True
    r["message_id"] = mid
    r["motion_generator_mode"], r["controller_mode"], r["robot_mode"] = MG, CTRL, mode
    r["q"], r["dq"], r["tau_J_d"], r["q_d"] = q, dq, tau_J_d, q
    kin = KIN if F_T_EE is None else kinematics.get_kinematics(SPEC, F_T_EE)
    r["O_T_EE"] = kin.fk(q).reshape(16, order="F")
    r["F_T_EE"] = r["EE_T_K"] = np.eye(4).reshape(16)
    if F_T_EE is not None:
        r["F_T_EE"] = F_T_EE.reshape(16, order="F")
    r["m_load"] = load
    if tau_J is not None:
        r["tau_J"] = tau_J
    return r.tobytes()


def _plan(kind: str, q0: np.ndarray) -> Any:
    """A plan of 200 ms that moves the arm a little from ``q0``."""
    n = 201
    s = np.linspace(0.0, 1.0, n)[:, None]
    limits = OnlineLimits.joints(SPEC, 1.0)
    if kind == "JointMove":
        dq_goal = np.array([0.05, -0.04, 0.03, 0.06, -0.02, 0.04, 0.05])
        q = q0 + s * dq_goal
        dq = np.tile(dq_goal / 0.2, (n, 1))
        return JointPlan(q, dq, np.zeros((n, 7)), np.full(7, 600.0), np.full(7, 50.0), 1e-3,
                         1e-2, limits)  # fmt: skip
    T = np.asarray(KIN.fk(q0))
    p = T[:3, 3] + s * np.array([0.02, -0.03, 0.01])
    quat = np.tile(laws.quat_from_matrix(T.reshape(16, order="F")), (n, 1))
    v = np.zeros((n, 6))
    v[:, :3] = np.array([0.02, -0.03, 0.01]) / 0.2
    return PosePlan(p, quat, v, np.zeros((n, 6)), q0, np.diag([600.0] * 3 + [30.0] * 3), 1.0,
                    0.5, 1e-3, 1e-2, 5e-2, OnlineLimits.cartesian(SPEC, 1.0))  # fmt: skip


def make(kind: str, state: Any) -> Any:
    """A law of ``kind`` started on ``state`` (None: a user's handle, not started)."""
    if kind in ("JointMove", "PoseMove"):
        return tracker_for(_plan(kind, np.asarray(START_POSE, dtype=float)))
    if kind == "CartesianImpedance":
        law: Any = CartesianImpedance(filter_coeff=0.3, damping_ratio=0.8)
    elif kind == "JointTarget":
        law = JointTarget(0.5, timeout=0.1)
    elif kind == "CartesianTarget":
        law = CartesianTarget(0.5, timeout=0.1)
    elif kind == "JointPosition":
        law = JointPosition(filter_coeff=0.2)
    elif kind == "IntegratedVelocity":
        law = IntegratedVelocity()
    elif kind == "AppliedForce":
        law = AppliedForce(damping=np.full(7, 2.0), filter_coeff=0.3)
    elif kind == "Force":  # (far from its threshold: these tests' arm wanders some cm)
        law = Force(k_p=0.8, k_i=3.0, threshold=1.0, filter_coeff=0.2)
    else:
        law = AppliedTorque(damping=np.full(7, 2.0), filter_coeff=0.5)
    if state is not None:
        law.start(state, MODEL)
    return law


def _move_input(kind: str, law: Any, k: int) -> None:
    """The user's new inputs at tick ``k`` (on the handle and on the reference alike)."""
    if kind == "CartesianImpedance":
        x = np.asarray(KIN.fk(START_POSE))[:3, 3] + [0.0, 0.05 if k < 90 else -0.03, 0.0]
        law.set_control(x, np.array([1.0, 0.0, 0.0, 0.0]))
        if k == 120:  # a new impedance: the damping target is Python's to compute
            law.set_impedance(np.diag([500.0, 500.0, 500.0, 20.0, 20.0, 20.0]))
    elif kind == "JointPosition":
        law.set_control(np.asarray(START_POSE) + 0.02 * (k // 40))
    elif kind == "IntegratedVelocity":
        law.set_control(np.full(7, 0.1 if k < 90 else -0.2))
    elif kind == "AppliedTorque":
        law.set_control(np.linspace(-1.0, 1.0, 7) * (k // 40))
    elif kind == "AppliedForce":
        law.set_control(np.array([2.0, -1.0, 4.0, 0.2, -0.1, 0.3]) * (k // 40))
        if k == 120:
            law.set_damping(np.full(7, 6.0))
    elif kind == "Force":
        law.set_control(np.array([1.5, -2.0, -6.0]) * (k // 40))
        if k == 120:  # new gains and damping, the threshold still far
            law.set_proportional_gain(1.5)
            law.set_integral_gain(0.5)
            law.set_damping(np.full(7, 2.0))
            law.set_threshold(0.8)


KINDS = ("CartesianImpedance", "JointPosition", "IntegratedVelocity", "AppliedTorque",
         "AppliedForce", "Force", "JointMove", "PoseMove")  # fmt: skip
# the laws that push with a force at the end effector (rt._tick_wrench): also a new end
# effector on the way, and measured torques
WRENCH = ("AppliedForce", "Force")


class Rig:
    """A robot's UDP socket and the client's, a shared block, and one law run by the
    compiled ticks beside its reference run by the Python tick."""

    def __init__(self, version: int, kind: str = "CartesianImpedance") -> None:
        self.dialect = fci.dialect(version)
        self.robot = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.robot.bind(("127.0.0.1", 0))
        self.client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        self.client.bind(("127.0.0.1", 0))
        self.client.connect(self.robot.getsockname())
        self.robot.connect(self.client.getsockname())
        self.client.setblocking(False)
        self.robot.settimeout(2.0)
        self.block, fd = SharedBlock.create()
        self.fd = fd
        self.rng = np.random.default_rng(version)
        self.mid = 100
        self.q = np.asarray(START_POSE, dtype=float)
        self.last = _state(self.dialect, self.mid, self.q, np.zeros(7), np.zeros(7))
        first = TickState(self.dialect, self.last)
        self.law, self.ref = make(kind, first), make(kind, TickState(self.dialect, self.last))
        self.handle: Any = None
        if isinstance(self.law, TorqueController):
            values = self.law.open_slot(self.block)
            self.handle = make(kind, None)
            self.handle.attach(self.block, values)
        self.fin, self.fin_ref = Finalize(SPEC), Finalize(SPEC)
        # the first tick is Python's, in the loop as here
        self.law.tick(0.0)
        self.law.step(first, MODEL)
        self.ref.tick(0.0)
        self.ref.step(TickState(self.dialect, self.last), MODEL)
        io = dataclasses.replace(
            TorqueIO.unconnected(version), udp=self.client.fileno(),
            last_data=self.last, modes=(MG, CTRL, MOVE),
        )  # fmt: skip
        self.io = io
        self.fast = fastloop.FastTicks(io, self.block, self.fin, None)
        self.command = np.ndarray((), self.dialect.command_dtype, buffer=io.command)

    def close(self) -> None:
        del self.fast
        self.block.close()
        self.robot.close()
        self.client.close()

    def next_state(self, **kw: Any) -> bytes:
        self.mid += 1
        self.q = self.q + self.rng.normal(0.0, 2e-3, 7)
        kw.setdefault("tau_J", self.rng.normal(0.0, 3.0, 7))
        return _state(self.dialect, self.mid, self.q, self.rng.normal(0.0, 0.05, 7),
                      self.rng.normal(0.0, 2.0, 7), **kw)  # fmt: skip

    def reference(self, data: bytes, dt: float) -> np.ndarray:
        """The reference's command for ``data`` (its law's torques in ``ref_tau``)."""
        state = TickState(self.dialect, data)
        self.ref.tick(dt)
        self.ref_tau = np.array(self.ref.step(state, MODEL), dtype=float)
        return np.asarray(self.fin_ref(self.ref_tau, state))

    def run(self, *, chan: int = -1, budget: int = 1, wait_ms: int = 1000,
            log: LogRing | None = None) -> fastloop.Outcome:  # fmt: skip
        compiled = self.law.compiled(TickState(self.dialect, self.last), MODEL)
        assert compiled is not None
        return self.fast.run(self.law, compiled, self.last, chan=chan, requests_taken=0,
                             log=log, budget=budget, wait_ms=wait_ms)  # fmt: skip

    def python_tick(self, data: bytes, dt: float) -> np.ndarray:
        """What the loop does with a state the compiled ticks hand back."""
        state = TickState(self.dialect, data)
        self.law.tick(dt)
        self.last = data
        sent = np.asarray(self.fin(self.law.step(state, MODEL), state))
        self.law.published()
        return sent


@pytest.fixture(params=[5, 10])
def rig(request: Any) -> Iterator[Rig]:
    r = Rig(request.param, "CartesianImpedance")
    yield r
    r.close()


@pytest.mark.parametrize("version", [5, 10])
@pytest.mark.parametrize("kind", KINDS)
def test_compiled_ticks_send_the_python_ticks_commands(kind: str, version: int) -> None:
    rig = Rig(version, kind)
    try:
        handed_back = []
        for k in range(1, 150):
            if k in (40, 90, 120) and rig.handle is not None:  # the user's new inputs
                _move_input(kind, rig.handle, k)
                _move_input(kind, rig.ref, k)
            ee = OTHER_EE if kind in WRENCH and k >= 100 else None  # another end effector
            data = rig.next_state(load=0.5 if k >= 70 else 0.0, F_T_EE=ee)  # a load at 70
            rig.robot.send(data)
            outcome = rig.run()
            expected = rig.reference(data, 1e-3)
            if outcome.then == "pending":
                handed_back.append(k)
                assert outcome.pending == data
                sent = rig.python_tick(data, 1e-3)
            else:
                assert outcome.then == "wait" and outcome.ticks == 1
                reply = rig.robot.recv(4096)
                rec = np.frombuffer(reply, rig.dialect.command_dtype)[0]
                assert int(rec["message_id"]) == rig.mid
                sent = np.frombuffer(rec["tau_J_d"].tobytes(), np.float64)
                rig.last = data
                assert rig.block.read_state() == data  # published as the Python tick does
                # the law's torques before the finishing (which may saturate them)
                np.testing.assert_allclose(rig.fast.tau, rig.ref_tau, rtol=0.0, atol=1e-9)
            np.testing.assert_allclose(sent, expected, rtol=0.0, atol=1e-9)
            if rig.handle is not None:  # what the user reads back
                np.testing.assert_allclose(rig.handle.get_time(), rig.ref.t, atol=1e-12)
        # handed back: the load (70) where the law uses the model, another end effector
        # (100) where it uses the kinematics, a new impedance (120), a move's trajectory's
        # end (200 ms: from tick 200 on, past this run)
        expected_back = {
            "CartesianImpedance": [70, 120], "JointMove": [70], "PoseMove": [70],
            "AppliedForce": [100], "Force": [70, 100],
        }.get(kind, [])  # fmt: skip
        assert handed_back == expected_back
        assert rig.law.t == pytest.approx(rig.ref.t)
        if kind == "IntegratedVelocity":
            np.testing.assert_array_equal(rig.handle.get_qd(), rig.ref.get_qd())
        if kind in WRENCH:  # the filters (and Force's integral) carried across hand-backs
            names = ("_law",) if kind == "Force" else ("_in", "_D")
            for name in names:
                np.testing.assert_allclose(getattr(rig.law, name), getattr(rig.ref, name),
                                           rtol=0.0, atol=1e-9)  # fmt: skip
    finally:
        rig.close()


def test_a_robot_that_left_the_motion_is_handed_back_unanswered(rig: Rig) -> None:
    data = rig.next_state(mode=int(RobotMode.kReflex.value))
    rig.robot.send(data)
    outcome = rig.run()
    assert outcome.then == "pending" and outcome.pending == data and outcome.ticks == 0


def test_non_finite_torques_raise_and_send_nothing(rig: Rig) -> None:
    rig.mid += 1
    r = np.frombuffer(_state(rig.dialect, rig.mid, rig.q, np.zeros(7), np.zeros(7)),
                      rig.dialect.state_dtype).copy()  # fmt: skip
    r["q"][0, 3] = np.nan  # (a NaN the sensors could never send: the law's torques are NaN)
    rig.robot.send(r.tobytes())
    with pytest.raises(ControlException, match="non-finite torques"):
        rig.run()
    rig.robot.settimeout(0.05)
    with pytest.raises(TimeoutError):
        rig.robot.recv(4096)


def test_a_state_goes_first_then_a_request_hands_back(rig: Rig) -> None:
    a, b = socket.socketpair()
    try:
        b.send(b"x")  # a request waiting on the channel
        data = rig.next_state()
        rig.robot.send(data)
        outcome = rig.run(chan=a.fileno(), budget=5)
        assert outcome.then == "wait" and outcome.ticks == 1  # the state was answered
        reply = np.frombuffer(rig.robot.recv(4096), rig.dialect.command_dtype)[0]
        assert int(reply["message_id"]) == rig.mid
        rig.last = data
        outcome = rig.run(chan=a.fileno(), budget=5)  # the request alone
        assert outcome.then == "wait" and outcome.ticks == 0
    finally:
        a.close()
        b.close()


def test_an_error_on_the_robots_socket_hands_back_to_pythons_receive(rig: Rig) -> None:
    port = rig.robot.getsockname()
    rig.robot.close()  # the robot is gone: the next datagram sent to it is refused
    rig.client.send(b"\0" * 8)
    time.sleep(0.05)
    outcome = rig.run(wait_ms=200)
    assert outcome.then == "tick" and outcome.ticks == 0
    with pytest.raises(OSError):  # what the Python receive then reports
        rig.client.recv(4096)
    rig.robot = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)  # (for close())
    assert port


def test_silence_hands_back_to_pythons_receive(rig: Rig) -> None:
    outcome = rig.run(wait_ms=20)
    assert outcome.then == "tick" and outcome.ticks == 0


def test_queued_states_the_newest_is_answered_and_logged(rig: Rig) -> None:
    record, spans = LogRing.layout(rig.dialect.state_dtype, LOG_FIELDS)
    fd = anonymous_file(LogRing.nbytes(10, record))
    log = LogRing(fd, 10, record, spans)
    try:
        states = [rig.next_state() for _ in range(3)]
        for data in states:
            rig.robot.send(data)
        outcome = rig.run(log=log)
        assert outcome.ticks == 1
        reply = np.frombuffer(rig.robot.recv(4096), rig.dialect.command_dtype)[0]
        assert int(reply["message_id"]) == rig.mid  # the newest
        logged = log.snapshot(rig.block.header)
        assert len(logged) == 1 and int(rig.block.header[HEADER.LOG_COUNT]) == 1
        newest = np.frombuffer(states[-1], rig.dialect.state_dtype)[0]
        np.testing.assert_array_equal(logged["q"][0], newest["q"])
        assert rig.law.dt == pytest.approx(3e-3)  # the robot's clock: three ticks on
    finally:
        log.close()


def test_more_states_queued_than_one_receive_takes_the_newest_is_answered(rig: Rig) -> None:
    """Eleven datagrams queued (more than a receive takes at once: RECV_BATCH), the
    newest third from the end, a stray short datagram and stale ones after it: all are
    taken in one tick and the newest is answered, the queue left empty."""
    tick = fastloop.kernels()
    states = [rig.next_state() for _ in range(9)]
    newest = rig.mid
    queue = [*states[:-1], b"\x01\x02\x03", states[-1], states[0]]
    assert len(queue) > 2 * tick.RECV_BATCH
    queue[-3], queue[-2] = queue[-2], queue[-3]  # the newest before the stray one
    for data in queue:
        rig.robot.send(data)
    outcome = rig.run()
    assert outcome.ticks == 1
    reply = np.frombuffer(rig.robot.recv(4096), rig.dialect.command_dtype)[0]
    assert int(reply["message_id"]) == newest
    assert rig.law.dt == pytest.approx(9e-3)
    with pytest.raises(BlockingIOError):  # nothing left for the next tick
        rig.client.recv(4096)


STREAMED = ("JointTarget", "CartesianTarget")


def _streamed_target(kind: str, k: int) -> tuple[Any, ...]:
    """The target sent before tick ``k``: a small joint or end-effector offset from the
    start that changes with ``k // 100`` (the targets of one hundred ticks repeat)."""
    dq = np.array([0.03, -0.02, 0.02, 0.04, -0.03, 0.05, 0.04]) * (1 + k // 100)
    if kind == "JointTarget":
        return (np.asarray(START_POSE) + dq,)
    T = np.asarray(KIN.fk(START_POSE))
    p = T[:3, 3] + np.array([0.01, -0.02, 0.015]) * (1 + k // 100)
    return p, laws.quat_from_matrix(T.reshape(16, order="F"))


@pytest.mark.timeout(600)
@pytest.mark.parametrize("version", [5, 10])
@pytest.mark.parametrize("kind", STREAMED)
def test_compiled_streamed_ticks_send_the_python_ticks_commands(kind: str, version: int) -> None:
    """Targets every 20 ms (50 Hz), then every 40 ms (25 Hz), repeated, then silence until
    the timeout: only the ticks with news (a target, the timeout) are Python's; every
    command, the reference, the lag and stale equal the Python ticks' and are finite."""
    rig = Rig(version, kind)
    try:
        sent_at = [*range(1, 100, 20), *range(100, 260, 40)]
        handed_back, stale_at = [], 0
        for k in range(1, 420):
            if k in sent_at:
                target = _streamed_target(kind, k)
                rig.handle.set_target(*target)
                rig.ref.set_target(*target)
            data = rig.next_state()
            rig.robot.send(data)
            outcome = rig.run()
            expected = rig.reference(data, 1e-3)
            if rig.ref._stale and not stale_at:
                stale_at = k
            if outcome.then == "pending":
                handed_back.append(k)
                assert outcome.pending == data
                sent = rig.python_tick(data, 1e-3)
            else:
                assert outcome.then == "wait" and outcome.ticks == 1
                reply = rig.robot.recv(4096)
                rec = np.frombuffer(reply, rig.dialect.command_dtype)[0]
                assert int(rec["message_id"]) == rig.mid
                sent = np.frombuffer(rec["tau_J_d"].tobytes(), np.float64)
                rig.last = data
            assert np.isfinite(sent).all()
            np.testing.assert_allclose(sent, expected, rtol=0.0, atol=1e-9)
            rig.ref.published()
            n = len(rig.ref._out)
            np.testing.assert_allclose(rig.block.read_outputs(n), rig.ref._out, rtol=0.0,
                                       atol=1e-9)  # fmt: skip
        assert stale_at in (sent_at[-1] + 100, sent_at[-1] + 101)  # (timeout: 0.1 s)
        assert handed_back == [*sent_at, stale_at]
        assert rig.handle.stale and rig.ref.stale
        assert rig.law.t == pytest.approx(rig.ref.t)
    finally:
        rig.close()


@pytest.mark.parametrize("version", [5, 10])
@pytest.mark.parametrize("kind", STREAMED)
def test_compiled_streamed_ticks_send_no_non_finite_torques(kind: str, version: int) -> None:
    """A state that makes a streamed target's torques non-finite, while its generator
    moves toward a new target: the compiled tick raises and sends nothing."""
    rig = Rig(version, kind)
    try:
        rig.handle.set_target(*_streamed_target(kind, 150))
        data = rig.next_state()
        rig.robot.send(data)
        assert rig.run().then == "pending"  # the new target: ruckig, in Python
        rig.python_tick(data, 1e-3)
        rig.mid += 1
        r = np.frombuffer(_state(rig.dialect, rig.mid, rig.q, np.zeros(7), np.zeros(7)),
                          rig.dialect.state_dtype).copy()  # fmt: skip
        r["q"][0, 3] = np.nan
        rig.robot.send(r.tobytes())
        with pytest.raises(ControlException, match="non-finite torques"):
            rig.run()
        rig.robot.settimeout(0.05)
        with pytest.raises(TimeoutError):
            rig.robot.recv(4096)
    finally:
        rig.close()


@pytest.mark.parametrize("version", [5, 10])
def test_force_past_its_threshold_is_handed_back_and_raises_as_the_python_tick(
    version: int,
) -> None:
    """A Force controller whose threshold the user lowers (filtered toward it) while the arm
    wanders: the compiled ticks answer every state until the one at which the Python tick
    raises, which they hand back unanswered, the law untouched; its Python step then
    raises the same error."""
    rig = Rig(version, "Force")
    try:
        rig.handle.set_threshold(0.012)
        rig.ref.set_threshold(0.012)
        answered = 0
        for _ in range(2000):
            data = rig.next_state()
            rig.robot.send(data)
            before = rig.law._law.copy()
            outcome = rig.run()
            try:
                rig.reference(data, 1e-3)
            except ControlException as exc:
                expected = str(exc)
                break
            assert outcome.then == "wait" and outcome.ticks == 1
            rig.robot.recv(4096)
            rig.last = data
            answered += 1
        else:
            pytest.fail("the arm never moved past the threshold")
        assert answered > 20  # (the threshold was filtered down to where the arm is)
        assert outcome.then == "pending" and outcome.pending == data and outcome.ticks == 0
        np.testing.assert_array_equal(rig.law._law, before)  # nothing changed
        with pytest.raises(ControlException, match="distance threshold exceeded") as caught:
            rig.python_tick(data, 1e-3)
        assert str(caught.value) == expected
        rig.robot.settimeout(0.05)
        with pytest.raises(TimeoutError):  # nothing sent for it
            rig.robot.recv(4096)
    finally:
        rig.close()


def _pressing(k: int) -> np.ndarray:
    """The external wrench at tick ``k``: the force's z down 0.1 N a tick from 0 (past
    -5 N at tick 51), x and y about it, a moment."""
    return np.array([0.3 * np.sin(k / 7.0), 0.2, -0.1 * k, 0.01 * k, 0.0, -0.5])


GUARDS = {
    "force": (conditions.Force.z < -5.0) | (Elapsed > 10.0),
    "time": (Elapsed > 0.04) & ~(conditions.Force.z > 0.0),
    "norm": conditions.Force.norm > 3.3,
    "field": (Field("dq").norm > 1e3) | (Field("m_load") > 0.25),  # the load from tick 70
    "errors": Errors & (Distance > 0.0),  # an error flag from tick 60
}


@pytest.mark.parametrize("version", [5, 10])
@pytest.mark.parametrize("guard", GUARDS)
@pytest.mark.parametrize("kind", ["JointMove", "PoseMove"])
def test_compiled_guarded_moves_hand_back_the_tick_their_condition_holds(
    kind: str, guard: str, version: int
) -> None:
    """A guarded move runs compiled until its condition holds: that tick is handed back
    unanswered, and the Python tick decides there as the reference does on every tick
    (the same tick, the same condition and time, the same torques before and on it)."""
    rig = Rig(version, kind)
    rig.law.until = rig.ref.until = GUARDS[guard]
    try:
        handed_back = []
        for k in range(1, 150):
            data = rig.next_state(force=_pressing(k), load=0.5 if k >= 70 else 0.0,
                                  error=3 if k >= 60 else None)  # fmt: skip
            rig.robot.send(data)
            outcome = rig.run()
            expected = rig.reference(data, 1e-3)
            if outcome.then == "pending":
                handed_back.append(k)
                assert outcome.pending == data and outcome.ticks == 0
                sent = rig.python_tick(data, 1e-3)
            else:
                assert outcome.then == "wait" and outcome.ticks == 1
                rec = np.frombuffer(rig.robot.recv(4096), rig.dialect.command_dtype)[0]
                sent = np.frombuffer(rec["tau_J_d"].tobytes(), np.float64)
                rig.last = data
            np.testing.assert_allclose(sent, expected, rtol=0.0, atol=1e-9)
            assert rig.law.condition == rig.ref.condition
            if rig.ref.condition:
                break
        fired = rig.ref.condition_time
        assert rig.ref.condition and rig.law.condition_time == fired
        assert handed_back[-1] == round(fired * 1e3)  # the tick it held on was Python's
        assert set(handed_back[:-1]) <= {70}  # besides it, the load's (the model's) only
        assert len(handed_back) < 3 and handed_back[-1] > 30  # the others ran compiled
        assert rig.law.stopping and rig.law.compiled(TickState(rig.dialect, data), MODEL) is None
    finally:
        rig.close()


@pytest.mark.parametrize(("kind", "field"),
                         [("AppliedForce", "q"), ("Force", "q"), ("Force", "tau_J")])  # fmt: skip
def test_the_force_laws_send_no_non_finite_torques(kind: str, field: str) -> None:
    """A NaN in the joint positions (either law) or the measured torques (Force's): the
    compiled tick raises as the Python tick does (its torques are NaN) and sends nothing."""
    rig = Rig(10, kind)
    try:
        rig.mid += 1
        r = np.frombuffer(_state(rig.dialect, rig.mid, rig.q, np.zeros(7), np.zeros(7)),
                          rig.dialect.state_dtype).copy()  # fmt: skip
        r[field][0, 3] = np.nan
        data = r.tobytes()
        with pytest.raises(ControlException, match="non-finite torques"):
            rig.reference(data, 1e-3)  # the Python tick
        rig.robot.send(data)
        with pytest.raises(ControlException, match="non-finite torques"):
            rig.run()
        rig.robot.settimeout(0.05)
        with pytest.raises(TimeoutError):
            rig.robot.recv(4096)
    finally:
        rig.close()


@pytest.mark.parametrize("kind", ["JointMove", "PoseMove"])
def test_a_guarded_move_on_a_function_of_the_state_runs_its_ticks_in_python(kind: str) -> None:
    rig = Rig(5, kind)
    try:
        rig.law.until = when(lambda state: state.O_F_ext_hat_K[2] < -5.0)
        assert rig.law.compiled(TickState(rig.dialect, rig.last), MODEL) is None
        rig.law.until = conditions.Force.z < -5.0
        rig.law._program_made = False  # (made at the first ask: asked again for the test)
        assert rig.law.compiled(TickState(rig.dialect, rig.last), MODEL) is not None
    finally:
        rig.close()


@pytest.mark.parametrize("kind", ["JointMove", "PoseMove"])
def test_a_guarded_moves_compiled_ticks_take_the_types_the_warm_up_compiled(kind: str) -> None:
    """The warm-up runs unguarded moves (rt.fastloop.warm_up): a guarded one's arrays
    (its program and stack among them) have the same numba types, so its first compiled
    tick compiles nothing."""
    import numba

    rig = Rig(5, kind)
    try:
        state = TickState(rig.dialect, rig.last)
        plain = rig.law.compiled(state, MODEL)
        rig.law.until = (conditions.Force.z < -5.0) | ~(Elapsed < 3.0)
        guarded = rig.law.compiled(state, MODEL)
        assert plain is not None and guarded is not None
        assert guarded.arrays[-2].shape[0] == 4  # (its program: 2 comparisons, ~, |)
        types = [numba.typeof(a) for a in plain.arrays]
        assert [numba.typeof(a) for a in guarded.arrays] == types
    finally:
        rig.close()


def _settling_states(rig: Rig, ending: str) -> Iterator[bytes]:
    """States of an arm that follows the move's plan (off it by 1 mrad a joint, 10 for a
    Cartesian move, whose goal is looser), then, past its end (tick 200), comes to rest
    at its goal (``ending`` "rest": its offset decays in 15 ms) or stays off it
    (``ending`` "timeout")."""
    plan = rig.ref
    joints = isinstance(plan, JointMove)
    if not joints:  # the joints from the start to a configuration at the plan's goal
        T = np.eye(4)
        T[:3, :3] = rotation.to_matrix(plan.quat[-1])
        T[:3, 3] = plan.p[-1]
        q_goal = np.asarray(KIN.ik(T, START_POSE, START_POSE[6]))
        assert np.isfinite(q_goal).all()
    for k in range(1, 1300):
        j = min(k, plan.last)
        if joints:
            at, rate = plan.q[j], plan.dq[j] if k <= plan.last else np.zeros(7)
        else:
            at = np.asarray(START_POSE) + (j / plan.last) * (q_goal - START_POSE)
            rate = np.zeros(7)
        off, off_rate = (1e-3 if joints else 1e-2), 0.0
        if k > plan.last and ending == "rest":
            off *= np.exp(-(k - plan.last) / 15.0)
            off_rate = -off / 15e-3
        rig.mid += 1
        yield _state(rig.dialect, rig.mid, at + off, rate + off_rate, np.zeros(7))


@pytest.mark.parametrize("version", [5, 10])
@pytest.mark.parametrize("ending", ["rest", "timeout"])
@pytest.mark.parametrize("kind", ["JointMove", "PoseMove"])
def test_a_moves_settling_runs_compiled_and_hands_back_the_tick_it_ends_on(
    kind: str, ending: str, version: int
) -> None:
    """Past its trajectory's end a move settles compiled (its integral and friction push
    as its Python step computes them, to 1e-9) and hands back unanswered the one state it
    ends on, at rest at its goal or at the settling's time out, where the Python tick
    finishes it as the reference does."""
    rig = Rig(version, kind)
    try:
        handed_back, finished = [], None
        for k, data in enumerate(_settling_states(rig, ending), start=1):
            rig.robot.send(data)
            outcome = rig.run()
            expected = rig.reference(data, 1e-3)
            if outcome.then == "pending":
                handed_back.append(k)
                assert outcome.pending == data and outcome.ticks == 0
                sent = rig.python_tick(data, 1e-3)
            else:
                assert outcome.then == "wait" and outcome.ticks == 1
                rec = np.frombuffer(rig.robot.recv(4096), rig.dialect.command_dtype)[0]
                sent = np.frombuffer(rec["tau_J_d"].tobytes(), np.float64)
                rig.last = data
                np.testing.assert_allclose(rig.fast.tau, rig.ref_tau, rtol=0.0, atol=1e-9)
            np.testing.assert_allclose(sent, expected, rtol=0.0, atol=1e-9)
            state = TickState(rig.dialect, data)
            if rig.ref.finished(state):
                assert rig.law.finished(state)
                finished = k
                break
            assert not rig.law.finished(state)
        assert finished is not None and handed_back == [finished]  # the settling ran compiled
        past = finished - rig.ref.last  # [ticks] after the trajectory's end
        # (the time out: 1 s of the robot's clock, summed in 1 ms steps)
        assert (20 < past < 150) if ending == "rest" else past in (1000, 1001), past
        np.testing.assert_allclose(rig.law.integral, rig.ref.integral, rtol=0.0, atol=1e-12)
        assert np.abs(rig.ref.integral).max() > 0.0  # (the integral took part)
        assert rig.law.result(state) == rig.ref.result(state)
    finally:
        rig.close()


@pytest.mark.parametrize("version", [5, 10])
@pytest.mark.parametrize("then", ["settle", "cancel"])
@pytest.mark.parametrize("kind", ["JointMove", "PoseMove"])
def test_a_moves_lead_in_and_stop_run_compiled(kind: str, then: str, version: int) -> None:
    """A move that leads in from where the arm is (0.02 rad a joint off its plan's start)
    runs its online generator compiled, with the Python step's torques (to 1e-9) and
    reference, and hands Python the ticks only it can do: the first (ruckig calculates),
    the one its generator reaches its target on, and the one it ends on; cancelled on the
    way, its stop too: the tick of the cancel's ruckig step, the one its generator comes
    to rest on. (The joint move's arm follows its reference and comes to rest at the goal;
    the Cartesian move's stays where it was, at rest: it times out settling.)"""
    rig = Rig(version, kind)
    try:
        start = TickState(rig.dialect, _state(rig.dialect, rig.mid, rig.q + 0.02, np.zeros(7),
                                              np.zeros(7)))  # fmt: skip
        rig.law.handover(None, start, MODEL)
        rig.ref.handover(None, start, MODEL)
        python, pending, finished = [], [], None
        for k in range(1, 2000):
            if then == "cancel" and k == 150:
                rig.law.cancel("stopped")
                rig.ref.cancel("stopped")
            past = max(0.0, rig.ref.t - rig.ref.t_end)  # the offset settles to the goal
            rig.mid += 1
            if kind == "JointMove":
                ref_q, ref_dq = rig.ref.ref[0], rig.ref.ref[1]
                q, dq = ref_q + 5e-4 * np.exp(-past / 15e-3), ref_dq
            else:
                q, dq = start.q, np.zeros(7)
            data = _state(rig.dialect, rig.mid, q, dq, np.zeros(7))
            compiled = rig.law.compiled(TickState(rig.dialect, rig.last), MODEL)
            expected = rig.reference(data, 1e-3)
            rig.ref.published()  # (the loop's, after the command: a lead-in's limits refined)
            if compiled is None:
                python.append(k)
                sent = rig.python_tick(data, 1e-3)
            else:
                rig.robot.send(data)
                outcome = rig.fast.run(rig.law, compiled, rig.last, chan=-1, requests_taken=0,
                                       log=None, budget=1, wait_ms=1000)  # fmt: skip
                if outcome.then == "pending":
                    pending.append(k)
                    sent = rig.python_tick(data, 1e-3)
                else:
                    assert outcome.then == "wait" and outcome.ticks == 1
                    rec = np.frombuffer(rig.robot.recv(4096), rig.dialect.command_dtype)[0]
                    sent = np.frombuffer(rec["tau_J_d"].tobytes(), np.float64)
                    rig.last = data
                    np.testing.assert_allclose(rig.fast.tau, rig.ref_tau, rtol=0.0, atol=1e-9)
            np.testing.assert_allclose(sent, expected, rtol=0.0, atol=1e-9)
            for a, b in zip(rig.law.ref, rig.ref.ref, strict=True):
                np.testing.assert_allclose(a, b, rtol=0.0, atol=1e-12)
            state = TickState(rig.dialect, data)
            if rig.ref.finished(state):
                assert rig.law.finished(state)
                finished = k
                break
            assert not rig.law.finished(state)
        assert finished is not None
        # ruckig's steps: the first, a Cartesian lead-in's again on its refined limits (the
        # tick after the first command: PoseMove.published), the cancel's
        ruckig = [1] if kind == "JointMove" else [1, 2]
        assert python == ruckig + ([150] if then == "cancel" else [])
        assert len(pending) == 2 and pending[-1] == finished  # the lead's end, the move's
        assert finished > 150
        assert rig.law.result(state) == rig.ref.result(state)
    finally:
        rig.close()
