"""The 1 kHz path's pieces: struct layouts equal the fci dtypes, the lazy RobotState, the
command value cache, the state phase of the hybrid wait, the cache warm-up rehearsal."""

from __future__ import annotations

import types

import numpy as np
import pytest

from panda_py import fci
from panda_py import libfranka as lf
from panda_py.libfranka import _network, _wire
from panda_py.libfranka import limits as lm
from panda_py.libfranka._commander import Commander
from panda_py.libfranka._warm import rehearsal

VERSIONS = sorted(fci.SUPPORTED_VERSIONS)


def _random_state(d: fci.Dialect, rng: np.random.Generator) -> np.ndarray:
    state = d.new_state()
    for name in d.state_dtype.names or ():
        sub = d.state_dtype.fields[name][0]
        if sub.base.kind == "f":
            state[name] = rng.normal(0, 3, sub.shape)
        else:
            state[name] = rng.integers(0, 2 if sub.base.kind == "b" else 200, sub.shape)
    state["message_id"] = rng.integers(0, 2**40)
    return state


@pytest.mark.parametrize("version", VERSIONS)
def test_struct_blocks_read_and_write_what_the_dtypes_say(version):
    rng = np.random.default_rng(version)
    d = fci.dialect(version)
    w = _wire.layout(d)
    state = _random_state(d, rng)
    data = d.encode_state(state)
    rec = d.decode_state(data)
    assert w.header.unpack(data) == tuple(
        int(rec[n]) for n in ("message_id", "motion_generator_mode", "controller_mode",
                              "robot_mode")
    )  # fmt: skip
    flat = lambda *names: [x for n in names for x in rec[n].reshape(-1).tolist()]  # noqa: E731
    assert list(w.joint.unpack(data)) == flat("q_d", "dq_d", "ddq_d")
    assert list(w.pose.unpack(data)) == flat("O_T_EE_c", "O_dP_EE_c", "O_ddP_EE_c")
    assert list(w.elbow.unpack(data)) == flat("elbow_c", "delbow_c", "ddelbow_c")
    assert list(w.tau_J_d.unpack(data)) == flat("tau_J_d")
    buffer = bytearray(w.command_size)
    w.c_message_id.pack(buffer, 77)
    w.c_q.pack(buffer, *range(7))
    w.c_pose.pack(buffer, *range(16))
    w.c_elbow.pack(buffer, 0.5, -1.0, True)
    w.c_tau.pack(buffer, *range(10, 17))
    cmd = d.decode_command(bytes(buffer))
    assert int(cmd["message_id"]) == 77
    assert cmd["q_c"].tolist() == list(range(7))
    assert cmd["O_T_EE_c"].tolist() == list(range(16))
    assert cmd["elbow_c"].tolist() == [0.5, -1.0] and bool(cmd["valid_elbow"])
    assert cmd["tau_J_d"].tolist() == list(range(10, 17))


@pytest.mark.parametrize("version", VERSIONS)
def test_robot_state_reads_every_field_from_the_bytes(version):
    rng = np.random.default_rng(100 + version)
    d = fci.dialect(version)
    state = _random_state(d, rng)
    data = d.encode_state(state)
    rec = d.decode_state(data)
    s = lf.RobotState(d, data)
    for name in ("O_T_EE", "q", "dq", "tau_J_d", "O_T_EE_c", "elbow", "theta", "dtheta"):
        value = getattr(s, name)
        assert value.dtype == np.float64 and value.flags.writeable
        np.testing.assert_array_equal(value, rec[name])
    assert s.message_id == int(rec["message_id"])
    assert s.m_ee == float(rec["m_ee"])
    if d.has_accelerometers:
        assert s.accelerometer_top.shape == (6, 3)
        np.testing.assert_array_equal(s.accelerometer_top, rec["accelerometer_top"])
    # a record (as before) gives the same state; a short datagram is refused
    np.testing.assert_array_equal(lf.RobotState(d, state).q, s.q)
    with pytest.raises(ValueError, match="bytes"):
        lf.RobotState(d, bytearray(10))
    s.q[0] = 1e9  # each read is a fresh copy
    assert s.q[0] == rec["q"][0]


