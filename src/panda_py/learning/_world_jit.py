"""The fast world's ticks compiled: many ticks of a streamed-target controller
(``CartesianTarget`` or ``JointTarget``) on the in-process robot in one numba call, each
tick the law's compiled step (``controllers._fused``), the control process's finishing
(``_kernels.finalize_torques``: walls, rate and range saturation, the low-pass filter)
and the robot's compiled tick (:func:`panda_py.sim.compiled.torque_tick`: its checks,
the hand, ``mj_step``, the state's fill), with no Python between ticks.

A kernel runs the ticks the Python reference would run the same way. A tick with news
for the law (a new target: ruckig calculates) has its part before the law's compiled step
done in Python first (``CartesianTarget.compiled_news``; ``S_STEPPED``), and the kernel
runs the rest of it. Where a tick needs more (the robot's checks failing, a non-finite
torque, a contact) it stops before that tick, or hands the rest of it back,
with a status (:class:`Stop`) saying which; :class:`panda_py.learning.world.FastWorld`
does that part in Python and goes on. Imported where numba runs (else ImportError);
cached under a key over its sources and theirs (:mod:`panda_py.jit.cache`).
"""

from __future__ import annotations

import enum
import hashlib
from pathlib import Path

import numpy as np

from panda_py.controllers import laws
from panda_py.jit import cache, libc
from panda_py.motion import online
from panda_py.sim import compiled as sim

_KERNELS = laws.compiled()
_FUSED = laws.fused()
_ONLINE = online.compiled_kernels()
if _KERNELS is None or _FUSED is None or _ONLINE is None:
    raise ImportError("the control laws run without numba")

__all__ = ["Stop", "joint_target_ticks", "pose_target_ticks", "read_state"]

KEY = hashlib.sha256(
    (cache.source_key([Path(__file__), Path(libc.__file__)]) + sim.KEY + _FUSED.KEY).encode()
).hexdigest()[:20]

_finalize = _KERNELS.finalize_torques
_pose_target_step = _FUSED.pose_target_step
_joint_tracking_step = _FUSED.joint_tracking_step
_sample = _ONLINE.sample
_torque_tick = sim.torque_tick
_clear_of_contacts = sim.clear_of_contacts
_restore_contacts = sim.restore_contacts
_ROBOT = int(sim.Tick.ROBOT)


class Stop(enum.IntEnum):
    """Why a kernel returned (with the number of ticks it completed)."""

    DONE = 0  # all the ticks asked for
    WHOLE = 1  # the next tick is the reference's, whole
    ROBOT = 2  # the next tick's law ran (its command in ``cmd``): the robot's part is left
    FILL = 3  # the last tick counted is done but for the state's fill
    CONTACTS = 4  # the last tick counted is done but for the contacts' part of the fill
    NON_FINITE = 5  # the next tick's law gave a non-finite torque (in ``tau``)


# the stops as the kernels return them (plain integers)
_DONE, _WHOLE, _AT_ROBOT, _NON_FINITE = (
    int(Stop.DONE),
    int(Stop.WHOLE),
    int(Stop.ROBOT),
    int(Stop.NON_FINITE),
)

# indices of the scalars ``s`` (float64), synchronised with the controller by the caller
S_T, S_T_TARGET, S_TIMEOUT, S_STALE, S_GEN_TIME, S_GEN_FINISHED, S_DURATION = 0, 1, 2, 3, 4, 5, 6
S_DAMPING_DUE, S_DT, S_GAIN, S_DTAU_MAX, S_DAMPING_TICKS, S_FRICTION_SPEED = 7, 8, 9, 10, 11, 12
S_ERROR_RATE, S_OUT, S_STEPPED = 13, 14, 15
SCALARS = 16


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def read_state(sb, at, single, q, dq, O_T_EE, tau_J_d):  # type: ignore[no-untyped-def,unused-ignore]
    """The fields a law and its finishing read, from the robot's state buffer ``sb`` as
    the wire carries them: ``at`` the offsets of q, dq, O_T_EE, tau_J_d; ``single``: 1
    where the wire rounds the field to float32 (protocol v10)."""
    for f, dst in ((0, q), (1, dq), (2, O_T_EE), (3, tau_J_d)):
        a = at[f]
        if single[f]:
            for i in range(dst.shape[0]):
                dst[i] = np.float64(np.float32(sb[a + i]))
        else:
            for i in range(dst.shape[0]):
                dst[i] = sb[a + i]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _before_tick(s):  # type: ignore[no-untyped-def,unused-ignore]
    """Whether the next tick runs as compiled: the targets do not go stale in it (else
    the reference runs it whole: the law's news)."""
    t = s[S_T] + s[S_DT]
    return not (s[S_STALE] == 0.0 and t - s[S_T_TARGET] > s[S_TIMEOUT])


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _advance(s):  # type: ignore[no-untyped-def,unused-ignore]
    """The generator's compiled step's bookkeeping (``OnlineGenerator._advance``): the
    time to sample at, or -1 where the trajectory has finished (the reference stands)."""
    if s[S_GEN_FINISHED] != 0.0:
        return -1.0
    s[S_GEN_TIME] += s[S_DT]
    s[S_GEN_FINISHED] = 1.0 if s[S_GEN_TIME] > s[S_DURATION] else 0.0
    return s[S_GEN_TIME]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _finish(s, tau, q, dq, tau_J_d, walls, cmd, out, robot, cull):  # type: ignore[no-untyped-def,unused-ignore]
    """The law's torques ``tau`` finished into ``cmd`` (``laws.JointWalls.finalize``), the
    time published, the robot's tick (its collision detection skipped where no contact
    can arise: ``cull``, :func:`panda_py.sim.compiled.contact_cull`; the same step): a
    :class:`Stop` and whether the tick completed."""
    table, scale, flags, tau_max = walls
    if not _finalize(tau, q, dq, tau_J_d, table, scale, flags, s[S_DTAU_MAX], tau_max,
                     s[S_GAIN], cmd):  # fmt: skip
        return _NON_FINITE, False
    out[0] = s[S_T]
    culled = _clear_of_contacts(cull)
    status = _torque_tick(cmd, *robot)
    if culled:
        _restore_contacts(cull)
    if status == _ROBOT:
        return _AT_ROBOT, False
    return status, True


