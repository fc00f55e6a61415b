"""The control loop's compiled ticks of the built-in controllers and the streamed targets,
each law's part of a tick on the skeleton of :mod:`panda_py.rt._tick` (which waits,
decodes, finishes, sends and publishes around it): ``tick(view, law)`` runs the law on the
state taken and returns 0 with its torques in ``view[TAU]``, or PENDING with nothing
changed where the state is Python's (``_tick.loop_kernel``). Each law's step is the fused
one its Python ``step`` calls (:mod:`panda_py.controllers._fused`) or the same arithmetic
in the same order.
"""

from __future__ import annotations

from pathlib import Path

from panda_py.controllers import laws
from panda_py.fci import PERIOD
from panda_py.jit import cache, libc
from panda_py.motion import online
from panda_py.rt import _tick
from panda_py.rt._tick import DQ, LAW_T, OUT_VALUES, PENDING, POSE, TAU, VALUES, Q

_FUSED, _ONLINE = laws.fused(), online.compiled_kernels()
if _FUSED is None or _ONLINE is None:  # plain Python: Python ticks (rt._tick refuses too)
    raise ImportError("the control laws run without numba")
_cartesian_impedance_step = _FUSED.cartesian_impedance_step
_joint_tracking_step = _FUSED.joint_tracking_step
_pose_target_step = _FUSED.pose_target_step
_sample = _ONLINE.sample
_advance, _next_time, _copy = _tick.advance, _tick.next_time, libc.copy

__all__ = [
    "applied_torque_ticks", "cartesian_impedance_ticks", "cartesian_target_ticks",
    "integrated_velocity_ticks", "joint_position_ticks", "joint_target_ticks",
]  # fmt: skip

KEY = cache.source_key([Path(__file__)]) + _tick.KEY[:20]

# a streamed target's scalars (controllers.streaming._Streamed.compiled): when the last
# target arrived [s], the timeout [s] (inf: none), 1 if stale; the generator's time in its
# trajectory [s], 1 once it finished, the trajectory's duration [s]; the ticks until the
# tracking's damping update and their period (CartesianTarget); the friction's speed and
# error rate, the offsets of the target among the inputs and of the reference among the
# outputs (JointTarget)
(T_TARGET, T_TIMEOUT, T_STALE, T_GEN_TIME, T_FINISHED, T_DURATION, T_DAMPING_DUE,
 T_DAMPING_TICKS, T_FRICTION_SPEED, T_ERROR_RATE, T_TARGET_AT, T_OUT_AT) = range(12)  # fmt: skip
TARGET_SCALARS = 12


@cache.keyed_jit(KEY, nogil=True)
def _ema(filtered, target, alpha):  # type: ignore[no-untyped-def,unused-ignore]
    """``controllers.laws.ema``: in place, ``filtered <- alpha target + (1 - alpha)
    filtered`` (at once for alpha >= 1)."""
    if alpha >= 1.0:
        _copy(filtered, 0, target, 0, filtered.size)
    else:
        for i in range(filtered.size):
            filtered[i] += alpha * (target[i] - filtered[i])


@cache.keyed_jit(KEY, nogil=True)
def _cartesian_impedance(view, law):  # type: ignore[no-untyped-def,unused-ignore]
    """``CartesianImpedance`` (``controllers._fused.cartesian_impedance_step``); the
    impedance and the damping ratio are guarded (the damping target ``Kd_t`` is Python's
    to compute)."""
    values_in, at, filtered, Kd_t, chain, origin, ca, sa, mass, h, inertia, J = law
    _advance(view)
    _cartesian_impedance_step(values_in, at, filtered, Kd_t, view[POSE], view[Q], view[DQ],
                              chain, origin, ca, sa, mass, h, inertia, J,
                              view[TAU])  # fmt: skip
    return 0


