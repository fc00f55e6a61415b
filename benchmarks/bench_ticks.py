"""The control loop's compiled ticks (``panda_py.rt._tick``) in process: what one tick of
each built-in law costs, from a state datagram waiting on the robot's socket to its
command sent, the state published to shared memory and the outputs written.

Run: ``python benchmarks/bench_ticks.py [--n 5000] [--repeat 3]``.

A "robot" socket on loopback sends a state (random joints near the start pose, protocol
v10), the loop kernel runs one tick on it (``FastTicks.run`` with a budget of one), the
robot takes the command. Timed per tick: the ``run`` call; printed beside it, the same call
when it returns at once (no state, no wait: the Python call's own cost), and the tick's
cost without it (the difference of the medians), median, p99 and worst [us]. Against the
law's Python ``step`` alone on the same states (``law.tick`` + ``law.step`` + the
finishing, what the loop ran per tick before), which includes no receive, send or
publishing. The moves run twice: as they are, and guarded (``until=``, a condition that
never holds here: before the conditions were compiled, a guarded move's every tick was
that Python step). The machine is a noisy 2-core VM: run it more than once.
"""

from __future__ import annotations

import argparse
import dataclasses
import os
import socket
import time
from typing import Any

import numpy as np

from panda_py import conditions, fci, kinematics
from panda_py.conditions import Elapsed, Torque
from panda_py.controllers import (
    AppliedForce,
    AppliedTorque,
    CartesianImpedance,
    CartesianTarget,
    Force,
    IntegratedVelocity,
    JointPosition,
    JointTarget,
    laws,
)
from panda_py.controllers.finalize import Finalize
from panda_py.controllers.model import ControlModel
from panda_py.controllers.moves import tracker_for
from panda_py.controllers.warmup import example_plans
from panda_py.libfranka import RobotMode, TorqueIO
from panda_py.libfranka.state import TickState
from panda_py.robots.params import START_POSE, get_robot
from panda_py.rt import fastloop
from panda_py.rt.shm import SharedBlock

VERSION = 10
# a guarded move's condition (the guarded moves' rows): two comparisons and a norm
GUARD = (conditions.Force.z < -5.0) | (Torque.norm > 50.0) | (Elapsed > 1e3)
MG, CTRL, MOVE = 5, 2, int(RobotMode.kMove.value)


def _stats(values: Any) -> tuple[float, float, float]:
    a = np.asarray(values) * 1e6
    return float(np.median(a)), float(np.percentile(a, 99)), float(a.max())


def _states(n: int, spec: Any) -> list[bytes]:
    dialect = fci.dialect(VERSION)
    kin = kinematics.get_kinematics(spec)
    rng = np.random.default_rng(0)
    out = []
    for i in range(n):
        r = np.zeros((), dialect.state_dtype)
        q = np.asarray(START_POSE) + rng.normal(0.0, 0.01, 7)
        r["message_id"] = 1000 + i
        r["motion_generator_mode"], r["controller_mode"], r["robot_mode"] = MG, CTRL, MOVE
        r["q"], r["dq"], r["q_d"] = q, rng.normal(0.0, 0.05, 7), q
        r["O_T_EE"] = kin.fk(q).reshape(16, order="F")
        r["F_T_EE"] = r["EE_T_K"] = np.eye(4).reshape(16)
        out.append(r.tobytes())
    return out


