"""How long after its trajectory each kind of move ends (issue 46): ``MoveResult.elapsed -
MoveResult.duration`` [ms] of random moves, and for a move that replaces a running one
how long it takes against the fastest trajectory our limits allow from the state it took
over in (the online generator at the move's limits, from the reference it took over).

Run: ``python benchmarks/bench_move_ends.py [--moves 20] [--robot fer|fr3|both]
[--kinds joint,pose,replace-joint,replace-pose]``.

Against a lockstep panda-sim through the public API (``Panda.move_to_joint_position``,
``move_to_pose``, ``asynchronous=True``), so the figures do not depend on the machine's
load. Moves: joint targets the start pose plus uniform +-0.3 rad a joint; poses the start
pose moved by uniform +-12 cm along each axis, its orientation kept (the first pose move
starts from where the joint moves left the arm: it turns back as well). Replacements: a
move of the same kind replaced after a uniform 100-400 ms by another random one; its
bound is the online generator's trajectory from the logged state (positions, velocities,
accelerations) at the hand-over to the goal, at the robot's limits at the move's speed
factor (the joints' for a joint move, unramped; the Cartesian ones, uncapped by the
joints', for a pose move: "vs fastest"), and for a pose move also the fastest of those
trajectories whose joint velocities and accelerations stay within the robot's joint limits
all the way (the limits scaled down until an arm following it through J^+ from the logged
joints fits: "vs in joints"), and within the share of them a Cartesian lead-in leaves
itself for its tracking's overshoot (``moves.JOINT_SHARE``), at the move's own limits
(their jerk ramped: ``planning.pose_online``; "vs our share"). A replacing pose move's
start is the replaced move's reference at the hand-over (its plan made again as
``Panda.move_to_pose`` makes it: planning is deterministic), not the logged arm. Prints
median, p99 and worst per kind (p99 of 20 moves is about the worst).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import panda_py
from panda_py import constants, kinematics
from panda_py.controllers import laws, moves
from panda_py.controllers.plans import PosePlan
from panda_py.motion import rotation as rot
from panda_py.motion.online import OnlineGenerator, OnlineLimits, OnlinePose
from panda_py.panda import planning
from panda_py.panda.move_args import pose_options
from panda_py.panda.plan_torques import load_of
from panda_py.robots.params import get_robot
from panda_py.sim import Simulator, free_loopback_host

KINDS = ("joint", "pose", "replace-joint", "replace-pose")


def _summary(name: str, values: list[float], unit: str) -> None:
    v = np.array(values)
    print(f"  {name:<14} n={len(v):3d}  median {np.median(v):8.3f}  p99 "
          f"{np.percentile(v, 99):8.3f}  worst {v.max():8.3f} {unit}")  # fmt: skip


def _random_target(kind: str, rng: np.random.Generator) -> tuple[str, object]:
    q0 = np.array(constants.JOINT_POSITION_START)
    if kind == "joint":
        return kind, q0 + rng.uniform(-0.3, 0.3, 7)
    T = panda_py.fk(q0)
    T[:3, 3] += rng.uniform(-0.12, 0.12, 3)
    return kind, T


def _start(panda: panda_py.Panda, target: tuple[str, object]) -> panda_py.MotionHandle:
    kind, goal = target
    if kind == "joint":
        return panda.move_to_joint_position(goal, asynchronous=True)
    return panda.move_to_pose(goal, asynchronous=True)


def _handover_state(log: dict[str, list[np.ndarray]], elapsed: float) -> int:
    """The log's sample where the first move handed over: its first tick (the last state
    before the arm moved) plus its elapsed time."""
    q = np.array(log["q"])
    moving = np.nonzero(np.abs(np.diff(q, axis=0)).max(axis=1) > 0)[0]
    return int(moving[0]) + round(elapsed / 1e-3)


def _first_plan(panda: panda_py.Panda, goal: np.ndarray, spec: object) -> PosePlan:
    """The plan ``Panda.move_to_pose(goal)`` makes from the arm at rest now (the same call
    with the same state: planning is deterministic), whose reference a replacing move
    takes over."""
    state = panda.get_state()
    quat = laws.quat_from_matrix(state.O_T_EE)
    goal_quat = laws.quat_from_matrix(goal.reshape(16, order="F"))
    return planning.pose_move(
        state.O_T_EE[12:15].copy(), quat, goal[:3, 3][None], goal_quat[None], pose_options({}),
        state.q.copy(), spec, at_rest=True,  # type: ignore[arg-type]
        F_T_EE=state.F_T_EE.reshape(4, 4, order="F"), load=load_of(state),
    )  # fmt: skip


def _bound(kind: str, goal: object, log: dict[str, list[np.ndarray]], k: int,
           spec: object, robot: str,
           ref: tuple[np.ndarray, ...] | None = None) -> tuple[float, float, float]:  # fmt: skip
    """[s] the fastest trajectory at the move's limits from the logged state at ``k``, and
    the fastest of those whose joint velocities and accelerations stay within the
    robot's joint limits along the way, and within JOINT_SHARE of them (a joint move:
    the same three)."""
    if kind == "joint":
        q, dq = np.array(log["q"]), np.array(log["dq"])
        gen = OnlineGenerator(OnlineLimits.joints(spec, 0.2))  # type: ignore[arg-type]
        gen.reset(q[k], dq[k], (dq[k + 1] - dq[k - 1]) / 2e-3)
        gen.set_target(np.asarray(goal))
        gen.step()
        return gen.duration, gen.duration, gen.duration
    T = np.array(log["O_T_EE"])
    p = T[:, 12:15]
    quats = np.array([laws.quat_from_matrix(t) for t in T[k - 1 : k + 2]])
    v = (p[k + 1] - p[k - 1]) / 2e-3
    a = (p[k + 1] - 2.0 * p[k] + p[k - 1]) / 1e-6
    if quats[0] @ quats[1] < 0.0:
        quats[0] = -quats[0]
    if quats[2] @ quats[1] < 0.0:
        quats[2] = -quats[2]
    # the angular velocity in the base frame: 2 (dq/dt) q^-1, its vector part
    w = 2.0 * rot.multiply((quats[2] - quats[0]) / 2e-3, rot.conjugate(quats[1]))[:3]
    Tg = np.asarray(goal)
    quat_goal = laws.quat_from_matrix(Tg.reshape(16, order="F"))
    if ref is None:  # the arm's state, from the log
        start = (p[k], quats[1], np.hstack([v, w]), np.hstack([a, np.zeros(3)]), Tg[:3, 3],
                 quat_goal, np.zeros(6), np.zeros(6))  # fmt: skip
    else:  # the replaced move's reference, which the lead-in starts from
        start = (*ref, Tg[:3, 3], quat_goal, np.zeros(6), np.zeros(6))
    limits = OnlineLimits.cartesian(spec, 0.2)  # type: ignore[arg-type]
    twists = _pose_twists(limits, start)
    out = [len(twists) * 1e-3]
    q0 = np.array(log["q"][k])
    # ours: the move's own limits (their jerk the acceleration over planning.RAMP_TIME)
    ours = planning.pose_online(spec, 0.2).limits  # type: ignore[arg-type]
    for share, base in ((1.0, limits), (moves.JOINT_SHARE, ours)):
        capped, within = base, twists if base is limits else _pose_twists(base, start)
        for _ in range(12):  # the limits scaled until the joints' demand fits
            over_v, over_a = _joint_demand(within, q0, spec, robot, share)
            if over_v <= 1.0 and over_a <= 1.0:
                break
            capped = capped.scaled(min(1.0, 0.99 / over_v), min(1.0, 0.99 / over_a))
            within = _pose_twists(capped, start)
        out.append(len(within) * 1e-3)
    return out[0], out[1], out[2]


def _pose_twists(limits: OnlineLimits, start: tuple[np.ndarray, ...]) -> np.ndarray:
    """The online generator's twists, tick by tick, from ``start`` to its goal."""
    gen = OnlinePose(limits)
    gen.reset_toward(*start)
    out = [gen.twist.copy()]
    while not gen.step():
        out.append(gen.twist.copy())
    return np.array(out)


