"""The simulator's per-tick arithmetic compiled by numba: the robot state's per-tick fields,
the checks every received command and every motion tick pass through, the commanded
joint signal's derivatives and limits, and the robot's joint impedance controller.

Each kernel does, value for value, what the plain NumPy reference does
(:meth:`StateAssembly._fill_state_reference`, :meth:`RobotCore._accept`,
:meth:`RobotCore._motion_tick`, :class:`~panda_py.sim.safety.JointSignal`,
:meth:`~panda_py.sim.physics.Physics.joint_tracking_torque`); one call replaces a few
dozen NumPy calls on 7-vectors, whose fixed cost (about 0.5 us each) was most of a tick.
``tests/sim/test_sim_tick_jit.py`` holds them equal bit for bit (the controller to
rounding: its matrix product sums in an order of its own).
Imported by :mod:`.fastpath` only when the kinematics run compiled (numba installed,
``PANDA_PY_NO_JIT`` unset); compiled once per machine (about 3 s, when the first simulator
starts) and cached on disk under a key over this file (:mod:`panda_py.jit.cache`); the
kernels call nothing compiled elsewhere.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from panda_py.jit import cache

__all__ = [
    "FIELDS", "all_finite", "fill_state", "joint_limit_bits", "joint_push", "joint_tracking",
    "measured_in_limits", "torque_in_limits",
]  # fmt: skip

# the compile cache's key: the kernels compile this file alone (panda_py.jit.cache)
KEY = cache.source_key([Path(__file__)])

# The state fields the kernel writes, in the order of its offset vector ``off``.
FIELDS = (
    "O_T_EE", "O_T_EE_d", "elbow", "elbow_d", "elbow_c", "delbow_c", "ddelbow_c",
    "O_T_EE_c", "O_dP_EE_d", "O_dP_EE_c", "O_ddP_EE_c", "tau_J", "dtau_J", "tau_J_d",
    "q", "dq", "theta", "dtheta", "q_d", "dq_d", "ddq_d", "accelerometer_top",
    "accelerometer_bottom",
)  # fmt: skip
(
    _O_T_EE, _O_T_EE_D, _ELBOW, _ELBOW_D, _ELBOW_C, _DELBOW_C, _DDELBOW_C, _O_T_EE_C,
    _O_DP_EE_D, _O_DP_EE_C, _O_DDP_EE_C, _TAU_J, _DTAU_J, _TAU_J_D, _Q, _DQ, _THETA,
    _DTHETA, _Q_D, _DQ_D, _DDQ_D, _ACC_TOP, _ACC_BOTTOM,
) = range(len(FIELDS))  # fmt: skip

# flags of fill_state
MOVING_JOINT = 1  # a joint motion generator runs
MOVING_CARTESIAN = 2  # a Cartesian motion generator runs
MODE_CHANGED = 4  # the generator differs from the last fill's: write the held zeros


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _put_col_major(sb, at, T):  # type: ignore[no-untyped-def,unused-ignore]
    for c in range(4):
        for r in range(4):
            sb[at + 4 * c + r] = T[r, c]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def fill_state(  # type: ignore[no-untyped-def,unused-ignore]
    sb, off, q, dq, tau_applied, gravcomp, dq_before, drive, constraint, tau_J_d, jq, jdq,
    jddq, q_hold, cart_T, cart_v, cart_a, elbow_c, delbow_c, ddelbow_c, fk, xmat, links,
    const, flags,
):  # fmt: skip
    """The per-tick fields into the state buffer ``sb`` (float64, field ``i`` of FIELDS
    at ``off[i]``). ``fk`` (2, 4, 4): O_T_EE of the measured joints and, outside a
    Cartesian motion, of the desired ones ``jq``; ``xmat``: MuJoCo's body rotations,
    ``links`` the bodies of links 1..6; ``const``: (elbow flip q4 [rad], 1 / DT [1/s],
    -gravity z [m/s^2]). tau_J as ``Physics.sensor_torque`` (``dq_before`` the joint
    velocities before the step, ``drive`` its rotor inertia and viscous friction rows,
    ``constraint`` the arm's constraint forces), the contacts' part left to the
    reference."""
    flip, inv_dt, minus_gz = const[0], const[1], const[2]
    moving_cart = (flags & MOVING_CARTESIAN) != 0
    moving = moving_cart or (flags & MOVING_JOINT) != 0
    changed = (flags & MODE_CHANGED) != 0
    _put_col_major(sb, off[_O_T_EE], fk[0])
    at = off[_O_T_EE_D]
    if moving_cart:
        _put_col_major(sb, at, cart_T)
    else:
        _put_col_major(sb, at, fk[1])
    e = off[_ELBOW]
    sb[e] = q[2]
    sb[e + 1] = 1.0 if q[3] > flip else -1.0
    ed = off[_ELBOW_D]
    sb[ed] = jq[2]
    sb[ed + 1] = 1.0 if jq[3] > flip else -1.0
    ec = off[_ELBOW_C]
    if moving_cart:
        dc, ddc = off[_DELBOW_C], off[_DDELBOW_C]
        for i in range(2):
            sb[ec + i] = elbow_c[i]
            sb[dc + i] = delbow_c[i]
            sb[ddc + i] = ddelbow_c[i]
        _put_col_major(sb, off[_O_T_EE_C], cart_T)
        pd, pc, ac = off[_O_DP_EE_D], off[_O_DP_EE_C], off[_O_DDP_EE_C]
        for i in range(6):
            sb[pd + i] = cart_v[i]
            sb[pc + i] = cart_v[i]
            sb[ac + i] = cart_a[i]
    else:
        sb[ec] = sb[ed]
        sb[ec + 1] = sb[ed + 1]
        tc = off[_O_T_EE_C]
        for i in range(16):
            sb[tc + i] = sb[at + i]
        if changed:  # zeros stand until a Cartesian motion
            for f, n in ((_DELBOW_C, 2), (_DDELBOW_C, 2), (_O_DP_EE_D, 6), (_O_DP_EE_C, 6),
                         (_O_DDP_EE_C, 6)):  # fmt: skip
                s = off[f]
                for i in range(n):
                    sb[s + i] = 0.0
    tj, dtj, tjd = off[_TAU_J], off[_DTAU_J], off[_TAU_J_D]
    o_q, o_dq, o_th, o_dth = off[_Q], off[_DQ], off[_THETA], off[_DTHETA]
    o_qd, o_dqd, o_ddqd = off[_Q_D], off[_DQ_D], off[_DDQ_D]
    for i in range(7):
        tau = (dq[i] - dq_before[i]) * (-inv_dt * drive[0, i])
        tau = tau + tau_applied[i]
        tau = tau + gravcomp[i]
        tau = tau - drive[1, i] * dq[i]
        tau = tau + constraint[i]
        sb[dtj + i] = (tau - sb[tj + i]) * inv_dt
        sb[tj + i] = tau
        sb[tjd + i] = tau_J_d[i]
        sb[o_q + i] = q[i]
        sb[o_dq + i] = dq[i]
        sb[o_th + i] = q[i]
        sb[o_dth + i] = dq[i]
        if moving:
            sb[o_qd + i] = jq[i]
            sb[o_dqd + i] = jdq[i]
            sb[o_ddqd + i] = jddq[i]
        else:
            sb[o_qd + i] = q_hold[i]
            if changed:
                sb[o_dqd + i] = 0.0
                sb[o_ddqd + i] = 0.0
    # Accelerometers of links 1..6: -g_z times the third row of each link's rotation.
    top, bottom = off[_ACC_TOP], off[_ACC_BOTTOM]
    for k in range(6):
        b = links[k]
        for j in range(3):
            v = xmat[b, 6 + j] * minus_gz
            sb[top + 3 * k + j] = v
            sb[bottom + 3 * k + j] = v


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def torque_in_limits(tau, tau_J_d, tau_max, dtau_step):  # type: ignore[no-untyped-def,unused-ignore]
    """|tau| <= tau_max and |tau - tau_J_d| <= dtau_step on every joint (False for a NaN)."""
    for i in range(7):
        if not (abs(tau[i]) <= tau_max[i] and abs(tau[i] - tau_J_d[i]) <= dtau_step[i]):
            return False
    return True


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def measured_in_limits(q, dq, q_lo, q_hi, dq_hi):  # type: ignore[no-untyped-def,unused-ignore]
    """No joint below q_lo, above q_hi or faster than dq_hi (a NaN passes, as in the
    NumPy reference, whose comparisons are all False for it)."""
    for i in range(7):
        if q[i] < q_lo[i] or q[i] > q_hi[i] or abs(dq[i]) > dq_hi[i]:
            return False
    return True


# kinds of joint_push
PUSH_POSITION = 0  # x: the commanded positions [rad]
PUSH_VELOCITY = 1  # x: the commanded velocities [rad/s]
EXTRAPOLATE = 2  # a lost command: keep the acceleration (x unused)


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def joint_push(q, dq, ddq, dddq, x, kind, dt):  # type: ignore[no-untyped-def,unused-ignore]
    """:class:`~panda_py.sim.safety.JointSignal`'s backward-Euler update, in place, with
    its arithmetic operation for operation (``kind``: PUSH_POSITION, PUSH_VELOCITY or
    EXTRAPOLATE)."""
    for i in range(7):
        if kind == PUSH_POSITION:
            q_new = x[i]
            dq_new = (q_new - q[i]) / dt
        elif kind == PUSH_VELOCITY:
            dq_new = x[i]
            q_new = q[i] + dq_new * dt
        else:
            dq_new = dq[i] + ddq[i] * dt
            q_new = q[i] + dq_new * dt
        ddq_new = (dq_new - dq[i]) / dt
        dddq[i] = (ddq_new - ddq[i]) / dt
        ddq[i] = ddq_new
        dq[i] = dq_new
        q[i] = q_new


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def joint_limit_bits(q, dq, ddq, dddq, upper, lower):  # type: ignore[no-untyped-def,unused-ignore]
    """Which joint limits a commanded signal breaks: bit 0 position (below ``lower`` or
    above ``upper[7:14]``), bit 1 velocity, bit 2 acceleration, bit 3 jerk (``upper``
    as ``safety._Limits.upper``: q_max twice, then |dq|, |ddq|, |dddq| limits). A NaN
    breaks none, as in the NumPy reference."""
    bits = 0
    for i in range(7):
        if q[i] < lower[i] or q[i] > upper[7 + i]:
            bits |= 1
        if abs(dq[i]) > upper[14 + i]:
            bits |= 2
        if abs(ddq[i]) > upper[21 + i]:
            bits |= 4
        if abs(dddq[i]) > upper[28 + i]:
            bits |= 8
    return bits


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def all_finite(x):  # type: ignore[no-untyped-def,unused-ignore]
    """No NaN and no infinity in the vector ``x``."""
    for i in range(x.shape[0]):
        if not math.isfinite(x[i]):
            return False
    return True


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def joint_tracking(  # type: ignore[no-untyped-def,unused-ignore]
    M, bias, grav, q, dq, q_d, dq_d, ddq_d, K_theta, K_default, coulomb, omega, fs_inv, out
):  # fmt: skip
    """The robot's joint impedance controller tracking (q_d, dq_d, ddq_d) into ``out``, as
    :meth:`~panda_py.sim.physics.Physics.joint_tracking_torque` with its friction
    compensation: stiffness scaled by max(K_theta / K_default, 1e-3), computed torque
    ``M acc + (bias - grav)`` (``M`` the arm's mass matrix, ``bias`` MuJoCo's bias force,
    ``grav`` its gravity compensation), then the dry friction cancelled (``coulomb``,
    ``fs_inv`` one over the friction's speed). Operation for operation but the matrix
    product's sum, whose order BLAS chooses: equal to the reference to rounding."""
    acc = np.empty(7)
    kp_gain = omega * omega
    kd_gain = 2.0 * omega
    for i in range(7):
        scale = max(K_theta[i] / K_default[i], 1e-3)
        kp = kp_gain * scale
        kd = kd_gain * math.sqrt(scale)
        acc[i] = ddq_d[i] + kp * (q_d[i] - q[i]) + kd * (dq_d[i] - dq[i])
    for i in range(7):
        tau = 0.0
        for j in range(7):
            tau += M[i, j] * acc[j]
        tau += bias[i] - grav[i]
        c = coulomb[i]
        moving = math.tanh(dq[i] * fs_inv)
        still = min(max(tau, -c), c)
        out[i] = tau + (c * moving + (1.0 - abs(moving)) * still)
