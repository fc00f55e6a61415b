"""The :class:`Kinematics` of one arm with one end effector: fk, frames, Jacobians and the
analytical ik, for single configurations and for batches.

A facade: the arithmetic is :mod:`._fk` and :mod:`._ik` (written once, run compiled or
plain, see :mod:`._backend`); ik's arguments are sorted by :mod:`._args`. Single calls
with float64 arrays take a short path to the one-pose kernels (or, plain, to the scalar
functions themselves); everything else goes through the batch entry points.
"""

from __future__ import annotations

import enum
import math
import struct
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py.kinematics import _args, _backend, _fk, _ik, _input
from panda_py.kinematics._args import DEFAULT_Q7
from panda_py.robots.params import FRANKA_HAND, START_POSE, RobotSpec, get_robot

__all__ = ["DEFAULT_Q7", "Q7_SEARCH_STEP", "IKResult", "IKStatus", "Kinematics", "hand_F_T_EE"]

Q7_SEARCH_STEP = _ik.Q7_SEARCH_STEP
"""The step [rad] of the ``q_7`` search (``q7_search``): candidates ``q_7 +- k * step``, nearest
first."""
# A flange-to-EE transform whose rotation is this close [-] to a z rotation and whose
# translation this close [m] to the z axis keeps the ik target on joint 7's axis (the
# He-Liu geometry then takes it directly; any other EE is first mapped to the flange).
_Z_ONLY_TOL = 1e-15

FloatArray = NDArray[np.float64]
_F64 = np.dtype(np.float64)

# struct packs floats straight into a fresh array: ~4x faster than np.array(list)
_PACK16: Callable[..., None] = struct.Struct("16d").pack_into
_PACK7: Callable[..., None] = struct.Struct("7d").pack_into
_PACK28: Callable[..., None] = struct.Struct("28d").pack_into
_PACK42: Callable[..., None] = struct.Struct("42d").pack_into


class IKStatus(enum.IntEnum):
    """Why an ik branch has (no) solution."""

    OK = _ik.OK
    UNREACHABLE = _ik.UNREACHABLE  # the wrist point is out of the arm's reach for this q7
    JOINT_LIMIT = _ik.JOINT_LIMIT  # the geometry solves, but a joint (or q7) is out of limits
    SINGULAR = _ik.SINGULAR  # the shoulder lies on the joint-6 axis: q6 is undefined


@dataclass(frozen=True)
class IKResult:
    """Outcome of :meth:`Kinematics.ik_result`.

    Single pose: ``q`` (7,) [rad], the solution in the case of ``q_init`` (NaN if none);
    ``status`` its :class:`IKStatus`; ``solutions`` (4, 7) all four branches (as
    ``ik_full``); ``statuses`` their four statuses; ``q_7`` [rad] the q7 used (differs from
    the requested one only after a successful ``q7_search``). Batches add a leading N axis
    and hold statuses as int8 arrays of :class:`IKStatus` values.
    """

    q: FloatArray
    status: Any
    solutions: FloatArray
    statuses: Any
    q_7: Any

    @property
    def ok(self) -> Any:
        """True where ``q`` is a solution."""
        if isinstance(self.status, np.ndarray):
            return self.status == IKStatus.OK
        return self.status == IKStatus.OK


def hand_F_T_EE() -> FloatArray:
    """The Franka Hand's TCP relative to the flange: ``TransZ(0.1034) RotZ(-pi/4)``."""
    c, s = math.cos(FRANKA_HAND.tcp_rotz), math.sin(FRANKA_HAND.tcp_rotz)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[2, 3] = FRANKA_HAND.tcp_offset
    return T


def _z_only(F_T_EE: FloatArray) -> bool:
    """F_T_EE a rotation about and a translation along the flange's z axis."""
    R, p = F_T_EE[:3, :3], F_T_EE[:3, 3]
    return bool(
        abs(R[2, 2] - 1.0) <= _Z_ONLY_TOL
        and np.abs(R[:2, 2]).max() <= _Z_ONLY_TOL
        and np.abs(R[2, :2]).max() <= _Z_ONLY_TOL
        and np.abs(p[:2]).max() <= _Z_ONLY_TOL
    )