def _joint_demand(twists: np.ndarray, q0: np.ndarray, spec: object, robot: str,
                  share: float) -> tuple[float, float]:  # fmt: skip
    """The largest joint velocity and acceleration, each as a fraction of ``share`` of the
    robot's limit (or of the start's, where that is more), of an arm that follows
    ``twists`` (one a tick) from ``q0`` (J^+ at each tick)."""
    q, dq = q0.copy(), np.empty((len(twists), 7))
    for i, twist in enumerate(twists):
        dq[i] = laws.damped_pinv(kinematics.zero_jacobian(q, robot=robot)) @ twist
        q += dq[i] * 1e-3
    ddq = np.gradient(dq, 1e-3, axis=0)
    joints = spec.joints  # type: ignore[attr-defined]
    v = np.abs(dq) / (share * np.array(joints.dq_max))
    a = np.abs(ddq) / (share * np.array(joints.ddq_max))
    # where the arm's own motion at the hand-over asks for more already, the rest is judged
    # against it (as the move judges its lead-in: moves.joint_capped_peaks)
    return (
        float(v.max()) / max(1.0, float(v[0].max())),
        float(a.max()) / max(1.0, float(a[:2].max())),
    )


def run(robot: str, moves: int, kinds: tuple[str, ...]) -> None:
    spec = get_robot(robot)
    with (
        Simulator(free_loopback_host(), robot=robot, lockstep=True) as sim,
        panda_py.Panda(sim.host) as panda,
    ):
        panda.move_to_start()
        rng = np.random.default_rng(0)
        print(f"{robot.upper()} (lockstep):")
        for kind in kinds:
            base = kind.removeprefix("replace-")
            late, ratios, within, at_share, errors = [], [], [], [], []
            t0 = time.monotonic()
            for _ in range(moves):
                if kind == base:
                    h = _start(panda, _random_target(base, rng))
                    h.wait(60.0)
                    r = h.result
                    assert r is not None
                    late.append(1e3 * (r.elapsed - r.duration))
                    errors.append(1e3 * (r.joint_error if base == "joint" else r.position_error))
                    continue
                panda.move_to_start()
                panda.enable_logging(20_000)
                target = _random_target(base, rng)
                plan = _first_plan(panda, target[1], spec) if base == "pose" else None  # type: ignore[arg-type]
                first = _start(panda, target)
                ticks = panda.get_state().time.to_msec()
                wait = rng.uniform(100.0, 400.0)
                while panda.get_state().time.to_msec() - ticks < wait:
                    time.sleep(1e-4)
                target = _random_target(base, rng)
                second = _start(panda, target)
                second.wait(60.0)
                a, b = first.result, second.result
                assert a is not None and b is not None
                log = panda.get_log()
                k = _handover_state(log, a.elapsed)
                ref = None
                if plan is not None:  # the first move's reference at its last tick
                    i = min(round(a.elapsed / 1e-3), len(plan.position) - 1)
                    ref = (plan.position[i], plan.orientation[i], plan.twist[i], plan.accel[i])
                cartesian, joints, shared = _bound(base, target[1], log, k, spec, robot, ref)
                ratios.append(b.elapsed / cartesian)
                within.append(b.elapsed / joints)
                at_share.append(b.elapsed / shared)
                late.append(1e3 * (b.elapsed - b.duration))
                panda.disable_logging()
            print(f" {kind} ({moves} moves, {time.monotonic() - t0:.0f} s):")
            _summary("after traj.", late, "ms")
            if errors:
                _summary("error", errors, "mrad" if base == "joint" else "mm")
            if ratios:
                _summary("vs fastest", ratios, "x")
                _summary("vs in joints", within, "x")
                _summary("vs our share", at_share, "x")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--moves", type=int, default=20)
    p.add_argument("--robot", choices=("fer", "fr3", "both"), default="both")
    p.add_argument("--kinds", default=",".join(KINDS))
    args = p.parse_args()
    kinds = tuple(k for k in args.kinds.split(",") if k)
    unknown = [k for k in kinds if k not in KINDS]
    if unknown:
        p.error(f"--kinds: unknown {unknown}, expected some of {list(KINDS)}")
    for robot in ("fer", "fr3") if args.robot == "both" else (args.robot,):
        run(robot, args.moves, kinds)


if __name__ == "__main__":
    main()
