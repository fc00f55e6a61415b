"""The :class:`Kinematics` of one arm with one end effector: fk, frames, Jacobians and the
analytical ik, for single configurations and for batches."""

from __future__ import annotations

import enum
import math
import os
import struct
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py.kinematics import _ik, _input
from panda_py.kinematics._codegen import ChainSpec, _snap, compile_chain
from panda_py.robots.params import FRANKA_HAND, START_POSE, RobotSpec, get_robot

# panda-py's default redundancy parameter q7 [rad] (panda_py.ik's q_7 default).
DEFAULT_Q7 = math.pi / 4
# Step [rad] of the q7 search (``q7_search``): candidates q_7 +- k * step, nearest first.
Q7_SEARCH_STEP = 0.01
# A flange-to-EE transform whose rotation is this close [-] to a z rotation and whose
# translation this close [m] to the z axis is folded into the last joint (faster code).
_Z_ONLY_TOL = 1e-15
# Rows per chunk of the batched (NumPy) paths: measured fastest on 2-core x86 boxes.
BATCH_CHUNK = 512

FloatArray = NDArray[np.float64]
_F64 = np.dtype(np.float64)

# The optional numba backend (:mod:`._numba`): _UNSET until the first call that could use
# it, then the module, or None (numba missing, or PANDA_PY_NO_JIT=1). Tests set it.
_UNSET: Any = object()
_JIT: Any = _UNSET


def load_jit() -> Any:
    """The numba backend module, or None: imported on first use (importing numba and
    loading the cached kernels takes about a second; compiling them the first time, after
    installing, several more)."""
    global _JIT
    if _JIT is _UNSET:
        if os.environ.get("PANDA_PY_NO_JIT", "") not in ("", "0"):
            _JIT = None
        else:
            try:
                from panda_py.kinematics import _numba
            except ImportError:
                _JIT = None
            else:
                _JIT = _numba
    return _JIT


# Batches of at least this many rows run the numba kernels on all cores (below it the
# threads' start-up costs more than they save); never on a single-core machine.
PARALLEL_MIN_ROWS = 2048 if (os.cpu_count() or 1) > 1 else 2**62
# One parallel launch at a time (numba's fallback threading layer aborts on concurrent
# launches; a second caller takes the serial kernel instead of waiting), and none in a
# forked child (GNU OpenMP, numba's default layer on Linux, is not fork-safe).
_PAR_LOCK = threading.Lock()
_PAR_PID = os.getpid()


def _run(serial: Any, parallel: Any, n: int, *args: Any) -> None:
    """A numba batch kernel over n rows: the parallel variant where it pays and is safe."""
    if n >= PARALLEL_MIN_ROWS and os.getpid() == _PAR_PID and _PAR_LOCK.acquire(blocking=False):
        try:
            parallel(*args)
        finally:
            _PAR_LOCK.release()
    else:
        serial(*args)


def _raise_invalid(T: FloatArray, qi: FloatArray, q7: FloatArray, k: int) -> None:
    """The validating path's message for pose k, which a kernel found not to be a finite
    rigid transform (or with a non-finite q_init or q_7)."""
    _input.check_rigid("O_T_EE", T)  # each names the first bad item of a batch
    _input.check_finite("q_init", qi, 1)
    _input.check_finite("q_7", q7, 0)
    raise ValueError(  # not reached unless the two checks disagree at the tolerance
        f"O_T_EE: expected a rigid transform (tolerance {_input.ROTATION_TOL}) (batch index {k})"
    )


def _pack_chain(dh: Any, F_T_EE: FloatArray) -> FloatArray:
    """The numba fk kernels' chain (11, 4): per joint ``[a, d, cos alpha, sin alpha]``
    (cos/sin snapped to exact 0, +-1 as in ``_codegen``), ``[flange_d, 0, 0, 0]``, then
    the top 3 rows of F_T_EE."""
    CF = np.zeros((11, 4))
    for i in range(7):
        CF[i] = (dh.a[i], dh.d[i], _snap(math.cos(dh.alpha[i])), _snap(math.sin(dh.alpha[i])))
    CF[7, 0] = dh.flange_d
    CF[8:] = F_T_EE[:3]
    return CF