def _laws(state: Any, model: Any, spec: Any) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for cls in (CartesianImpedance, JointPosition, IntegratedVelocity, AppliedTorque):
        law = cls()
        law.start(state, model)
        out[cls.__name__] = law
    # the force laws pushing (Force: a threshold the states' spread stays within)
    applied = AppliedForce(damping=np.full(7, 2.0), filter_coeff=0.1)
    applied.start(state, model)
    applied.set_control([0.0, 0.0, 5.0, 0.0, 0.0, 0.0])
    out["AppliedForce"] = applied
    force = Force(threshold=1.0)
    force.start(state, model)
    force.set_control([0.0, 0.0, -5.0])
    out["Force"] = force
    # the streamed targets toward a target set before their first tick (no timeout: no
    # news afterwards), their generators moving for the first seconds, then at rest
    joint_target = JointTarget(timeout=None)
    joint_target.start(state, model)
    joint_target.set_target(np.asarray(START_POSE) + 0.3)
    out["JointTarget"] = joint_target
    pose_target = CartesianTarget(timeout=None)
    pose_target.start(state, model)
    pose_target.set_target(
        state.O_T_EE[12:15] + np.array([0.0, 0.1, -0.1]), laws.quat_from_matrix(state.O_T_EE)
    )
    out["CartesianTarget"] = pose_target
    joint, pose = example_plans(state, spec)
    # a long plan that holds the arm (the moves' plan-following phase throughout)
    for name, plan in (("move_to_joint_position", joint), ("move_to_pose", pose)):
        fields = {}
        for f in dataclasses.fields(plan):
            v = getattr(plan, f.name)
            if isinstance(v, np.ndarray) and v.ndim == 2 and v.shape[0] == 2:
                v = np.repeat(v[:1], 200000, axis=0)
            fields[f.name] = v
        out[name] = tracker_for(type(plan)(**fields))
        # the same, guarded: a condition that never holds here, evaluated every tick
        guarded = tracker_for(type(plan)(**fields))
        guarded.until = GUARD
        out[f"{name} until"] = guarded
    return out


def run(n: int, repeat: int) -> None:
    spec = get_robot("fer")
    model = ControlModel(spec)
    states = _states(n + 1, spec)
    dialect = fci.dialect(VERSION)
    first = TickState(dialect, states[0])
    print(f"compiled ticks in process, protocol v{VERSION}, {n} ticks each, {repeat} repeats [us]")
    print(f"{'law':<30}{'run() median':>13}{'p99':>8}{'worst':>9}{'tick alone':>12}"
          f"{'Python step median':>20}")  # fmt: skip
    for rep in range(repeat):
        robot = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        robot.bind(("127.0.0.1", 0))
        client = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        client.bind(("127.0.0.1", 0))
        client.connect(robot.getsockname())
        robot.connect(client.getsockname())
        client.setblocking(False)
        block, fd = SharedBlock.create()
        os.close(fd)
        try:
            for name, law in _laws(first, model, spec).items():
                fin = Finalize(spec)
                if hasattr(law, "open_slot"):
                    law.open_slot(block)
                law.tick(0.0)
                law.step(first, model)
                io = dataclasses.replace(TorqueIO.unconnected(VERSION), udp=client.fileno(),
                                         last_data=states[0], modes=(MG, CTRL, MOVE))  # fmt: skip
                fast = fastloop.FastTicks(io, block, fin, None)
                last = states[0]
                compiled = law.compiled(TickState(dialect, last), model)
                assert compiled is not None, name
                empty, ticks = [], []
                for i in range(n):
                    t0 = time.perf_counter()
                    fast.run(law, compiled, last, chan=-1, requests_taken=0, log=None,
                             budget=1, wait_ms=0)  # fmt: skip
                    empty.append(time.perf_counter() - t0)
                    robot.send(states[i + 1])
                    t0 = time.perf_counter()
                    out = fast.run(law, compiled, last, chan=-1, requests_taken=0, log=None,
                                   budget=1, wait_ms=100)  # fmt: skip
                    ticks.append(time.perf_counter() - t0)
                    assert out.ticks == 1, (name, out)
                    robot.recv(4096)
                    last = states[i + 1]
                # the law's Python tick on the same states (fresh TickStates, as the loop)
                py = []
                for i in range(min(n, 2000)):
                    st = TickState(dialect, states[i + 1])
                    t0 = time.perf_counter()
                    law.tick(1e-3)
                    fin(law.step(st, model), st)
                    py.append(time.perf_counter() - t0)
                med, p99, worst = _stats(ticks)
                alone = med - _stats(empty)[0]
                print(f"{name:<30}{med:13.1f}{p99:8.1f}{worst:9.1f}{alone:12.1f}"
                      f"{_stats(py)[0]:20.1f}   (repeat {rep + 1})")  # fmt: skip
                del fast
        finally:
            block.close()
            robot.close()
            client.close()


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--n", type=int, default=5000)
    p.add_argument("--repeat", type=int, default=3)
    a = p.parse_args()
    run(a.n, a.repeat)


if __name__ == "__main__":
    main()