@cache.keyed_jit(KEY, nogil=True)
def _joint_position(view, law):  # type: ignore[no-untyped-def,unused-ignore]
    """``JointPosition``: its inputs (at ``at``: position, velocity, stiffness, damping,
    filter_coeff) filtered into ``q_d``, ``dq_d``, ``K``, ``D``; ``tau = K (q_d - q) +
    D (dq_d - dq)``."""
    at, q_d, dq_d, K, D = law
    values, q, dq, tau = view[VALUES], view[Q], view[DQ], view[TAU]
    _advance(view)
    a = values[at[4]]
    _ema(q_d, values[at[0] : at[0] + 7], a)
    _ema(dq_d, values[at[1] : at[1] + 7], a)
    _ema(K, values[at[2] : at[2] + 7], a)
    _ema(D, values[at[3] : at[3] + 7], a)
    for i in range(7):
        tau[i] = K[i] * (q_d[i] - q[i]) + D[i] * (dq_d[i] - dq[i])
    return 0


@cache.keyed_jit(KEY, nogil=True)
def _integrated_velocity(view, law):  # type: ignore[no-untyped-def,unused-ignore]
    """``IntegratedVelocity``: ``q_d += dt dq_d`` within [``lower``, ``upper``] (published
    at ``at[3]`` of the outputs), ``tau = K (q_d - q) - D dq`` (the inputs at ``at``:
    velocity, stiffness, damping)."""
    at, q_d, lower, upper = law
    values, out_values, q, dq, tau = view[VALUES], view[OUT_VALUES], view[Q], view[DQ], view[TAU]
    _advance(view)
    dt = view[LAW_T][1]
    v, k, d, o = at[0], at[1], at[2], at[3]
    for i in range(7):
        x = q_d[i] + dt * values[v + i]
        q_d[i] = min(max(x, lower[i]), upper[i])  # (np.clip's order)
        out_values[o + i] = q_d[i]
        tau[i] = values[k + i] * (q_d[i] - q[i]) - values[d + i] * dq[i]
    return 0


@cache.keyed_jit(KEY, nogil=True)
def _applied_torque(view, law):  # type: ignore[no-untyped-def,unused-ignore]
    """``AppliedTorque``: its inputs (at ``at``: torque, damping, filter_coeff) filtered
    into ``applied`` and ``D``; ``tau = applied - D dq``."""
    at, applied, D = law
    values, dq, tau = view[VALUES], view[DQ], view[TAU]
    _advance(view)
    a = values[at[2]]
    _ema(applied, values[at[0] : at[0] + 7], a)
    _ema(D, values[at[1] : at[1] + 7], a)
    for i in range(7):
        tau[i] = applied[i] - D[i] * dq[i]
    return 0


@cache.keyed_jit(KEY, nogil=True)
def _stale_due(view, s):  # type: ignore[no-untyped-def,unused-ignore]
    """Whether the state taken is the one at which a streamed target's timeout passes
    (``_Streamed._pending``: that tick is Python's)."""
    return s[T_STALE] == 0.0 and _next_time(view) - s[T_TARGET] > s[T_TIMEOUT]


@cache.keyed_jit(KEY, nogil=True)
def _gen_advance(s):  # type: ignore[no-untyped-def,unused-ignore]
    """``OnlineGenerator._advance`` (its input unchanged since ruckig's step, its
    trajectory packed): the time to sample at, or -1 where it finished (it stands)."""
    if s[T_FINISHED] != 0.0:
        return -1.0
    s[T_GEN_TIME] += PERIOD
    s[T_FINISHED] = 1.0 if s[T_GEN_TIME] > s[T_DURATION] else 0.0
    return s[T_GEN_TIME]