def _pack_ik(P: _ik.IKParams) -> FloatArray:
    """The numba ik kernels' parameters: d1, d3, d5, a4, a7, d_e, theta_e, l24, l46,
    q4_offset, q_min (7), q_max (7), cos and sin of q4_offset, 1 / (2 l24 l46)."""
    head = [P.d1, P.d3, P.d5, P.a4, P.a7, P.d_e, P.theta_e, P.l24, P.l46, P.q4_offset]
    tail = [P.cos_q4_offset, P.sin_q4_offset, P.inv_2l24l46]
    return np.array([*head, *P.q_min, *P.q_max, *tail], dtype=np.float64)


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


def _case_row(q2: float, q5: float) -> int:
    """Branch index (see :mod:`._ik`) of a configuration: the q6 branch follows the sign of
    cos(q5), the shoulder branch the sign of q2."""
    return (2 if math.cos(q5) >= 0.0 else 0) + (1 if q2 < 0.0 else 0)


def _tail(F_T_EE: FloatArray) -> dict[str, Any]:
    """ChainSpec tail arguments for a flange-to-EE transform."""
    R, p = F_T_EE[:3, :3], F_T_EE[:3, 3]
    z_only = (
        abs(R[2, 2] - 1.0) <= _Z_ONLY_TOL
        and np.abs(R[:2, 2]).max() <= _Z_ONLY_TOL
        and np.abs(R[2, :2]).max() <= _Z_ONLY_TOL
        and np.abs(p[:2]).max() <= _Z_ONLY_TOL
    )
    if z_only:
        return {"tail_rotz": math.atan2(R[1, 0], R[0, 0]), "tail_z": float(p[2])}
    return {
        "tail_R": tuple(tuple(float(v) for v in row) for row in R),
        "tail_p": (float(p[0]), float(p[1]), float(p[2])),
    }


def hand_F_T_EE() -> FloatArray:
    """The Franka Hand's TCP relative to the flange: ``TransZ(0.1034) RotZ(-pi/4)``."""
    c, s = math.cos(FRANKA_HAND.tcp_rotz), math.sin(FRANKA_HAND.tcp_rotz)
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[2, 3] = FRANKA_HAND.tcp_offset
    return T