class Kinematics:
    """Kinematics of one arm (``robot``: "fer"/"panda", "fr3", "fr3-pre-5.9"; the joint
    limits ik respects) with one end effector (``F_T_EE``: flange-to-EE transform, default
    the Franka Hand's TCP). The DH geometry is the same for all Franka arms."""

    def __init__(self, robot: str | RobotSpec = "fer", *, F_T_EE: object = None) -> None:
        self.robot: RobotSpec = get_robot(robot)  # ValueError for an unknown name
        if F_T_EE is None:
            T = hand_F_T_EE()
        else:
            T = _input.transforms("F_T_EE", F_T_EE)
            if T.ndim != 2:
                raise ValueError(f"F_T_EE: expected one 4x4 transform, got shape {T.shape}")
            T = T.copy()
        T.setflags(write=False)
        self.F_T_EE: FloatArray = T
        dh = self.robot.dh
        self._chain = _fk.make_chain(dh, T)
        self._CF = _fk.pack_chain(self._chain)
        # ik: the He-Liu geometry needs a target on joint 7's z axis; any other EE is first
        # mapped back to the flange.
        if dh.a[4] != -dh.a[3] or any(dh.a[i] != 0.0 for i in (0, 1, 2, 5)):
            raise ValueError("robot: the analytical ik needs the Franka DH structure")
        if _z_only(T):
            d_e, theta_e = dh.flange_d + float(T[2, 3]), math.atan2(T[1, 0], T[0, 0])
            self._EE_T_F: FloatArray | None = None
        else:
            d_e, theta_e = dh.flange_d, 0.0
            self._EE_T_F = np.asarray(np.linalg.inv(T), dtype=np.float64)
        j = self.robot.joints
        self._ik_params = _ik.ik_params(
            dh.d[0], dh.d[2], dh.d[4], dh.a[3], dh.a[6], d_e, theta_e, j.q_min, j.q_max
        )
        self._P = _ik.pack_ik_params(self._ik_params)
        self._start = np.array(START_POSE)
        self.q_min: FloatArray = np.array(j.q_min)
        self.q_max: FloatArray = np.array(j.q_max)

    def __repr__(self) -> str:
        return f"Kinematics(robot={self.robot.name!r}, F_T_EE={self.F_T_EE.tolist()!r})"

    # ---------------------------------------------------------------- forward kinematics

    @property
    def chain_constants(self) -> FloatArray:
        """The arm's chain to this end effector, packed as the compiled kernels take it
        (shared: not to be changed), for a compiled loop that calls
        :func:`compiled_kernels` itself."""
        return self._CF

    def fk(self, q: object) -> FloatArray:
        """``O_T_EE`` (4, 4) for joint positions q (7,) [rad]; a batch (N, 7) gives
        (N, 4, 4). Translations in [m]."""
        if type(q) is np.ndarray and q.dtype is _F64 and q.ndim == 1:
            out = self._fk_one(q)
            if out is not None:
                return out
        qa = _input.joints("q", q)
        qb = np.ascontiguousarray(qa.reshape(-1, 7))
        out = np.empty((qb.shape[0], 4, 4))
        _backend.fk(qb, self._CF, out)
        return out[0] if qa.ndim == 1 else out

    def _fk_one(self, q: FloatArray) -> FloatArray | None:
        """O_T_EE of a float64 vector, or None for the validating path."""
        jit = _backend.jit()
        out = np.empty((4, 4))
        if jit is not None:
            try:
                if jit.single("fk_one")(q, self._CF, out):
                    return out
            except (TypeError, ValueError):  # not a float64 vector
                pass
            return None
        if q.shape != (7,):
            return None
        v = q.tolist()
        s = v[0] + v[1] + v[2] + v[3] + v[4] + v[5] + v[6]
        if s - s != 0.0:  # a NaN or infinity
            return None
        _PACK16(out, 0, *_fk.ee_pose(self._chain, v), 0.0, 0.0, 0.0, 1.0)
        return out

    def fk_frames(self, q: object) -> FloatArray:
        """Poses of J1..J7, the flange and the EE (libfranka's ``Frame`` order) in the base
        frame: (9, 4, 4) for q (7,) [rad], (N, 9, 4, 4) for a batch (N, 7)."""
        qa = _input.joints("q", q)
        qb = np.ascontiguousarray(qa.reshape(-1, 7))
        out = np.empty((qb.shape[0], 9, 4, 4))
        _backend.frames(qb, self._CF, out)
        return out[0] if qa.ndim == 1 else out

    def zero_jacobian(self, q: object) -> FloatArray:
        """Geometric Jacobian of the EE expressed in the base frame, (6, 7) for q (7,) [rad]
        (rows: linear [m/s per rad/s], then angular [rad/s per rad/s]); (N, 6, 7) for a
        batch (N, 7). libfranka's ``zeroJacobian(Frame::kEndEffector)``."""
        return self._jacobians(q, body=False)

    def follow(
        self, poses: object, q_start: object, *, damping: float = 0.0, iterations: int = 2
    ) -> FloatArray:
        """Configurations (N, 7) that follow the poses (N, 4, 4), in order, from
        ``q_start`` (7,) [rad] the way a Cartesian law's ``J^+`` moves the arm: each the
        one before moved by ``iterations`` damped least-squares steps (``damping`` [-],
        the pseudo-inverse's) toward its pose. Continuous where :meth:`ik`'s case ends or
        splits joints 1 and 3 anew (q2 = 0), and q7 moves as the arm's would."""
        T = _input.transforms("poses", poses)
        q = _input.joints("q_start", q_start)
        if T.ndim != 3 or q.ndim != 1:
            raise ValueError(
                f"poses, q_start: expected a batch of poses (N, 4, 4) and one configuration "
                f"(7,), got shapes {T.shape} and {q.shape}"
            )
        damping = _input.nonnegative("damping", damping, "-")
        if isinstance(iterations, bool) or not isinstance(iterations, int) or iterations < 1:
            raise ValueError(f"iterations: expected an int >= 1, got {iterations!r}")
        out = np.empty((T.shape[0], 7))
        Tb = np.ascontiguousarray(T, dtype=np.float64)
        _backend.follow(Tb, self._CF, np.ascontiguousarray(q), damping, iterations, out)
        return out

    def body_jacobian(self, q: object) -> FloatArray:
        """Geometric Jacobian of the EE expressed in the EE frame, (6, 7) or (N, 6, 7).
        libfranka's ``bodyJacobian(Frame::kEndEffector)``."""
        return self._jacobians(q, body=True)

    def _jacobians(self, q: object, body: bool) -> FloatArray:
        jit = _backend.jit()
        if (
            jit is not None
            and type(q) is np.ndarray
            and q.dtype is _F64
            and q.shape == (7,)
            and q.flags.c_contiguous
        ):
            out = np.empty((1, 6, 7))
            if jit.jacobian_one(q, self._CF, body, out):
                return out[0]
        elif jit is None and type(q) is np.ndarray and q.dtype is _F64 and q.shape == (7,):
            v = q.tolist()
            s = v[0] + v[1] + v[2] + v[3] + v[4] + v[5] + v[6]
            if s - s == 0.0:  # finite
                # columns packed as the rows of the transpose
                out = np.empty((7, 6))
                _PACK42(
                    out, 0, *(x for col in _fk.jacobian_columns(self._chain, v, body) for x in col)
                )
                return out.T.copy()
        qa = _input.joints("q", q)
        qb = np.ascontiguousarray(qa.reshape(-1, 7))
        out = np.empty((qb.shape[0], 6, 7))
        _backend.jacobian(qb, self._CF, body, out)
        return out[0] if qa.ndim == 1 else out

    # ---------------------------------------------------------------- inverse kinematics

    def ik(self, *args: Any, **kwargs: Any) -> FloatArray:
        """See :func:`panda_py.kinematics.ik`."""
        if 1 <= len(args) <= 3 and (not kwargs or kwargs.keys() == {"q7_search"}):
            q = self._ik_fast(*args, radius=kwargs.get("q7_search", 0.0))
            if q is not None:
                return q
        return self._ik_general(False, *args, **kwargs)

    def ik_full(self, *args: Any, **kwargs: Any) -> FloatArray:
        """See :func:`panda_py.kinematics.ik_full`."""
        if 1 <= len(args) <= 3 and (not kwargs or kwargs.keys() == {"q7_search"}):
            q = self._ik_fast(*args, full=True, radius=kwargs.get("q7_search", 0.0))
            if q is not None:
                return q
        return self._ik_general(True, *args, **kwargs)

    def _ik_fast(
        self,
        O_T_EE: Any,
        q_init: Any = None,
        q_7: Any = DEFAULT_Q7,
        *,
        full: bool = False,
        radius: Any = 0.0,
    ) -> FloatArray | None:
        """One 4x4 float64 pose, a float64 q_init (or None), a real q_7 and a float q7
        search radius >= 0 [rad]: the solution, or None for the general path (which also
        words the error for bad input)."""
        if self._EE_T_F is not None or not (type(radius) is float and radius >= 0.0):
            return None
        qi = self._start if q_init is None else q_init
        if not (
            type(O_T_EE) is np.ndarray
            and O_T_EE.dtype is _F64
            and type(qi) is np.ndarray
            and qi.dtype is _F64
        ):
            return None  # (numba's TypeError would cost ~100 us to word)
        jit = _backend.jit()
        if jit is not None:
            out = np.empty((4, 7) if full else 7)
            try:
                kernel = jit.single("ik_full_one" if full else "ik_one")
                if kernel(self._P, O_T_EE, qi, q_7, radius, out):
                    return out
            except (TypeError, ValueError):  # not a number / of the wrong shape
                pass
            return None
        if O_T_EE.shape != (4, 4) or qi.shape != (7,) or not isinstance(q_7, (float, int)):
            return None
        (r00, r01, r02, px), (r10, r11, r12, py), (r20, r21, r22, pz), last = O_T_EE.tolist()
        q1, q2, q3, q4, q5, q6, q7i = qi.tolist()
        q7 = float(q_7)
        err = _ik.rigid_error(r00, r01, r02, px, r10, r11, r12, py, r20, r21, r22, pz, *last)
        s = q7 + q1 + q2 + q3 + q4 + q5 + q6 + q7i
        if not (err <= _ik.ROTATION_TOL and s - s == 0.0):
            return None
        row = _ik.case_row(q2, q5)
        if radius > 0.0:
            q7 = _ik.search_q7(
                self._ik_params, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, q7, q1,
                row, radius,
            )  # fmt: skip
        first = 0 if full else row
        rows = _ik.solve(
            self._ik_params, r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, q7, q1,
            first, full,
        )  # fmt: skip
        if full:
            out = np.empty((4, 7))
            _PACK28(out, 0, *rows[0][1], *rows[1][1], *rows[2][1], *rows[3][1])
            return out
        out = np.empty(7)
        _PACK7(out, 0, *rows[0][1])
        return out

    def _ik_general(
        self,
        full: bool,
        *args: Any,
        O_T_EE: Any = None,
        position: Any = None,
        orientation: Any = None,
        q_init: Any = None,
        q_7: Any = None,
        q7_search: float = 0.0,
    ) -> FloatArray:
        """ik (full: ik_full) with every overload and keyword, single or batched."""
        search = _args.search_radius(q7_search)
        T, qi, q7 = _args.parse_ik(args, O_T_EE, position, orientation, q_init, q_7)
        return self._solve(T, qi, q7, full, search)[0]

    def _solve(
        self, T: FloatArray, qi: FloatArray, q7: FloatArray, full: bool, search: float = 0.0
    ) -> tuple[FloatArray, NDArray[np.int8], FloatArray]:
        """Solutions, statuses and the q7 solved for of T (4, 4) or (N, 4, 4), q_init (7,)
        or (N, 7), q7 () or (N,): (7,), () and () (``full``: (4, 7), (4,) and ()), with a
        leading N for a batch; ``search`` > 0 [rad]: at the q7 nearest q7 within it with a
        solution in q_init's case (``_ik.search_q7``). A ValueError names the first pose,
        q_init or q7 that is not valid."""
        single = T.ndim == 2
        Tb = np.ascontiguousarray(T.reshape(-1, 4, 4), dtype=np.float64)
        n = Tb.shape[0]
        if self._EE_T_F is not None:  # test the given poses, then solve for the flange
            _input.check_rigid("O_T_EE", T)
            _input.check_finite("q_init", qi, 1)
            _input.check_finite("q_7", q7, 0)
            Tb = np.ascontiguousarray(Tb @ self._EE_T_F)
        m = 4 * n if full else n
        qout = np.empty((m, 7))
        st = np.empty(m, dtype=np.int8)
        q7out = np.empty(n)
        QI = np.ascontiguousarray(qi.reshape(-1, 7), dtype=np.float64)
        Q7 = np.ascontiguousarray(q7.reshape(-1), dtype=np.float64)
        _backend.ik(self._P, Tb, QI, Q7, search, full, qout, st, q7out)
        first = st[::4] if full else st
        if n and first.min() < 0:
            _args.raise_invalid(T, qi, q7, int(np.argmax(first < 0)))
        sols = qout.reshape((n, 4, 7) if full else (n, 7))
        stats = st.reshape((n, 4) if full else (n,))
        return (sols[0], stats[0], q7out[0]) if single else (sols, stats, q7out)

    def ik_result(
        self,
        *args: Any,
        O_T_EE: Any = None,
        position: Any = None,
        orientation: Any = None,
        q_init: Any = None,
        q_7: Any = None,
        q7_search: float = 0.0,
    ) -> IKResult:
        """Solve and explain; arguments as :func:`panda_py.kinematics.ik`."""
        search = _args.search_radius(q7_search)
        T, qi, q7 = _args.parse_ik(args, O_T_EE, position, orientation, q_init, q_7)
        return self._result(T, qi, q7, search)

    def _result(self, T: FloatArray, qi: FloatArray, q7: FloatArray, search: float) -> IKResult:
        batch = T.ndim == 3
        sols, stats, q7_used = self._solve(T, qi, q7, True, search)
        if not batch:
            sols, stats = sols[None], stats[None]
        n = sols.shape[0]
        qi_b = np.broadcast_to(qi, (n, 7))
        q2s, q5s = qi_b[:, 1].tolist(), qi_b[:, 4].tolist()
        rows = np.array([_ik.case_row(a, b) for a, b in zip(q2s, q5s, strict=True)], dtype=np.int64)
        idx = np.arange(n)
        q = sols[idx, rows]
        status = stats[idx, rows]
        if batch:
            return IKResult(q, status, sols, stats, q7_used)
        return IKResult(
            q[0],
            IKStatus(int(status[0])),
            sols[0],
            tuple(IKStatus(int(s)) for s in stats[0]),
            float(q7_used),
        )