@cache.keyed_jit(KEY, **libc.LOOP_KERNEL, error_model="numpy")
def pose_target_ticks(  # type: ignore[no-untyped-def,unused-ignore]
    n, s, tick, gen, law, arm, target, out, reads, walls, buf, robot, cull
):  # fmt: skip
    """Up to ``n`` ticks of ``CartesianTarget`` (its fused step,
    ``_fused.pose_target_step``) on the robot: (ticks completed, :class:`Stop`).
    ``s``: the scalars (``S_*``); ``tick``: the fused step's per-tick scalars; ``gen``:
    the generator's arrays (trajectory, state, frames, anchor, reference); ``law``: the
    tracking's buffer; ``arm``: the chain, the arm's parameters, armature, Coulomb
    friction; ``reads``: the state buffer, offsets, float32 flags; ``walls``: the
    finishing's table, its state and the torque limits; ``buf``: q, dq, O_T_EE,
    tau_J_d, tau, cmd; ``robot``: the robot's compiled tick's arguments; ``cull``: its
    contacts' cull (``CompiledTick.contact_cull``)."""
    traj, p, v, a, Ft, Fr, R0, q0, position, orientation, twist, accel = gen
    chain, origin, ca, sa, mass, h, inertia, armature, coulomb = arm
    sb, at, single = reads
    q, dq, O_T_EE, tau_J_d, tau, cmd = buf
    scalars = law[0:8]
    for k in range(n):
        if k == 0 and s[S_STEPPED] != 0.0:  # its clock and generator stepped (news)
            tick[0] = 0.0
        else:
            if not _before_tick(s):
                return k, _WHOLE
            s[S_T] += s[S_DT]  # ctrl.tick
            t = _advance(s)
            if t < 0.0:
                tick[0] = 0.0
            else:
                tick[0], tick[1], tick[2] = 1.0, s[S_DURATION], t
        read_state(sb, at, single, q, dq, O_T_EE, tau_J_d)
        tick[3] = s[S_STALE]
        # PoseImpedance.compiled_inputs(dt)
        s[S_DAMPING_DUE] -= 1.0
        scalars[0] = s[S_DT]
        scalars[7] = 1.0
        if s[S_DAMPING_DUE] < 0.0:
            scalars[6] = 1.0
            s[S_DAMPING_DUE] = s[S_DAMPING_TICKS] - 1.0
        else:
            scalars[6] = 0.0
        _pose_target_step(tick, traj, p, v, a, Ft, Fr, R0, q0, position, orientation, twist,
                          accel, O_T_EE, q, dq, chain, origin, ca, sa, mass, h, inertia,
                          armature, coulomb, law, target, out, tau)  # fmt: skip
        stop, completed = _finish(s, tau, q, dq, tau_J_d, walls, cmd, out, robot, cull)
        if stop != _DONE:
            return k + 1 if completed else k, stop
    return n, _DONE


@cache.keyed_jit(KEY, **libc.LOOP_KERNEL, error_model="numpy")
def joint_target_ticks(  # type: ignore[no-untyped-def,unused-ignore]
    n, s, gen, gains, arm, target, out, reads, walls, buf, robot, cull
):  # fmt: skip
    """Up to ``n`` ticks of ``JointTarget`` (its generator's compiled step, the joint
    impedance with its feed-forward, ``_fused.joint_tracking_step``, its outputs) on the
    robot, as :func:`pose_target_ticks`; ``gen``: the packed trajectory and the
    reference (position, velocity, acceleration); ``gains``: stiffness and damping;
    ``arm``: the arm's parameters, armature, Coulomb friction."""
    traj, position, velocity, acceleration = gen
    K, D = gains
    origin, ca, sa, mass, h, inertia, armature, coulomb = arm
    sb, at, single = reads
    q, dq, O_T_EE, tau_J_d, tau, cmd = buf
    o = int(s[S_OUT])
    for k in range(n):
        if k > 0 or s[S_STEPPED] == 0.0:  # (else its clock and generator stepped: news)
            if not _before_tick(s):
                return k, _WHOLE
            s[S_T] += s[S_DT]
            t = _advance(s)
            if t >= 0.0:
                _sample(traj, s[S_DURATION], t, position, velocity, acceleration)
        read_state(sb, at, single, q, dq, O_T_EE, tau_J_d)
        _joint_tracking_step(q, dq, origin, ca, sa, mass, h, inertia, armature, coulomb, K, D,
                             position, velocity, acceleration, s[S_FRICTION_SPEED],
                             s[S_ERROR_RATE], tau)  # fmt: skip
        lag = 0.0
        for i in range(7):
            out[o + i] = position[i]
            out[o + 7 + i] = velocity[i]
            out[o + 14 + i] = acceleration[i]
            lag = max(lag, abs(target[i] - position[i]))
        out[o + 21] = lag
        out[o + 22] = s[S_STALE]
        stop, completed = _finish(s, tau, q, dq, tau_J_d, walls, cmd, out, robot, cull)
        if stop != _DONE:
            return k + 1 if completed else k, stop
    return n, _DONE
