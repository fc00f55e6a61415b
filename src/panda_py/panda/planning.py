"""``Panda``'s moves on the user's side: the time-optimal plan of a checked motion
(:mod:`panda_py.panda.move_args`), sampled at the robot's 1 ms period for the control
process.

Everything here runs before anything is sent: a target out of the arm's reach never
starts a motion.
"""

from __future__ import annotations

import math
from typing import Literal, NamedTuple, overload

import numpy as np
from numpy.typing import NDArray

from panda_py import checks
from panda_py.controllers import laws
from panda_py.controllers.plans import JointPlan, PosePlan
from panda_py.fci import PERIOD
from panda_py.kinematics import get_kinematics
from panda_py.motion import CartesianTrajectory, JointTrajectory
from panda_py.motion.cartesian import CartesianSamples
from panda_py.motion.online import OnlineLimits
from panda_py.motion.rotation import matrix_rows, transforms
from panda_py.motion.smoothing import SMOOTHING_TIME, box_filter
from panda_py.panda.move_args import JointMoveOptions, PoseMoveOptions
from panda_py.panda.plan_torques import Load, loaded_arm, smoothing_width
from panda_py.robots.params import RobotSpec

__all__ = ["check_reachable", "joint_goal", "joint_move", "pose_goal", "pose_move"]

FloatArray = NDArray[np.float64]

SMOOTHING = round(SMOOTHING_TIME / PERIOD)  # [samples] a move's moving average
# [s] a joint plan's acceleration steps ramped over this (a moving average, as a Cartesian
# plan's over SMOOTHING_TIME), and the online generator's acceleration no faster (its jerk
# at most a_max / RAMP_TIME): unramped, a joint move's arrival (-2.5 rad/s^2 to 0 in one
# sample) was a 3.5 Nm torque step on joint 2 that the torque rate limit spread over 9 ms,
# pushing the arm on past the goal for 25 ms after its trajectory; ramped, it ends within
# 5 ms (10 ms was enough; the move gets 10 ms longer)
RAMP_TIME = 0.01
JOINT_SMOOTHING = round(RAMP_TIME / PERIOD)  # [samples]


def _times(duration: float) -> FloatArray:
    n = math.ceil(duration / PERIOD)
    t = np.arange(n + 1, dtype=np.float64) * PERIOD
    t[-1] = duration
    return t


@overload
def joint_move(q_now: FloatArray, waypoints: FloatArray, opts: JointMoveOptions,
               spec: RobotSpec, *, at_rest: Literal[True]) -> JointPlan: ...  # fmt: skip
@overload
def joint_move(q_now: FloatArray, waypoints: FloatArray, opts: JointMoveOptions,
               spec: RobotSpec, *, at_rest: bool = False) -> JointPlan | None: ...  # fmt: skip
def joint_move(q_now: FloatArray, waypoints: FloatArray, opts: JointMoveOptions,
               spec: RobotSpec, *, at_rest: bool = False) -> JointPlan | None:  # fmt: skip
    """The sampled plan from ``q_now`` through ``waypoints``; None if already there
    (``at_rest``: then a plan that rests there)."""
    traj = JointTrajectory(
        np.vstack([q_now, waypoints]), opts.speed_factor, opts.max_deviation, robot=spec
    )
    if traj.get_duration() == 0.0:
        if not at_rest:
            return None
        z = np.zeros((2, 7))
        goal = np.tile(waypoints[-1], (2, 1))
        online = joint_online(spec, opts.speed_factor)._asdict()
        return JointPlan(goal, z, z, opts.stiffness, opts.damping, opts.dq_threshold,
                         opts.success_threshold, **online)  # fmt: skip
    s = traj.sample(_times(traj.get_duration()))
    w = JOINT_SMOOTHING  # its acceleration steps ramped (see RAMP_TIME)
    positions = box_filter(s.positions, w)
    return JointPlan(
        positions, box_filter(s.velocities, w), box_filter(s.accelerations, w), opts.stiffness,
        opts.damping, opts.dq_threshold, opts.success_threshold,
        join=_join(positions, waypoints),
        **joint_online(spec, opts.speed_factor)._asdict(),
    )  # fmt: skip