# struct packs floats straight into a fresh array: ~4x faster than np.array(list)
_PACK16: Callable[..., None] = struct.Struct("16d").pack_into
_PACK7: Callable[..., None] = struct.Struct("7d").pack_into
_PACK28: Callable[..., None] = struct.Struct("28d").pack_into


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
        tail = _tail(T)
        spec = ChainSpec(dh.a, dh.d, dh.alpha, dh.flange_d, **tail)
        scalar = {"sin": math.sin, "cos": math.cos}
        vector = {"sin": np.sin, "cos": np.cos}
        self._ee: Callable[..., tuple[float, ...]] = compile_chain(spec, "ee", scalar)  # type: ignore[assignment]
        self._ee_n: Callable[..., tuple[Any, ...]] = compile_chain(spec, "ee", vector)  # type: ignore[assignment]
        self._frames_n: Callable[..., tuple[Any, ...]] = compile_chain(spec, "frames", vector)  # type: ignore[assignment]
        self._jac: Callable[..., tuple[float, ...]] = compile_chain(spec, "jacobian", scalar)  # type: ignore[assignment]
        self._jac_n: Callable[..., tuple[Any, ...]] = compile_chain(spec, "jacobian", vector)  # type: ignore[assignment]
        # ik: the He-Liu geometry needs a target on joint 7's z axis; any other EE is first
        # mapped back to the flange.
        if dh.a[4] != -dh.a[3] or any(dh.a[i] != 0.0 for i in (0, 1, 2, 5)):
            raise ValueError("robot: the analytical ik needs the Franka DH structure")
        if "tail_z" in tail:
            d_e, theta_e = dh.flange_d + tail["tail_z"], tail["tail_rotz"]
            self._EE_T_F: FloatArray | None = None
        else:
            d_e, theta_e = dh.flange_d, 0.0
            self._EE_T_F = np.asarray(np.linalg.inv(T), dtype=np.float64)
        j = self.robot.joints
        self._ik_params = _ik.IKParams(
            dh.d[0], dh.d[2], dh.d[4], dh.a[3], dh.a[6], d_e, theta_e, j.q_min, j.q_max
        )
        self._solve = _ik.make_scalar_solver(self._ik_params)
        self._CF = _pack_chain(dh, T)
        self._P = _pack_ik(self._ik_params)
        self._start = np.array(START_POSE)
        self.q_min: FloatArray = np.array(j.q_min)
        self.q_max: FloatArray = np.array(j.q_max)

    def __repr__(self) -> str:
        return f"Kinematics(robot={self.robot.name!r}, F_T_EE={self.F_T_EE.tolist()!r})"

    # ---------------------------------------------------------------- forward kinematics

    def fk(self, q: object) -> FloatArray:
        """``O_T_EE`` (4, 4) for joint positions q (7,) [rad]; a batch (N, 7) gives
        (N, 4, 4). Translations in [m]."""
        jit = _JIT if _JIT is not _UNSET else load_jit()
        if jit is not None and type(q) is np.ndarray and q.dtype is _F64 and q.ndim == 1:
            out = np.empty((4, 4))
            try:
                if jit.single("fk_one")(q, self._CF, out):
                    return out
            except (TypeError, ValueError):  # not float64: the general path converts
                pass
        if jit is None:
            return self._fk_pure(q)
        qa = _input.joints("q", q)
        qb = np.ascontiguousarray(qa.reshape(-1, 7))
        out = np.empty((qb.shape[0], 4, 4))
        _run(jit.fk_batch, jit.fk_batch_par, qb.shape[0], qb, self._CF, out)
        return out[0] if qa.ndim == 1 else out

    def _fk_pure(self, q: object) -> FloatArray:
        try:
            if len(q) != 7:  # type: ignore[arg-type]
                raise ValueError  # a batch: no tolist() of N rows here
            a, b, c, d, e, f, g = q.tolist()  # type: ignore[attr-defined]
            s = a + b + c + d + e + f + g
            if s - s == 0.0:  # all finite (a NaN or infinity makes this NaN)
                out = np.empty((4, 4))
                _PACK16(out, 0, *self._ee(a, b, c, d, e, f, g))
                return out
        except (AttributeError, TypeError, ValueError):
            pass
        qa = _input.joints("q", q)
        if qa.ndim == 1:
            out = np.empty((4, 4))
            _PACK16(out, 0, *self._ee(*qa.tolist()))
            return out
        return self._batched(self._ee_n, qa, (4, 4))

    def fk_frames(self, q: object) -> FloatArray:
        """Poses of J1..J7, the flange and the EE (libfranka's ``Frame`` order) in the base
        frame: (9, 4, 4) for q (7,) [rad], (N, 9, 4, 4) for a batch (N, 7)."""
        qa = _input.joints("q", q)
        single = qa.ndim == 1
        qb = qa[None] if single else qa
        jit = load_jit()
        if jit is not None:
            out = np.empty((qb.shape[0], 9, 4, 4))
            jit.frames_batch(np.ascontiguousarray(qb), self._CF, out)
        else:
            out = self._batched(self._frames_n, qb, (9, 4, 4))
        return out[0] if single else out

    def zero_jacobian(self, q: object) -> FloatArray:
        """Geometric Jacobian of the EE expressed in the base frame, (6, 7) for q (7,) [rad]
        (rows: linear [m/s per rad/s], then angular [rad/s per rad/s]); (N, 6, 7) for a
        batch (N, 7). libfranka's ``zeroJacobian(Frame::kEndEffector)``."""
        return self._jacobians(q, body=False)

    def body_jacobian(self, q: object) -> FloatArray:
        """Geometric Jacobian of the EE expressed in the EE frame, (6, 7) or (N, 6, 7).
        libfranka's ``bodyJacobian(Frame::kEndEffector)``."""
        return self._jacobians(q, body=True)

    def _jacobians(self, q: object, body: bool) -> FloatArray:
        jit = _JIT if _JIT is not _UNSET else load_jit()
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
        qa = _input.joints("q", q)
        if jit is not None:
            qb = np.ascontiguousarray(qa.reshape(-1, 7))
            out = np.empty((qb.shape[0], 6, 7))
            jit.jacobian_batch(qb, self._CF, body, out)
            return out[0] if qa.ndim == 1 else out
        if qa.ndim == 1:
            v = self._jac(*qa.tolist())
            T = np.array(v[:16]).reshape(4, 4)
            J = np.array(v[16:]).reshape(6, 7)
            if body:
                Rt = T[:3, :3].T
                J = np.concatenate([Rt @ J[:3], Rt @ J[3:]])
            return J
        vb = self._batched(self._jac_n, qa, (16 + 42,))
        Tb = vb[:, :16].reshape(-1, 4, 4)
        Jb = vb[:, 16:].reshape(-1, 6, 7)
        if body:
            Rt = np.swapaxes(Tb[:, :3, :3], 1, 2)
            Jb = np.concatenate([Rt @ Jb[:, :3], Rt @ Jb[:, 3:]], axis=1)
        return Jb

    @staticmethod
    def _batched(
        fn: Callable[..., tuple[Any, ...]], q: FloatArray, shape: tuple[int, ...]
    ) -> FloatArray:
        """Run generated code over rows of q in chunks small enough for the temporaries to
        stay in cache (one chunk of 10,000 rows is several times slower per row)."""
        n = q.shape[0]
        out = np.empty((n, math.prod(shape)))
        qt = np.ascontiguousarray(q.T)
        for start in range(0, n, BATCH_CHUNK):
            stop = min(start + BATCH_CHUNK, n)
            for i, v in enumerate(fn(*qt[:, start:stop])):
                out[start:stop, i] = v  # constants broadcast
        return out.reshape((n, *shape))

    # ---------------------------------------------------------------- inverse kinematics

    def ik(self, *args: Any, **kwargs: Any) -> FloatArray:
        """See :func:`panda_py.kinematics.ik`."""
        if not kwargs and 1 <= len(args) <= 3:
            q = self._ik_fast(*args)
            if q is not None:
                return q
        return self._ik_general(False, *args, **kwargs)

    def ik_full(self, *args: Any, **kwargs: Any) -> FloatArray:
        """See :func:`panda_py.kinematics.ik_full`."""
        if not kwargs and 1 <= len(args) <= 3:
            q = self._ik_fast(*args, full=True)
            if q is not None:
                return q
        return self._ik_general(True, *args, **kwargs)

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
        """ik (full: ik_full) with every overload and keyword, without the result object."""
        return self._ik_any(full, args, O_T_EE, position, orientation, q_init, q_7, q7_search)

    def _ik_any(
        self,
        full: bool,
        args: tuple[Any, ...],
        O_T_EE: Any,
        position: Any,
        orientation: Any,
        q_init: Any,
        q_7: Any,
        q7_search: float,
    ) -> FloatArray:
        """ik (full: ik_full) for one pose or a batch. With numba the kernels check each
        pose themselves (finite, rigid) while solving; an invalid one is then reported by
        the validating NumPy checks, which name it."""
        search = _input.nonnegative("q7_search", q7_search, "rad")
        jit = load_jit()
        fused = jit is not None and search == 0.0 and self._EE_T_F is None
        T, qi_a, q7_a = self._parse(
            args, O_T_EE, position, orientation, q_init, q_7, check=not fused
        )
        if not fused and (T.ndim == 2 or search > 0.0):
            r = self.ik_result(T, q_init=qi_a, q_7=q7_a, q7_search=search)
            return r.solutions if full else r.q  # one pose, or a search: the general path
        single = T.ndim == 2
        Tb = T[None] if single else T
        n = Tb.shape[0]
        if self._EE_T_F is not None:
            Tb = Tb @ self._EE_T_F
        if jit is not None:
            out = np.empty((n, 4, 7) if full else (n, 7))
            st = np.empty((n, 4) if full else (n,), dtype=np.int8)
            _run(
                jit.ik_batch,
                jit.ik_batch_par,
                n,
                self._P,
                np.ascontiguousarray(Tb),
                np.ascontiguousarray(qi_a.reshape(-1, 7)),
                np.ascontiguousarray(q7_a.reshape(-1)),
                full,
                out,
                st,
            )
            first = st[:, 0] if full else st
            if n and first.min() < 0:
                _raise_invalid(T, qi_a, q7_a, int(np.argmax(first < 0)))
            return out[0] if single else out
        q7 = np.broadcast_to(q7_a, (n,)).astype(np.float64)
        qi = np.broadcast_to(qi_a, (n, 7))
        if full:
            return self._solve_all(Tb, q7, qi)[0]
        rows = (np.where(np.cos(qi[:, 4]) >= 0.0, 2, 0) + (qi[:, 1] < 0.0)).astype(np.int64)
        out = np.empty((n, 7))
        for a in range(0, n, BATCH_CHUNK):
            b = min(a + BATCH_CHUNK, n)
            out[a:b] = _ik.solve_batch(
                self._ik_params, Tb[a:b, :3, :3], Tb[a:b, :3, 3], q7[a:b], qi[a:b, 0], rows[a:b]
            )[0]
        return out

    def _ik_fast(
        self, O_T_EE: Any, q_init: Any = None, q_7: Any = DEFAULT_Q7, *, full: bool = False
    ) -> FloatArray | None:
        """One 4x4 pose with default options, on plain floats; None means "take the
        general path" (which also produces the error message for bad input)."""
        if self._EE_T_F is not None:
            return None
        jit = _JIT if _JIT is not _UNSET else load_jit()
        if jit is not None:
            qi = self._start if q_init is None else q_init
            if not (
                type(O_T_EE) is np.ndarray
                and O_T_EE.dtype is _F64
                and type(qi) is np.ndarray
                and qi.dtype is _F64
            ):
                return None  # (numba's TypeError would cost ~100 us to word)
            out = np.empty((4, 7) if full else 7)
            try:
                if jit.single("ik_full_one" if full else "ik_one")(self._P, O_T_EE, qi, q_7, out):
                    return out
            except (TypeError, ValueError):  # not float64 arrays / a number
                pass
            return None  # the validating path, on the same kernels
        try:
            if len(O_T_EE) != 4:
                return None
            (r00, r01, r02, px), (r10, r11, r12, py), (r20, r21, r22, pz), last = O_T_EE.tolist()
            if q_init is None:
                q1, q2, q5 = START_POSE[0], START_POSE[1], START_POSE[4]
            else:
                q1, q2, _, _, q5, _, _ = q_init.tolist()
            q7 = float(q_7)
        except (AttributeError, TypeError, ValueError):
            return None
        tol = _input.ROTATION_TOL
        # rigid: unit, orthogonal columns x, y and z = x cross y; last row 0 0 0 1
        ex = r00 * r00 + r10 * r10 + r20 * r20 - 1.0
        ey = r01 * r01 + r11 * r11 + r21 * r21 - 1.0
        exy = r00 * r01 + r10 * r11 + r20 * r21
        cx = r10 * r21 - r20 * r11 - r02
        cy = r20 * r01 - r00 * r21 - r12
        cz = r00 * r11 - r10 * r01 - r22
        if not (
            -tol < ex < tol
            and -tol < ey < tol
            and -tol < exy < tol
            and -tol < cx < tol
            and -tol < cy < tol
            and -tol < cz < tol
            and last == [0.0, 0.0, 0.0, 1.0]
        ):
            return None
        s = px + py + pz + q1 + q2 + q5 + q7
        if s - s != 0.0:
            return None
        if full:
            res = self._solve(
                r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, q7, q1, (0, 1, 2, 3)
            )
            full_out = np.empty((4, 7))
            _PACK28(full_out, 0, *res[0][2], *res[1][2], *res[2][2], *res[3][2])
            return full_out
        row = (2 if math.cos(q5) >= 0.0 else 0) + (1 if q2 < 0.0 else 0)
        ((_, _status, sol),) = self._solve(
            r00, r01, r02, r10, r11, r12, r20, r21, r22, px, py, pz, q7, q1, (row,)
        )
        out = np.empty(7)
        _PACK7(out, 0, *sol)
        return out

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
        T, q_init_a, q7_a = self._parse(args, O_T_EE, position, orientation, q_init, q_7)
        search = _input.nonnegative("q7_search", q7_search, "rad")
        batch = T.ndim == 3
        Tb = T if batch else T[None]
        n = Tb.shape[0]
        if self._EE_T_F is not None:
            Tb = Tb @ self._EE_T_F
        qi = np.broadcast_to(q_init_a, (n, 7))
        q7 = np.broadcast_to(q7_a, (n,)).astype(np.float64)
        rows = (np.where(np.cos(qi[:, 4]) >= 0.0, 2, 0) + (qi[:, 1] < 0.0)).astype(np.int64)
        sols, stats = self._solve_all(Tb, q7, qi)
        idx = np.arange(n)
        q = sols[idx, rows].copy()
        status = stats[idx, rows].copy()
        q7_used = q7.copy()
        if search > 0.0:
            for offset in _search_offsets(search):
                todo = np.flatnonzero(status != IKStatus.OK)
                if todo.size == 0:
                    break
                q7c = q7[todo] + offset
                s2, st2 = self._solve_all(Tb[todo], q7c, qi[todo])
                r = rows[todo]
                found = st2[np.arange(todo.size), r] == IKStatus.OK
                hit = todo[found]
                q[hit] = s2[found, r[found]]
                status[hit] = IKStatus.OK
                sols[hit], stats[hit] = s2[found], st2[found]
                q7_used[hit] = q7c[found]
        if batch:
            return IKResult(q, status, sols, stats, q7_used)
        return IKResult(
            q[0],
            IKStatus(int(status[0])),
            sols[0],
            tuple(IKStatus(int(s)) for s in stats[0]),
            float(q7_used[0]),
        )

    def _solve_all(
        self, T: FloatArray, q7: FloatArray, qi: FloatArray
    ) -> tuple[FloatArray, NDArray[np.int8]]:
        """All four branches for N validated poses T (N, 4, 4), q7 (N,), q_init (N, 7):
        (N, 4, 7) and statuses (N, 4)."""
        n = T.shape[0]
        jit = load_jit()
        if jit is not None:
            sols = np.empty((n, 4, 7))
            stats = np.empty((n, 4), dtype=np.int8)
            _run(
                jit.ik_batch,
                jit.ik_batch_par,
                n,
                self._P,
                np.ascontiguousarray(T),
                np.ascontiguousarray(qi, dtype=np.float64),
                np.ascontiguousarray(q7, dtype=np.float64),
                True,
                sols,
                stats,
            )
            return sols, stats
        if n == 1:  # the scalar solver is ~50x faster than NumPy on one row
            args = T[0, :3, :3].ravel().tolist() + T[0, :3, 3].tolist()
            res = self._solve(*args, float(q7[0]), float(qi[0, 0]), (0, 1, 2, 3))
            sols = np.array([r[2] for r in res])[None]
            stats = np.array([r[1] for r in res], dtype=np.int8)[None]
            return sols, stats
        sols = np.empty((n, 4, 7))
        stats = np.empty((n, 4), dtype=np.int8)
        for a in range(0, n, BATCH_CHUNK):
            b = min(a + BATCH_CHUNK, n)
            sols[a:b], stats[a:b] = _ik.solve_batch_full(
                self._ik_params, T[a:b, :3, :3], T[a:b, :3, 3], q7[a:b], qi[a:b, 0]
            )
        return sols, stats

    def _parse(
        self,
        args: tuple[Any, ...],
        O_T_EE: Any,
        position: Any,
        orientation: Any,
        q_init: Any,
        q_7: Any,
        *,
        check: bool = True,
    ) -> tuple[FloatArray, FloatArray, FloatArray]:
        """Sort panda-py's two overloads, ``(O_T_EE, q_init, q_7)`` and ``(position,
        orientation, q_init, q_7)``, positional or keyword, into (T, q_init, q_7), checked
        for shape and (unless ``check=False``: a kernel checks them) values."""
        rest = list(args)
        if O_T_EE is None and position is None and rest:
            first = np.asarray(rest[0]) if not isinstance(rest[0], np.ndarray) else rest[0]
            second = rest[1] if len(rest) > 1 else orientation
            is_position = first.shape == (3,) or (
                first.ndim == 2 and first.shape[1] == 3 and np.shape(second)[-1:] == (4,)
            )
            if is_position:
                position = rest.pop(0)
            else:
                O_T_EE = rest.pop(0)
        if position is not None and orientation is None and rest:
            orientation = rest.pop(0)
        names = ["q_init", "q_7"]
        given = {"q_init": q_init, "q_7": q_7}
        if len(rest) > 2:
            raise ValueError(
                "ik: expected (O_T_EE, q_init, q_7) or (position, orientation, q_init, q_7), "
                f"got {len(rest)} extra positional arguments"
            )
        for name, value in zip(names, rest, strict=False):
            if given[name] is not None:
                raise ValueError(f"{name}: given both positionally and by keyword")
            given[name] = value
        if O_T_EE is not None:
            if position is not None or orientation is not None:
                raise ValueError("O_T_EE: give either O_T_EE or position and orientation")
            T = _input.transforms("O_T_EE", O_T_EE, check=check)
        elif position is not None and orientation is not None:
            T = _input.position_orientation(position, orientation)
        else:
            raise ValueError("ik: expected O_T_EE (4x4) or position (3,) and orientation (4,)")
        n = T.shape[0] if T.ndim == 3 else None
        if given["q_init"] is None:
            qi = np.array(START_POSE)
        else:
            qi = _input.joints("q_init", given["q_init"], check=check)
            if qi.ndim == 2 and (n is None or qi.shape[0] != n):
                raise ValueError(
                    f"q_init: expected shape (7,) or ({n}, 7) to match the poses, got {qi.shape}"
                )
        q7 = _input.scalar_or_batch(
            "q_7", DEFAULT_Q7 if given["q_7"] is None else given["q_7"], n, "rad", check=check
        )
        return T, qi, q7


def _search_offsets(radius: float) -> list[float]:
    """q7 offsets [rad] to try, nearest first: +step, -step, +2 step, ..."""
    out: list[float] = []
    k = 1
    while k * Q7_SEARCH_STEP <= radius + 1e-12:
        out += [k * Q7_SEARCH_STEP, -k * Q7_SEARCH_STEP]
        k += 1
    return out