@pytest.mark.parametrize("version", VERSIONS)
def test_a_tick_state_reads_every_array_field_as_the_robot_state_does(version):
    from panda_py.libfranka.state import TickState

    rng = np.random.default_rng(200 + version)
    d = fci.dialect(version)
    data = d.encode_state(_random_state(d, rng))
    plain, tick = lf.RobotState(d, data), TickState(d, data)
    names = list(_wire.layout(d).arrays)
    assert len(_wire.layout(d).bulk_slices) >= len(names) - 2  # all but the error bits
    for name in reversed(names):  # any order: the first read decodes the run
        value = getattr(tick, name, None)
        if value is None or not isinstance(value, np.ndarray):
            continue  # (errors read as Errors)
        want = getattr(plain, name)
        assert value.dtype == np.float64 and value.shape == want.shape, name
        np.testing.assert_array_equal(value, want)
        assert not value.flags.writeable and getattr(tick, name) is value, name
    # raw_fields: neighbours read as one span, others joined, the same bytes either way
    load = ("m_ee", "I_ee", "F_x_Cee", "m_load", "I_load", "F_x_Cload")
    assert tick.raw_fields(load) == b"".join(tick.raw_fields((n,)) for n in load)
    assert tick.raw_fields(("q", "m_ee")) == tick.raw_fields(("q",)) + tick.raw_fields(("m_ee",))


def test_a_command_array_handed_out_is_read_again():
    d = fci.dialect(10)
    data = d.encode_state(d.new_state())
    c = Commander(d, lm.RateLimits.for_robot("fer"), False, 1000.0)
    out = lf.JointPositions(np.zeros(7))
    c.joint_positions(out, data)  # the constructor's checked list
    assert c.record["q_c"].tolist() == [0.0] * 7
    q = out.q  # handed out: may change in place from now on
    q[3] = 0.25
    c.joint_positions(out, data)
    assert c.record["q_c"][3] == 0.25
    out.q = np.full(7, 0.5)  # replaced
    c.joint_positions(out, data)
    assert c.record["q_c"].tolist() == [0.5] * 7
    out.q[0] = np.inf
    with pytest.raises(ValueError, match="infinite or NaN"):
        c.joint_positions(out, data)


class _Clock:
    def __init__(self) -> None:
        self.t = 100.0

    def __call__(self) -> float:
        return self.t


def test_the_state_phase_follows_early_states_and_slews_after_late_ones(monkeypatch):
    clock = _Clock()
    monkeypatch.setattr(_network, "_clock", clock)
    net = _network.Network.__new__(_network.Network)  # no sockets: the phase logic only
    net._udp_size = 1
    net._next_due = 0.0
    net._robot_ip, net._udp_peer, net.foreign_datagrams = "h", None, 0
    P = _network.STATE_PERIOD
    net._accept(b"x")  # the first state sets the phase
    assert net._next_due == pytest.approx(100.0 + P)
    clock.t = 100.0 + P + 60e-6  # late inside the spin: the phase moves by the slew only
    net._accept(b"x")
    assert net._next_due == pytest.approx(100.0 + 2 * P + _network.PHASE_SLEW)
    clock.t = 100.0 + 2 * P - 5e-6  # early: sets the phase at once
    net._accept(b"x")
    assert net._next_due == pytest.approx(clock.t + P)
    clock.t += P + 2e-3  # far later than the spin covers: reset
    net._accept(b"x")
    assert net._next_due == pytest.approx(clock.t + P)


@pytest.mark.parametrize("version", [5, 10])
def test_a_rehearsal_touches_nothing_the_loop_keeps(version):
    d = fci.dialect(version)
    state = _random_state(d, np.random.default_rng(3))
    state["O_T_EE_c"] = np.eye(4).reshape(16)
    data = d.encode_state(state)
    polls = []
    conn = types.SimpleNamespace(
        dialect=d,
        layout=_wire.layout(d),
        _header=_wire.layout(d).header.struct_.unpack_from,
        last_data=data,
        net=types.SimpleNamespace(pending=lambda: polls.append(1) or False),
    )
    limits = lm.RateLimits.for_robot("fer")
    scratch = Commander(d, limits, True, 100.0)
    kinds = (lf.Torques, lf.CartesianPose)
    rehearsal(conn, scratch, kinds)()
    assert conn.last_data == data and len(polls) == 2  # a poll before each conversion
    assert any(bytes(scratch.buffer))  # it did convert, into its own buffer
    conn.net.pending = lambda: True  # the state is here: stop before converting
    other = Commander(d, limits, True, 100.0)
    rehearsal(conn, other, kinds)()
    assert not any(bytes(other.buffer))
    conn.last_data = b"\x00"  # nonsense: ignored, a rehearsal has nothing to report
    rehearsal(conn, Commander(d, limits, True, 100.0), kinds)()