# a stop (cancel, a guarded move's condition) decelerates with no less than this share of
# the robot's limits, whatever the move's speed factor: a guarded descent at 5 cm/s
# (speed factor 0.05) would otherwise brake 11 mm further into what it touched
STOP_SPEED_FACTOR = 0.5


class Online(NamedTuple):
    """The online generator's limits of a plan (its fields' names)."""

    limits: OnlineLimits
    stop_limits: OnlineLimits


def joint_online(spec: RobotSpec, speed_factor: float) -> Online:
    """The online generator's limits of a joint plan."""
    return _online("joint", spec, speed_factor)


def pose_online(spec: RobotSpec, speed_factor: float) -> Online:
    """The online generator's limits of a Cartesian plan."""
    return _online("pose", spec, speed_factor)


# a move's limits by (kind, the spec's id, speed factor), the spec kept with them (an id is
# only unique while its object lives): by id, as hashing a RobotSpec costs 9 us, more than
# building the limits did
_ONLINE: dict[tuple[str, int, float], tuple[RobotSpec, Online]] = {}


def _online(kind: str, spec: RobotSpec, speed_factor: float) -> Online:
    key = (kind, id(spec), speed_factor)
    hit = _ONLINE.get(key)
    if hit is not None and hit[0] is spec:
        return hit[1]
    make = OnlineLimits.joints if kind == "joint" else OnlineLimits.cartesian
    limits = make(spec, speed_factor)
    # a lead-in's acceleration ramped (a stop's is not: it must brake as soon as it can, a
    # guarded move's on what it touched). A Cartesian lead-in at the robot's jerk left the
    # arm behind its reference where it stopped accelerating: 20 random replacements ended
    # a median 56 ms (FER) and 78 ms (FR3) after their trajectory, ramped 20 and 4 ms, for
    # a trajectory 0-3 % longer
    online = Online(_ramped(limits), make(spec, max(speed_factor, STOP_SPEED_FACTOR)))
    if len(_ONLINE) >= 64:  # many speed factors (a policy's): keep the newest
        _ONLINE.clear()
    _ONLINE[key] = (spec, online)
    return online


def _ramped(limits: OnlineLimits) -> OnlineLimits:
    """``limits`` with each jerk at most its acceleration over RAMP_TIME: at the robot's
    jerk (scaled by the speed factor) a lead-in's acceleration rose and fell within 2 ms,
    a torque step the robot's torque rate limit (1000 Nm/s) spread over 10 ms, and the arm
    arrived with the rest of it as a push past its goal (a replacing joint move overshot
    0.24 mrad and crept back for 140 ms)."""
    jerk = tuple(min(j, a / RAMP_TIME) for j, a in zip(limits.jerk, limits.acceleration,
                                                       strict=True))  # fmt: skip
    return OnlineLimits(limits.velocity, limits.acceleration, jerk)


def joint_goal(goal: FloatArray, opts: JointMoveOptions, spec: RobotSpec) -> JointPlan:
    """A single-target joint move that replaces a running one: only its goal. The control
    process's online generator leads in to it from the running move's state (time-optimal
    under jerk limits); nothing to plan or sample here, so it takes effect sooner."""
    z = np.zeros((1, 7))
    online = joint_online(spec, opts.speed_factor)._asdict()
    return JointPlan(goal.reshape(1, 7), z, z, opts.stiffness, opts.damping, opts.dq_threshold,
                     opts.success_threshold, **online)  # fmt: skip


def pose_goal(position: FloatArray, quat: FloatArray, opts: PoseMoveOptions,
              q_nullspace: FloatArray, spec: RobotSpec) -> PosePlan:  # fmt: skip
    """:func:`joint_goal` for a Cartesian move."""
    z = np.zeros((1, 6))
    return PosePlan(
        position.reshape(1, 3), quat.reshape(1, 4), z, z, q_nullspace, opts.impedance,
        opts.damping_ratio, opts.nullspace_stiffness, opts.dq_threshold, opts.success_threshold,
        opts.orientation_threshold, **pose_online(spec, opts.speed_factor)._asdict(),
    )  # fmt: skip