@cache.keyed_jit(KEY, nogil=True)
def _joint_target(view, law):  # type: ignore[no-untyped-def,unused-ignore]
    """``JointTarget`` between its news (``controllers.streaming``): its generator's
    compiled step (the trajectory ``traj`` ruckig calculated, sampled into ``position``,
    ``velocity``, ``acceleration``), ``_fused.joint_tracking_step`` toward it and its
    outputs. A new target (the count of targets, guarded: the inputs left unread) or the
    timeout passing (``s``: the scalars, ``T_*``) is Python's: PENDING."""
    (s, traj, position, velocity, acceleration, K, D, origin, ca, sa, mass, h, inertia,
     armature, coulomb) = law  # fmt: skip
    if _stale_due(view, s):
        return PENDING
    values, out_values = view[VALUES], view[OUT_VALUES]
    t_at, o = int(s[T_TARGET_AT]), int(s[T_OUT_AT])
    _advance(view)
    t = _gen_advance(s)
    if t >= 0.0:
        _sample(traj, s[T_DURATION], t, position, velocity, acceleration)
    _joint_tracking_step(view[Q], view[DQ], origin, ca, sa, mass, h, inertia, armature,
                         coulomb, K, D, position, velocity, acceleration,
                         s[T_FRICTION_SPEED], s[T_ERROR_RATE], view[TAU])  # fmt: skip
    lag = 0.0
    for i in range(7):  # (JointTarget._publish)
        out_values[o + i] = position[i]
        out_values[o + 7 + i] = velocity[i]
        out_values[o + 14 + i] = acceleration[i]
        lag = max(lag, abs(values[t_at + i] - position[i]))
    out_values[o + 21] = lag
    out_values[o + 22] = s[T_STALE]
    return 0


@cache.keyed_jit(KEY, nogil=True)
def _cartesian_target(view, law):  # type: ignore[no-untyped-def,unused-ignore]
    """``CartesianTarget`` between its news, as :func:`_joint_target`: one
    ``_fused.pose_target_step`` a tick (its generator's compiled step, the tracking on the
    tracking law's buffer ``tracking``, the outputs), ``step`` its per-tick scalars
    (sample, duration, time, stale, the outputs' offset: ``CartesianTarget._fused_step``),
    the buffer's scalars set as ``tracking.PoseImpedance.compiled_inputs`` sets them."""
    (s, step, traj, p, v, a, Ft, Fr, R0, q0, position, orientation, twist, accel, tracking,
     target, chain, origin, ca, sa, mass, h, inertia, armature, coulomb) = law  # fmt: skip
    if _stale_due(view, s):
        return PENDING
    _advance(view)
    t = _gen_advance(s)
    if t < 0.0:
        step[0] = 0.0  # the reference stands
    else:
        step[0], step[1], step[2] = 1.0, s[T_DURATION], t
    step[3] = s[T_STALE]
    s[T_DAMPING_DUE] -= 1.0  # (PoseImpedance.compiled_inputs)
    tracking[0] = view[LAW_T][1]
    tracking[7] = 1.0  # a previous Jacobian: this law has ticked before
    if s[T_DAMPING_DUE] < 0.0:
        tracking[6] = 1.0
        s[T_DAMPING_DUE] = s[T_DAMPING_TICKS] - 1.0
    else:
        tracking[6] = 0.0
    _pose_target_step(step, traj, p, v, a, Ft, Fr, R0, q0, position, orientation, twist, accel,
                      view[POSE], view[Q], view[DQ], chain, origin, ca, sa, mass, h, inertia,
                      armature, coulomb, tracking, target, view[OUT_VALUES],
                      view[TAU])  # fmt: skip
    return 0


_kernel = _tick.loop_kernel  # (each law's tick, its name, how many arrays of its own)
cartesian_impedance_ticks = _kernel(_cartesian_impedance, "cartesian_impedance_ticks", 12)
joint_position_ticks = _kernel(_joint_position, "joint_position_ticks", 5)
integrated_velocity_ticks = _kernel(_integrated_velocity, "integrated_velocity_ticks", 4)
applied_torque_ticks = _kernel(_applied_torque, "applied_torque_ticks", 3)
joint_target_ticks = _kernel(_joint_target, "joint_target_ticks", 15)
cartesian_target_ticks = _kernel(_cartesian_target, "cartesian_target_ticks", 25)
