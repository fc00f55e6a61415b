"""Laws compiled with the model terms they need, each tick in one call on the law's own
buffers: ``CartesianImpedance``'s step (the input filter, the end effector's Jacobian, the
law, the Coriolis torques), ``AppliedForce``'s and ``Force``'s (the filter, the Jacobian,
for ``Force`` its distance check, the gravity torques and its PI law), and the moves' and
the streamed targets' tracking, Cartesian
(``tracking.PoseImpedance``: the Jacobian, the mass matrix, the damping from the arm's
inertia, the tracking torque with its feed-forward, the Coriolis torques) and in joint
space (``tracking.joint_impedance_torque``: the impedance, the friction feed-forward, and
the inertial feed-forward with the Coriolis torques in one recursion).

The same kernels the separate calls run (:mod:`._kernels`' filter and laws, the
kinematics' Jacobian, the dynamics' recursions), called from one kernel: one dispatch a
tick where there were four or five, and none of the Python between them (in the loop,
where code runs on cold caches once a millisecond, that Python cost more than the
arithmetic). Their temporaries live on the stack (:mod:`panda_py.jit.stack`): a tick
allocates nothing.

Compiled with the kinematics' and the dynamics' kernels inside, so cached under a key over
all of their sources (:mod:`panda_py.jit.cache`): an edit to any of them compiles afresh.
Imported on first use (:func:`panda_py.controllers.laws.fused`) unless
``PANDA_PY_NO_JIT=1`` or numba is missing.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
from numba import types

from panda_py import dynamics, kinematics
from panda_py.controllers import _kernels, tracking
from panda_py.jit import cache, stack
from panda_py.jit.stack import stack_array
from panda_py.motion import online
from panda_py.robots.params import GRAVITY

_KIN = kinematics.compiled_kernels()
_DYN = dynamics.compiled_kernels()
_ONLINE = online.compiled_kernels()
if _KIN is None or _DYN is None or _ONLINE is None:  # plain Python: the separate calls run
    raise ImportError("the kinematics, the dynamics or the online generator run without numba")

__all__ = [
    "applied_force_step", "cartesian_impedance_step", "force_exceeded",
    "force_step", "joint_tracking_step", "pose_target_step", "pose_tracking_step", "warmup",
]  # fmt: skip

KEY = cache.source_key([
    Path(__file__), Path(_kernels.__file__), Path(_DYN.__file__), Path(tracking.__file__),
    Path(_ONLINE.__file__), Path(stack.__file__), *Path(_KIN.__file__).parent.glob("*.py"),
])  # fmt: skip
_jacobian_one = _KIN.jacobian_one
_rnea = _DYN.rnea
_crba = _DYN.crba
_mass_damping = _kernels.mass_damping
_tracking = _kernels.pose_tracking_torque
_pose_filter = _kernels.pose_filter
_torque = _kernels.cartesian_impedance_torque
_sample_pose = _ONLINE.sample_pose
_target_outputs = _kernels.pose_target_outputs
# tracking.PoseImpedance's buffer: the offsets of its arrays (constants, compiled in)
_L = tracking.LAW_LAYOUT
_SCALARS, _K, _D, _QN = _L["scalars"][0], _L["K"][0], _L["D"][0], _L["q_n"][0]
_ERR, _PINV, _J, _JP = _L["err"][0], _L["J_pinv"][0], _L["J"][0], _L["J_prev"][0]
_M, _VIS = _L["M"][0], _L["viscous"][0]
_ema = _kernels._ema
# the base's acceleration whose torques hold the arm against gravity [m/s^2]
# (dynamics.LoadedArm.gravity's)
_A0, _A1, _A2 = (-GRAVITY[0], -GRAVITY[1], -GRAVITY[2])
# Force's buffer (30 values: _builtin.Force's views): the filtered force (3) [N], k_p and
# k_i, the damping D (7) [Nm s/rad] and the threshold [m]; where it started: the end
# effector's position (3) [m] and the torque sensors' bias (7) [Nm]; the integral of the
# torque error (7) [Nm s]
_FORCE_F, _FORCE_GAINS, _FORCE_D, _FORCE_THRESHOLD = 0, 3, 5, 12
_FORCE_P0, _FORCE_BIAS, _FORCE_INTEGRAL = 13, 16, 23


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _jacobian_or_nan(q, chain, J, tau):  # type: ignore[no-untyped-def,unused-ignore]
    """The Jacobian to the end effector of ``chain`` into ``J`` (1, 6, 7); False, and NaN
    torques in ``tau``, where ``q`` is not finite."""
    if _jacobian_one(q, chain, False, J):
        return True
    for i in range(7):
        tau[i] = math.nan
    return False


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _add_inverse_dynamics(origin, ca, sa, mass, h, inertia, q, dq, ddq, tau):  # type: ignore[no-untyped-def,unused-ignore]
    """``tau += M(q) ddq + C(q, dq) dq`` of the arm ``origin ... inertia``: the recursion
    without gravity (one call, the arrays on the stack)."""
    out = stack_array(7)
    zero = stack_array(3)
    for k in range(3):
        zero[k] = 0.0
    _rnea(origin, ca, sa, mass, h, inertia, q, dq, ddq, zero, out)
    for i in range(7):
        tau[i] += out[i]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _add_coriolis(origin, ca, sa, mass, h, inertia, q, dq, tau):  # type: ignore[no-untyped-def,unused-ignore]
    """``tau += C(q, dq) dq`` of the arm ``origin ... inertia``."""
    zero = stack_array(7)
    for i in range(7):
        zero[i] = 0.0
    _add_inverse_dynamics(origin, ca, sa, mass, h, inertia, q, dq, zero, tau)


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def cartesian_impedance_step(  # type: ignore[no-untyped-def,unused-ignore]
    values, at, filtered, Kd_t, O_T_EE, q, dq, chain, origin, ca, sa, mass, h, inertia, J, tau
):  # fmt: skip
    """One tick of ``CartesianImpedance``: the filter moves ``filtered`` (K (6x6), Kd
    (6x6), p (3), quat (4), q_n (7), k_n) toward the inputs ``values`` (at the offsets
    ``at`` of position, orientation, q_nullspace, impedance, filter_coeff and
    nullspace_stiffness; the damping's target ``Kd_t`` computed by the caller when they
    change); the torque
    ``J^T (-K e - Kd J dq) + N (k_n (q_n - q) - 2 sqrt(k_n) dq) + C(q, dq) dq`` into
    ``tau`` (7,), with the Jacobian to the end effector of ``chain`` into ``J`` (1, 6, 7)
    and the Coriolis torques of the arm ``origin ... inertia``
    (``dynamics.LoadedArm.arrays``). NaN torques where ``q`` is not finite."""
    alpha = values[at[4]]
    K = filtered[0:36].reshape((6, 6))
    Kd = filtered[36:72].reshape((6, 6))
    p = filtered[72:75]
    quat = filtered[75:79]
    q_n = filtered[79:86]
    K_t = values[at[3] : at[3] + 36].reshape((6, 6))
    p_t = values[at[0] : at[0] + 3]
    quat_t = values[at[1] : at[1] + 4]
    q_n_t = values[at[2] : at[2] + 7]
    _pose_filter(alpha, K, K_t, Kd, Kd_t, p, p_t, q_n, q_n_t, quat, quat_t)
    filtered[86] += alpha * (values[at[5]] - filtered[86])
    if not _jacobian_or_nan(q, chain, J, tau):
        return
    _torque(O_T_EE, J[0], q, dq, p, quat, K, Kd, q_n, filtered[86], tau)
    _add_coriolis(origin, ca, sa, mass, h, inertia, q, dq, tau)


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def applied_force_step(values, at, applied, D, q, dq, chain, J, tau):  # type: ignore[no-untyped-def,unused-ignore]
    """One tick of ``AppliedForce``: the filter moves ``applied`` (the wrench (6) [N, Nm])
    and ``D`` (7) [Nm s/rad] toward the inputs ``values`` (at the offsets ``at`` of force,
    damping and filter_coeff); ``tau = J^T applied - D dq`` into ``tau`` (7,), the
    Jacobian to the end effector of ``chain`` into ``J`` (1, 6, 7). NaN torques where
    ``q`` is not finite."""
    alpha = values[at[2]]
    _ema(applied, values[at[0] : at[0] + 6], alpha)
    _ema(D, values[at[1] : at[1] + 7], alpha)
    if not _jacobian_or_nan(q, chain, J, tau):
        return
    for i in range(7):
        s = 0.0
        for k in range(6):
            s += J[0, k, i] * applied[k]
        tau[i] = s - D[i] * dq[i]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def force_exceeded(values, at, law, O_T_EE):  # type: ignore[no-untyped-def,unused-ignore]
    """``Force``'s abort condition of this tick, nothing changed: the distance [m] the end
    effector ``O_T_EE`` moved from where the law started (``law``: ``Force``'s
    buffer) where it exceeds the threshold after this tick's filter (the inputs
    ``values`` at the offsets ``at`` of force, k_p, damping, threshold and
    filter_coeff), else -1. (Not past it where the distance is NaN, as NumPy's ``>``.)"""
    thr = law[_FORCE_THRESHOLD]
    thr += values[at[4]] * (values[at[3]] - thr)
    d0 = O_T_EE[12] - law[_FORCE_P0]
    d1 = O_T_EE[13] - law[_FORCE_P0 + 1]
    d2 = O_T_EE[14] - law[_FORCE_P0 + 2]
    moved = math.sqrt(d0 * d0 + d1 * d1 + d2 * d2)
    return moved if moved > thr else -1.0


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def force_step(  # type: ignore[no-untyped-def,unused-ignore]
    values, at, law, t, dt, O_T_EE, q, dq, tau_J, chain, origin, ca, sa, mass, h, inertia, J,
    tau,
):  # fmt: skip
    """One tick of ``Force`` at its time ``t`` [s], ``dt`` [s] after the last, on its
    buffer ``law`` (``FORCE_*``): the filter moves the force, the gains, the damping and
    the threshold toward the inputs (as :func:`force_exceeded`); past the threshold (at
    ``t > 0``) it returns the distance moved [m] (the law aborts: ``tau`` untouched),
    else -1 with ``tau`` (7,): ``tau_d + k_p (tau_d - tau_ext) + k_i integral - D dq``,
    ``tau_d = J_v^T f``, ``tau_ext = tau_J - g(q) - bias``, the integral of ``tau_d -
    tau_ext`` advanced by ``dt``; the Jacobian of ``chain`` into ``J`` (1, 6, 7), the
    gravity torques of the arm ``origin ... inertia``. NaN torques where ``q`` is not
    finite."""
    moved = force_exceeded(values, at, law, O_T_EE)
    alpha = values[at[4]]
    _ema(law[_FORCE_F : _FORCE_F + 3], values[at[0] : at[0] + 3], alpha)
    _ema(law[_FORCE_GAINS : _FORCE_GAINS + 2], values[at[1] : at[1] + 2], alpha)  # k_p, k_i
    _ema(law[_FORCE_D : _FORCE_D + 7], values[at[2] : at[2] + 7], alpha)
    law[_FORCE_THRESHOLD] += alpha * (values[at[3]] - law[_FORCE_THRESHOLD])
    if t > 0.0 and moved >= 0.0:
        return moved
    if not _jacobian_or_nan(q, chain, J, tau):
        return -1.0
    g = stack_array(7)
    zero = stack_array(7)
    a = stack_array(3)
    for i in range(7):
        zero[i] = 0.0
    a[0], a[1], a[2] = _A0, _A1, _A2
    _rnea(origin, ca, sa, mass, h, inertia, q, zero, zero, a, g)
    k_p, k_i = law[_FORCE_GAINS], law[_FORCE_GAINS + 1]
    for i in range(7):
        tau_ext = tau_J[i] - g[i] - law[_FORCE_BIAS + i]
        tau_d = 0.0
        for k in range(3):
            tau_d += J[0, k, i] * law[_FORCE_F + k]
        law[_FORCE_INTEGRAL + i] += dt * (tau_d - tau_ext)
        tau[i] = (tau_d + k_p * (tau_d - tau_ext) + k_i * law[_FORCE_INTEGRAL + i]
                  - law[_FORCE_D + i] * dq[i])  # fmt: skip
    return -1.0


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def pose_tracking_step(  # type: ignore[no-untyped-def,unused-ignore]
    O_T_EE, q, dq, chain, origin, ca, sa, mass, h, inertia, armature, coulomb, p_d, quat_d,
    v_d, a_d, law, tau,
):  # fmt: skip
    """One tick of ``tracking.PoseImpedance`` with the Coriolis torques, into ``tau`` (7,),
    on the law's buffer ``law`` (``tracking.LAW_LAYOUT``: its scalars, K, D, q_n, err,
    J_pinv, J, J_prev, M, viscous): the Jacobian to the end effector of ``chain`` into J (the one
    it held copied to J_prev first, where the scalars say it is the previous tick's); where
    the scalars ask, the arm's mass matrix into M (``origin ... inertia``:
    ``dynamics.LoadedArm.arrays``) and the damping D from the arm's inertia
    (``_kernels.mass_damping``), else the last ones; the tracking torque
    (``_kernels.pose_tracking_torque``, its pose error into err, the pseudo-inverse into
    J_pinv) and ``C(q, dq) dq``. NaN torques where ``q`` is not finite."""
    scalars = law[_SCALARS : _SCALARS + 8]
    J = law[_J : _J + 42].reshape((1, 6, 7))
    J_prev = law[_JP : _JP + 42].reshape((1, 6, 7))
    has_prev = scalars[7] != 0.0
    if has_prev:  # (a loop: numba's slice assignment costs several times more)
        for i in range(42):
            law[_JP + i] = law[_J + i]
    if not _jacobian_or_nan(q, chain, J, tau):
        return
    K = law[_K : _K + 36].reshape((6, 6))
    D = law[_D : _D + 36].reshape((6, 6))
    M = law[_M : _M + 49].reshape((7, 7))
    if scalars[6] != 0.0:
        _crba(origin, ca, sa, mass, h, inertia, q, M)
        _mass_damping(K, scalars[2], M, armature, J[0], scalars[5], D)
    Jp = J_prev[0] if has_prev else J[0]
    dt, k_n, speed, rate = scalars[0], scalars[1], scalars[3], scalars[4]
    _tracking(O_T_EE, J[0], Jp, q, dq, dt, p_d, quat_d, v_d, a_d, K, D, law[_QN : _QN + 7],
              k_n, M, armature, coulomb, law[_VIS : _VIS + 7], speed, rate, tau,
              law[_ERR : _ERR + 6],
              law[_PINV : _PINV + 42].reshape((7, 6)))  # fmt: skip
    _add_coriolis(origin, ca, sa, mass, h, inertia, q, dq, tau)


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def pose_target_step(  # type: ignore[no-untyped-def,unused-ignore]
    tick, traj, p, v, a, Ft, Fr, R0, q0, position, orientation, twist, accel, O_T_EE, q, dq,
    chain, origin, ca, sa, mass, h, inertia, armature, coulomb, law, target, out, tau,
):  # fmt: skip
    """One tick of ``CartesianTarget`` in one call: its generator's compiled step
    (``_online_jit.sample_pose``: the trajectory ``traj`` sampled into ``p``, ``v``, ``a``
    and turned into the reference ``position``, ``orientation``, ``twist``, ``accel``),
    where ``tick`` asks for it, then :func:`pose_tracking_step` toward that reference and
    the controller's outputs (``_kernels.pose_target_outputs``, the distance to the
    ``target`` (7,: position, orientation)). ``tick``: 1 to sample (else the reference
    stands as it is), the trajectory's duration, the time to sample at [s], 1 if the
    targets went stale (else 0), and the outputs' offset in ``out``."""
    if tick[0] != 0.0:
        _sample_pose(traj, tick[1], tick[2], p, v, a, Ft, Fr, R0, q0, position, orientation,
                     twist, accel)  # fmt: skip
    pose_tracking_step(O_T_EE, q, dq, chain, origin, ca, sa, mass, h, inertia, armature,
                       coulomb, position, orientation, twist, accel, law, tau)  # fmt: skip
    _target_outputs(position, orientation, twist, target[0:3], target[3:7], tick[3] != 0.0,
                    out, int(tick[4]))  # fmt: skip


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def joint_tracking_step(  # type: ignore[no-untyped-def,unused-ignore]
    q, dq, origin, ca, sa, mass, h, inertia, armature, coulomb, K, D, q_d, dq_d, ddq_d,
    friction_speed, error_rate, tau,
):  # fmt: skip
    """``tracking.joint_impedance_torque`` with the Coriolis torques, into ``tau`` (7,):
    ``K (q_d - q) + D (dq_d - dq) + (M + diag(armature)) ddq_d + coulomb tanh((dq_d +
    error_rate (q_d - q)) / friction_speed) + C(q, dq) dq``, ``M`` the arm's mass matrix
    (``origin ... inertia``: ``dynamics.LoadedArm.arrays``). ``M ddq_d + C dq`` is one
    recursion without gravity (``rnea(q, dq, ddq_d)``), not the mass matrix and a
    product plus a second recursion: the same torques for a third of the arithmetic."""
    for i in range(7):
        e = q_d[i] - q[i]
        acc = K[i] * e + D[i] * (dq_d[i] - dq[i]) + armature[i] * ddq_d[i]
        v = (dq_d[i] + error_rate * e) / friction_speed
        tau[i] = acc + coulomb[i] * math.tanh(v)
    _add_inverse_dynamics(origin, ca, sa, mass, h, inertia, q, dq, ddq_d, tau)


# One signature each, compiled (or loaded) at import, and no other: an input read-only
# (a state's field, a plan sent from the user's process) or writable (the laws' own
# buffers) is taken by the same code, and a call of any other type raises a TypeError
# instead of stopping the loop for seconds to compile (a joint move fed from its plan and
# then from its lead-in once did, in the middle of a motion, ending in a reflex).
_F8 = types.float64


def _in(ndim: int) -> types.Array:
    return types.Array(_F8, ndim, "C", readonly=True)


def _out(ndim: int) -> types.Array:
    return types.Array(_F8, ndim, "C")


_ARM = (_in(2), _in(1), _in(1), _in(1), _in(2), _in(3))  # LoadedArm.arrays
_AT = types.Array(types.int64, 1, "C", readonly=True)  # the inputs' offsets
_SIGNATURES = {
    cartesian_impedance_step: (
        _in(1), _AT, _out(1), _in(2), _in(1), _in(1), _in(1), _in(1), *_ARM, _out(3), _out(1),
    ),
    applied_force_step: (_in(1), _AT, _out(1), _out(1), _in(1), _in(1), _in(1), _out(3), _out(1)),
    force_exceeded: (_in(1), _AT, _out(1), _in(1)),
    force_step: (
        _in(1), _AT, _out(1), _F8, _F8, _in(1), _in(1), _in(1), _in(1), _in(1), *_ARM, _out(3),
        _out(1),
    ),
    pose_tracking_step: (
        _in(1), _in(1), _in(1), _in(1), *_ARM, _in(1), _in(1), _in(1), _in(1), _in(1), _in(1),
        _out(1), _out(1),
    ),
    pose_target_step: (
        _in(1), _in(2), _out(1), _out(1), _out(1), _in(2), _in(2), _in(2), _in(1), _out(1),
        _out(1), _out(1), _out(1), _in(1), _in(1), _in(1), _in(1), *_ARM, _in(1), _in(1),
        _out(1), _in(1), _out(1), _out(1),
    ),
    joint_tracking_step: (
        _in(1), _in(1), *_ARM, _in(1), _in(1), _in(1), _in(1), _in(1), _in(1), _in(1), _F8,
        _F8, _out(1),
    ),
}  # fmt: skip
for _kernel, _signature in _SIGNATURES.items():
    _kernel.compile(_signature)
    _kernel.disable_compile()


def warmup() -> None:
    """Run each kernel once (they are compiled or loaded at import, for one signature
    each), on inputs as the loop has them: the laws' own buffers, and the state's fields
    as a ``TickState`` has them (read-only)."""
    from panda_py.controllers import _builtin

    state = np.zeros(7), np.zeros(7), np.eye(4).reshape(16)
    for a in state:
        a.flags.writeable = False
    q, dq, O_T_EE = state
    ctrl = _builtin.CartesianImpedance()
    at = np.array([ctrl._sig_layout[n][0] for n in _builtin._FUSED_SIGNALS], dtype=np.int64)
    filtered = np.zeros(_builtin._FILTERED_SIZE)
    filtered[78] = 1.0  # a unit quaternion
    arm = dynamics.LoadedArm("fer")
    chain = kinematics.get_kinematics("fer").chain_constants
    cartesian_impedance_step(ctrl._values, at, filtered, np.eye(6), O_T_EE, q, dq, chain,
                             *arm.arrays, np.empty((1, 6, 7)), np.empty(7))  # fmt: skip
    applied = _builtin.AppliedForce()
    at = np.array([applied._sig_layout[n][0] for n in _builtin._APPLIED_SIGNALS])
    applied_force_step(applied._values, at, np.zeros(6), np.zeros(7), q, dq, chain,
                       np.empty((1, 6, 7)), np.empty(7))  # fmt: skip
    force = _builtin.Force()
    at = np.array([force._sig_layout[n][0] for n in _builtin._FORCE_SIGNALS])
    law_buffer = np.zeros(_builtin._FORCE_SIZE)
    force_exceeded(force._values, at, law_buffer, O_T_EE)
    force_step(force._values, at, law_buffer, 1e-3, 1e-3, O_T_EE, q, dq, q, chain, *arm.arrays,
               np.empty((1, 6, 7)), np.empty(7))  # fmt: skip
    z6 = np.zeros(6)
    law = tracking.PoseImpedance(np.eye(6), 1.0, np.zeros(7), 1.0)
    buf = law.compiled_inputs(1e-3)
    z7 = np.zeros(7)
    joint_tracking_step(q, dq, *arm.arrays, z7, z7, z7 + 1.0, z7 + 1.0, z7, z7, z7, 0.01, 10.0,
                        np.empty(7))  # fmt: skip
    quat = np.array([0.0, 0.0, 0.0, 1.0])
    pose_tracking_step(O_T_EE, q, dq, chain, *arm.arrays, np.zeros(7), np.zeros(7),
                       np.zeros(3), quat, z6, z6.copy(), buf, np.empty(7))  # fmt: skip
    traj, I3 = np.zeros((6, _ONLINE.ROW)), np.eye(3)
    tick = np.array([1.0, 0.0, 0.0, 0.0, 0.0])
    pose_target_step(tick, traj, z6.copy(), z6.copy(), z6.copy(), I3, I3, I3, quat, np.zeros(3),
                     quat.copy(), z6.copy(), z6.copy(), O_T_EE, q, dq, chain, *arm.arrays,
                     np.zeros(7), np.zeros(7), buf, np.zeros(7), np.zeros(20),
                     np.empty(7))  # fmt: skip