def _join(samples: FloatArray, waypoints: FloatArray) -> int:
    """Where a lead-in joins the plan when the move replaces another mid-motion: the
    sample nearest the first waypoint (-1, the goal, for a single target), so the rest of
    the path through the waypoints stays the planned, time-optimal one."""
    if len(waypoints) < 2:
        return -1
    return int(np.argmin(np.linalg.norm(samples - waypoints[0], axis=1)))


def check_reachable(positions: FloatArray, quats: FloatArray, q_now: FloatArray,
                    spec: RobotSpec, F_T_EE: FloatArray) -> None:  # fmt: skip
    """Raise ValueError for the first target pose the arm cannot reach (no IK solution
    within the joint limits for any q7 near the current one). The current q7 (usually
    enough) is tried first, in few calls: a move's target is checked on the way to the
    robot, on the cold caches of a caller that slept in between (a policy's)."""
    kin = get_kinematics(spec, F_T_EE)
    q7_now = float(q_now[6])
    for i, (p, quat) in enumerate(zip(positions.tolist(), quats.tolist(), strict=True)):
        r0, r1, r2 = matrix_rows(*quat)
        T = np.array([[*r0, p[0]], [*r1, p[1]], [*r2, p[2]], [0.0, 0.0, 0.0, 1.0]])
        if _solvable(kin.ik_full(T, q_now, q7_now)):
            continue
        j = spec.joints
        if any(_solvable(kin.ik_full(T, q_now, q7))
               for q7 in np.linspace(j.q_min[6], j.q_max[6], 25).tolist()):  # fmt: skip
            continue
        raise ValueError(
            f"pose[{i}]: position {np.round(p, 4).tolist()} with orientation "
            f"{np.round(quat, 4).tolist()} is out of reach of the {spec.name} (no inverse "
            "kinematics solution within the joint limits)"
        )


def _solvable(solutions: FloatArray) -> bool:
    """Whether one of ik_full's rows (4, 7) is a solution (finite)."""
    return any(checks.all_finite(row) for row in solutions.tolist())


# of the joints' velocity and acceleration limits a sampled Cartesian plan may ask for:
# the arm tracks a plan with its feed-forward closely (measured within 1-2 % of the
# planned joint accelerations), unlike a lead-in from a running move (moves.JOINT_SHARE)
PLAN_JOINT_SHARE = 0.85
# damped least-squares steps per pose when the arm's configurations follow a path (poses
# 1 ms or a few millimetres apart: the second step leaves micrometres)
FOLLOW_ITERATIONS = 2
# [m] how far configurations following a path may be from it before it counts as out of
# reach (where the arm can follow, they are within micrometres)
REACH_TOLERANCE = 1e-3


class ArmJoints:
    """The arm's joints along a Cartesian plan (a :class:`~panda_py.motion.JointMap`), as
    the Cartesian law moves them: ``q̇ = J^+ v`` (its feed-forward's damped pseudo-inverse)
    at the configurations it passes through (:meth:`configurations`), bounded by
    PLAN_JOINT_SHARE of the joints' limits."""

    def __init__(self, spec: RobotSpec, q_now: FloatArray,
                 F_T_EE: FloatArray | None = None) -> None:  # fmt: skip
        from panda_py.kinematics import get_kinematics

        self.kinematics = get_kinematics(spec, F_T_EE)
        self.q_now = np.asarray(q_now, dtype=np.float64)
        self.velocity = PLAN_JOINT_SHARE * np.asarray(spec.joints.dq_max, dtype=np.float64)
        self.acceleration = PLAN_JOINT_SHARE * np.asarray(spec.joints.ddq_max, dtype=np.float64)

    def configurations(self, poses: FloatArray) -> FloatArray:
        """The arm's configurations at the poses (N, 4, 4) of a path from where it is, as
        the law moves it (:meth:`~panda_py.kinematics.Kinematics.follow`: ``J^+`` with the
        law's damping, q7 free, continuous where the analytical inverse kinematics jumps);
        the law's pull of the nullspace toward the start is left out."""
        return self.kinematics.follow(
            poses, self.q_now, damping=laws.PINV_DAMPING, iterations=FOLLOW_ITERATIONS
        )

    def rates(self, poses: FloatArray, twists: FloatArray) -> FloatArray:
        return self.rates_at(self.configurations(poses), twists)

    def rates_at(self, q: FloatArray, twists: FloatArray) -> FloatArray:
        """The joints' rates (N, 7) that give the twists (N, 6) at configurations q (N, 7)
        (NaN rows where q is)."""
        out = np.full((len(q), 7), np.nan)
        ok = np.isfinite(q).all(axis=1)
        if ok.any():
            J = self.kinematics.zero_jacobian(q[ok])  # (M, 6, 7)
            JJt = J @ J.transpose(0, 2, 1)
            JJt[:, range(6), range(6)] += laws.PINV_DAMPING**2
            y = np.linalg.solve(JJt, twists[ok][:, :, None])
            out[ok] = (J.transpose(0, 2, 1) @ y)[:, :, 0]
        return out


