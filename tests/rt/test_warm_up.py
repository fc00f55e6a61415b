"""The control process's warm-up compiles (or loads) every numba kernel its laws call with
the argument types the loop hands them, so no tick stops for the compiler: after
``connect``, running each controller and each move as the loop runs them (inputs pickled
from the user's process, a new read-only state each tick) adds no kernel signature.

A signature missed here stalled a real tick for 7-9 ms (a move's nullspace pose came
writable from the user's plan, the warm-up's read-only from its state)."""

from __future__ import annotations

import os
import socket
from typing import Any

import numba
import numpy as np
import pytest

from panda_py import controllers as c
from panda_py.controllers.moves import tracker_for
from panda_py.controllers.plans import JointPlan, PosePlan
from panda_py.libfranka.state import TickState
from panda_py.libfranka.types import RealtimeConfig
from panda_py.motion.online import OnlineLimits
from panda_py.rt import requests as rq
from panda_py.rt.channel import Channel
from panda_py.rt.child import ControlServer
from panda_py.rt.shm import SharedBlock

pytestmark = pytest.mark.timeout(120)


def _signatures() -> dict[str, set[str]]:
    """Every compiled signature of every numba kernel panda_py has loaded."""
    import sys

    found: dict[str, set[str]] = {}
    for name, module in list(sys.modules.items()):
        if not name.startswith("panda_py") or module is None:
            continue
        for attr, value in list(vars(module).items()):
            if isinstance(value, numba.core.registry.CPUDispatcher):
                found[f"{name}.{attr}"] = {str(s) for s in value.signatures}
    return found


def _sent(obj: Any) -> Any:
    """``obj`` as the control process receives it from the user's (the channel: pickle 5,
    large arrays out of band, read-only on arrival)."""
    a, b = socket.socketpair()
    with a, b:
        Channel(a).send(obj)
        return Channel(b).recv()[0]


def _run(server: ControlServer, law: Any, ticks: int = 5) -> None:
    """Ticks of ``law`` as ``ControlServer._run`` runs them, each on a fresh state."""
    robot, model = server.robot, server.model
    assert robot is not None and model is not None
    for k in range(ticks):
        state = robot.decode_state(robot.receive_raw_state(), TickState)
        if k == 0:
            start = getattr(law, "start", None)
            if start is not None and not hasattr(law, "plan"):
                start(state, model)
        law.tick(1e-3)
        server.finalize(law.step(state, model), state)  # type: ignore[misc]
        law.published()


@pytest.mark.parametrize("version", [5, 10])
def test_no_law_compiles_anything_after_the_warm_up(
    sim_for_version, version: int, monkeypatch
) -> None:
    from panda_py.rt import child

    # the test's own thread must keep its scheduling (pytest's processes inherit it)
    monkeypatch.setattr(child, "set_current_thread_to_highest_priority", lambda: None)
    sim = sim_for_version(version)
    block, fd = SharedBlock.create()
    os.close(fd)
    server = ControlServer(None, block, os.getpid())  # type: ignore[arg-type]
    try:
        server.connect(rq.Connect(sim.host, int(RealtimeConfig.kIgnore), 5.0))
        before = _signatures()
        robot, model, spec = server.robot, server.model, server.limits
        assert robot is not None and model is not None and spec is not None
        for cls in (c.CartesianImpedance, c.JointPosition, c.IntegratedVelocity,
                    c.AppliedTorque, c.AppliedForce, c.Force, c.CartesianTarget,
                    c.JointTarget):  # fmt: skip
            _run(server, _sent(cls()))  # as sent by the user
        # the moves, with plans as the user's process sends them (writable arrays)
        state = robot.decode_state(robot.receive_raw_state(), TickState)
        q = np.array(state.q)
        z, six = np.zeros((2, 7)), np.zeros((2, 6))
        joint = JointPlan(np.array([q, q]), z, z, np.full(7, 600.0), np.full(7, 50.0),
                          1e-3, 1e-2, OnlineLimits.joints(spec, 1.0))  # fmt: skip
        p = np.array([state.O_T_EE[12:15]] * 2)
        quat = np.array([c.laws.quat_from_matrix(state.O_T_EE)] * 2)
        pose = PosePlan(p, quat, six, six, q, np.diag([600.0] * 3 + [30.0] * 3), 1.0, 10.0,
                        1e-3, 1e-2, 5e-2, OnlineLimits.cartesian(spec, 1.0))  # fmt: skip
        for plan in (joint, pose):
            law = tracker_for(_sent(plan))
            _run(server, law)
            other = tracker_for(_sent(pose if plan is joint else joint))
            other.handover(law, robot.decode_state(robot.receive_raw_state(), TickState), model)
            _run(server, other)
        after = _signatures()
        new = {k: sorted(v - before.get(k, set())) for k, v in after.items()}
        assert not {k: v for k, v in new.items() if v}, "compiled after the warm-up"
    finally:
        if server.robot is not None:
            server.robot.close()
        block.close()


@pytest.mark.parametrize("version", [5, 10])
def test_no_compiled_tick_compiles_anything_after_the_warm_up(
    sim_for_version, version: int, monkeypatch
) -> None:
    """Every built-in controller's compiled ticks (rt.fastloop, the loop kernels its
    ``compiled`` names: the force laws' too), sent by the user and run as the loop runs
    them, find their kernels compiled by the warm-up ``connect`` ran."""
    from panda_py.libfranka import TorqueIO
    from panda_py.rt import child, fastloop

    if fastloop.kernels() is None:
        pytest.skip("no compiled ticks here (numba missing or PANDA_PY_NO_JIT=1)")
    monkeypatch.setattr(child, "set_current_thread_to_highest_priority", lambda: None)
    sim = sim_for_version(version)
    block, fd = SharedBlock.create()
    os.close(fd)
    server = ControlServer(None, block, os.getpid())  # type: ignore[arg-type]
    try:
        server.connect(rq.Connect(sim.host, int(RealtimeConfig.kIgnore), 5.0))
        before = _signatures()
        robot, model, finalize = server.robot, server.model, server.finalize
        assert robot is not None and model is not None and finalize is not None
        fast = fastloop.FastTicks(TorqueIO.unconnected(robot.server_version()), block,
                                  finalize, None)  # fmt: skip
        names = []
        for cls in (c.CartesianImpedance, c.JointPosition, c.IntegratedVelocity,
                    c.AppliedTorque, c.AppliedForce, c.Force):  # fmt: skip
            law = _sent(cls())
            state = robot.decode_state(robot.receive_raw_state(), TickState)
            law.start(state, model)
            law.open_slot(block)
            law.tick(0.0)
            law.step(state, model)
            compiled = law.compiled(state, model)
            assert compiled is not None, cls.__name__
            names.append(compiled.kernel)
            fast.run(law, compiled, state.raw, chan=-1, requests_taken=0, log=None, budget=1,
                     wait_ms=0)  # fmt: skip
        finalize.reset()
        assert "applied_force_ticks" in names and "force_ticks" in names
        after = _signatures()
        new = {k: sorted(v - before.get(k, set())) for k, v in after.items()}
        assert not {k: v for k, v in new.items() if v}, "compiled after the warm-up"
    finally:
        if server.robot is not None:
            server.robot.close()
        block.close()