def joint_time_scale(s: CartesianSamples, joints: ArmJoints) -> float:
    """How many times slower (>= 1) the samples (every PERIOD) must be run for the joints
    to stay within their bounds: the check of every sample after the profile (which bounds
    them from points a few millimetres apart), on the configurations the arm passes
    through (:meth:`ArmJoints.configurations`)."""
    twists = np.hstack([s.velocities, s.angular_velocities])
    q = joints.configurations(transforms(s.positions, s.orientations))
    dq = joints.rates_at(q, twists)
    # the accelerations along the arm's own motion: the rates one tick on, at where these
    # rates take the arm
    ddq = (joints.rates_at(q[:-1] + dq[:-1] * PERIOD, twists[1:]) - dq[:-1]) / PERIOD
    with np.errstate(invalid="ignore"):
        v = np.abs(dq) / joints.velocity
        a = np.abs(ddq) / joints.acceleration
    v_max = float(np.max(v, initial=0.0, where=np.isfinite(v)))
    a_max = float(np.max(a, initial=0.0, where=np.isfinite(a)))
    return max(1.0, v_max, math.sqrt(a_max))


def pose_move_in_joint_space(
    plan: PosePlan, opts: PoseMoveOptions, q_now: FloatArray, spec: RobotSpec,
    F_T_EE: FloatArray,
) -> JointPlan:  # fmt: skip
    """The sampled Cartesian plan as joint positions, velocities and accelerations: the
    IK of every sample, in the current configuration's case and with the current q7, as
    panda-py's; where that path leaves its case or outruns the joints (across q2 = 0 it
    splits joints 1 and 3 anew at every sample), the configurations the arm passes
    through instead (:meth:`ArmJoints.configurations`: q7 moves), on which the plan's
    timing was judged. Tracked with the joint stiffness and damping of the plan's options
    (judged on the pose by the caller: the joint success threshold is infinite)."""
    from panda_py.kinematics import get_kinematics

    kinematics = get_kinematics(spec, F_T_EE)
    poses = transforms(plan.position, plan.orientation)
    q = kinematics.ik(poses, q_now, float(q_now[6]))
    step = np.abs(np.diff(q, axis=0)) / PERIOD
    if not (np.isfinite(q).all() and (step <= np.asarray(spec.joints.dq_max)).all()):
        q = ArmJoints(spec, q_now, F_T_EE).configurations(poses)
        off = np.linalg.norm(kinematics.fk(q)[:, :3, 3] - plan.position, axis=1)
        bad = np.flatnonzero(~(off <= REACH_TOLERANCE))
        if bad.size:
            t = bad[0] * PERIOD
            raise ValueError(
                f"pose: the straight path leaves the {spec.name}'s reach {t:.3f} s into the "
                f"motion (the arm following it ends up {off[bad[0]] * 1000:.1f} mm from it)"
            )
    dq = np.gradient(q, PERIOD, axis=0)
    dq[0] = dq[-1] = 0.0
    ddq = np.gradient(dq, PERIOD, axis=0)
    assert opts.joint_space is not None
    stiffness, damping = opts.joint_space
    return JointPlan(
        q, dq, ddq, stiffness, damping, opts.dq_threshold, math.inf,
        **joint_online(spec, opts.speed_factor)._asdict(),
    )  # fmt: skip


@overload
def pose_move(p_now: FloatArray, quat_now: FloatArray, positions: FloatArray,
              quats: FloatArray, opts: PoseMoveOptions, q_nullspace: FloatArray,
              spec: RobotSpec, *, at_rest: Literal[True],
              F_T_EE: FloatArray | None = None,
              load: Load | None = None) -> PosePlan: ...  # fmt: skip
@overload
def pose_move(p_now: FloatArray, quat_now: FloatArray, positions: FloatArray,
              quats: FloatArray, opts: PoseMoveOptions, q_nullspace: FloatArray,
              spec: RobotSpec, *, at_rest: bool = False,
              F_T_EE: FloatArray | None = None,
              load: Load | None = None) -> PosePlan | None: ...  # fmt: skip
def pose_move(p_now: FloatArray, quat_now: FloatArray, positions: FloatArray,
              quats: FloatArray, opts: PoseMoveOptions, q_nullspace: FloatArray,
              spec: RobotSpec, *, at_rest: bool = False,
              F_T_EE: FloatArray | None = None,
              load: Load | None = None) -> PosePlan | None:  # fmt: skip
    """The sampled Cartesian plan from the current pose through the targets, its
    nullspace resting at ``q_nullspace`` (the arm's configuration now); None if already
    there (``at_rest``: then a plan that rests there). The Cartesian limits alone can ask a
    joint for more than its own (near the start pose, 2.6 m/s^2 at speed factor 0.2 is all
    of joint 2's): the plan is time-optimal under the joints' limits too (:class:`ArmJoints`,
    ``F_T_EE`` the end effector's, None: the robot's hand), and every sample is checked
    (:func:`joint_time_scale`). Its smoothing is wide enough for the loop to deliver the
    torques it asks for (:mod:`.plan_torques`; ``load``: the state's total load, None:
    the Franka Hand's)."""
    joints = ArmJoints(spec, q_nullspace, F_T_EE)
    traj = CartesianTrajectory(
        np.vstack([p_now, positions]), np.vstack([quat_now, quats]), opts.speed_factor,
        opts.max_deviation, robot=spec, joints=joints,
    )  # fmt: skip
    if traj.get_duration() == 0.0:
        if not at_rest:
            return None
        z = np.zeros((2, 6))
        return PosePlan(
            np.tile(positions[-1], (2, 1)), np.tile(quats[-1], (2, 1)), z, z, q_nullspace,
            opts.impedance, opts.damping_ratio, opts.nullspace_stiffness, opts.dq_threshold,
            opts.success_threshold, opts.orientation_threshold,
            **pose_online(spec, opts.speed_factor)._asdict(),
        )  # fmt: skip
    duration = traj.get_duration()
    s = traj.sample(_times(duration))
    k = joint_time_scale(s, joints)
    if k > 1.0:  # the same path, k times slower: velocities / k, accelerations / k^2
        s = traj.sample(_times(k * duration) / k)
        s = s._replace(velocities=s.velocities / k, accelerations=s.accelerations / (k * k),
                       angular_velocities=s.angular_velocities / k)  # fmt: skip
    # its acceleration steps ramped (smoothing.py), as widely as the loop's torque rate
    # needs (plan_torques): the arm can follow them; the acceleration the rate of the
    # smoothed twist (central differences), so that it starts and ends at rest as the twist
    # does (the moving average of the profile's own acceleration, padded with its first and
    # last, fed the profile's whole first acceleration forward from the first tick, the
    # reference at rest)
    _, _, (position, orientation, twist, accel) = smoothing_width(
        s, SMOOTHING, joints, loaded_arm(spec, load), np.asarray(spec.drives.armature)
    )
    return PosePlan(
        position=position,
        orientation=orientation,
        twist=twist,
        accel=accel,
        q_nullspace=q_nullspace,
        impedance=opts.impedance,
        damping_ratio=opts.damping_ratio,
        nullspace_stiffness=opts.nullspace_stiffness,
        dq_threshold=opts.dq_threshold,
        success_threshold=opts.success_threshold,
        orientation_threshold=opts.orientation_threshold,
        join=_join(position, positions),
        **pose_online(spec, opts.speed_factor)._asdict(),
    )
