"""Forward and inverse kinematics of the Franka arms (FER "Panda", FR3), single or batched.

Drop-in for panda-py's ``fk``, ``ik`` and ``ik_full`` (same arguments, defaults and NaN
behaviour), in pure Python and NumPy:

* ``fk(q)`` -> ``O_T_EE`` (4, 4) with the Franka Hand's TCP as end effector
  (``F_T_EE = TransZ(0.1034) RotZ(-pi/4)``; the same offset ik uses, so ``ik(fk(q))``
  returns q). ``fk_frames``, ``zero_jacobian``, ``body_jacobian`` complete it.
* ``ik(O_T_EE, q_init=START_POSE, q_7=pi/4)`` or ``ik(position, orientation, q_init,
  q_7)`` (quaternion x, y, z, w): the analytical solver of He and Liu (ICCAR 2021), the
  solution in the same case as ``q_init``, NaN if it has none. ``ik_full``: all four
  (4, 7), NaN rows where a branch has none.
* Beyond panda-py: ``ik_result`` says why there is no solution (:class:`IKStatus`);
  ``q7_search=r`` tries q7 within r [rad] of ``q_7`` (nearest first, in steps of
  ``Q7_SEARCH_STEP``) when ``q_7`` has none, ``q7_search=math.inf`` joint 7's whole range
  (an unknown q7; one compiled loop over the candidates); every function takes a batch
  (N, 7) configurations or (N, 4, 4) poses and returns (N, ...) arrays; ``robot="fr3"``
  (or a :class:`Kinematics` object) selects the joint limits, ``F_T_EE=`` another end
  effector.

The arithmetic is written once, in scalar Python (``_fk``, ``_ik``), and runs compiled by
numba (a regular dependency where numba ships wheels; ``_numba``, loaded on the first call,
not at import; batches of ``_backend.PARALLEL_MIN_ROWS`` or more on all cores) or as plain
Python (no numba, or ``PANDA_PY_NO_JIT=1``). The first call after installing compiles
the kernels it needs and caches them per user (``~/.cache/panda_py/numba``); later
processes load them. :func:`warmup` compiles or loads them all ahead of time, for
processes that must not stall later.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from panda_py.jit import LOADED
from panda_py.kinematics import _backend, _fk
from panda_py.kinematics._backend import NAME, warmup
from panda_py.kinematics._model import (
    _F64,
    _PACK16,
    DEFAULT_Q7,
    Q7_SEARCH_STEP,
    FloatArray,
    IKResult,
    IKStatus,
    Kinematics,
    hand_F_T_EE,
)

__all__ = [
    "DEFAULT_Q7",
    "Q7_SEARCH_STEP",
    "IKResult",
    "IKStatus",
    "Kinematics",
    "body_jacobian",
    "compiled_kernels",
    "fk",
    "fk_frames",
    "get_kinematics",
    "hand_F_T_EE",
    "ik",
    "ik_full",
    "ik_result",
    "warmup",
    "zero_jacobian",
]

_UNSET: Any = object()  # the backend not chosen yet (jit.LOADED has no entry)


def compiled_kernels() -> Any:
    """The compiled kinematics kernels (numba), loaded from their cache on first use, or
    None where the kinematics run as plain Python (numba missing, ``PANDA_PY_NO_JIT=1``):
    for a loop that calls them on buffers of its own (the simulator's tick)."""
    return _backend.jit()


_DEFAULT = Kinematics("fer")
_CACHE: dict[tuple[str, bytes | None], Kinematics] = {("fer", None): _DEFAULT}
_CACHE_MAX = 32


def get_kinematics(robot: Any = "fer", F_T_EE: Any = None) -> Kinematics:
    """The (cached) :class:`Kinematics` for a robot name and flange-to-EE transform."""
    if isinstance(robot, Kinematics):
        if F_T_EE is not None:
            raise ValueError("F_T_EE: give it to Kinematics(...), not with a Kinematics object")
        return robot
    from panda_py.robots.params import get_robot

    name = get_robot(robot).name
    key_T = None
    if F_T_EE is not None:
        key_T = np.ascontiguousarray(F_T_EE, dtype=np.float64).tobytes()
    kin = _CACHE.get((name, key_T))
    if kin is None:
        kin = Kinematics(name, F_T_EE=F_T_EE)
        if len(_CACHE) >= _CACHE_MAX:
            _CACHE.pop(next(k for k in _CACHE if k != ("fer", None)))
        _CACHE[(name, key_T)] = kin
    return kin


def _make_fk(kin: Kinematics) -> Any:
    # A closure over the default model: one Python call frame, no attribute look-ups on
    # the fast path (a float64 vector in, one 4x4 array out), on the numba kernel (its
    # signatures refuse other types with a TypeError) or on the plain scalar code.
    empty, ndarray, F64, UNSET = np.empty, np.ndarray, _F64, _UNSET
    CF, chain, pack, ee_pose = kin._CF, kin._chain, _PACK16, _fk.ee_pose
    kernel: Any = None  # the numba kernel, once loaded

    def fk(q: Any, *, robot: Any = None, F_T_EE: Any = None) -> FloatArray:
        """``O_T_EE`` (4, 4) [m] for joint positions ``q`` (7,) [rad]; a batch (N, 7)
        gives (N, 4, 4). ``robot``/``F_T_EE`` select another arm or end effector (default
        the FER with the Franka Hand)."""
        nonlocal kernel
        if robot is None and F_T_EE is None:
            if type(q) is ndarray and q.dtype is F64 and q.ndim == 1:
                jit = LOADED.get(NAME, UNSET)
                if jit is UNSET:
                    jit = _backend.load_jit()
                if jit is not None:
                    if kernel is None:
                        kernel = jit.single("fk_one")
                    out = empty((4, 4))
                    try:
                        if kernel(q, CF, out):
                            return out
                    except (TypeError, ValueError):  # not float64
                        pass
                elif q.shape[0] == 7:
                    v = q.tolist()
                    s = v[0] + v[1] + v[2] + v[3] + v[4] + v[5] + v[6]
                    if s - s == 0.0:  # all finite (NaN or infinity make this NaN)
                        out = empty((4, 4))
                        pack(out, 0, *ee_pose(chain, v), 0.0, 0.0, 0.0, 1.0)
                        return out
            return kin.fk(q)
        return get_kinematics(robot if robot is not None else "fer", F_T_EE).fk(q)

    return fk


fk = _make_fk(_DEFAULT)


def fk_frames(q: Any, *, robot: Any = "fer", F_T_EE: Any = None) -> FloatArray:
    """Poses of J1..J7, flange and EE in the base frame (libfranka's Frame order):
    (9, 4, 4) for q (7,) [rad], (N, 9, 4, 4) for (N, 7)."""
    return get_kinematics(robot, F_T_EE).fk_frames(q)


def zero_jacobian(q: Any, *, robot: Any = "fer", F_T_EE: Any = None) -> FloatArray:
    """Geometric EE Jacobian in the base frame, (6, 7) or (N, 6, 7): rows linear
    velocity [m/s] then angular velocity [rad/s] per joint velocity [rad/s]."""
    return get_kinematics(robot, F_T_EE).zero_jacobian(q)


def body_jacobian(q: Any, *, robot: Any = "fer", F_T_EE: Any = None) -> FloatArray:
    """Geometric EE Jacobian in the EE frame, (6, 7) or (N, 6, 7)."""
    return get_kinematics(robot, F_T_EE).body_jacobian(q)


_NOARG: Any = object()  # "not given", for ik's positional-only parameters


def _make_ik(kin: Kinematics, full: bool) -> Any:
    # One Python frame on the fast path (float64 arrays, positional q_init and q_7, the
    # default robot): the numba kernel is called directly; its signatures refuse other
    # types (TypeError) and it returns False for bad shapes or values, and everything
    # else takes the general path, which also words the error messages.
    if kin._EE_T_F is not None:
        raise ValueError("the fast single-pose ik needs an EE on the flange's z axis")
    F64, UNSET = _F64, _UNSET
    P, start, empty, ndarray = kin._P, kin._start, np.empty, np.ndarray
    shape = (4, 7) if full else 7
    kernel_name = "ik_full_one" if full else "ik_one"
    kernel: Any = None  # the numba kernel, once loaded
    scalar = kin._ik_fast  # the pure path's single-pose solver

    def ik(
        O_T_EE: Any = _NOARG, q_init: Any = _NOARG, q_7: Any = _NOARG, /, *more: Any, **kw: Any
    ) -> FloatArray:
        nonlocal kernel
        fast = type(O_T_EE) is ndarray and O_T_EE.ndim == 2 and not more
        qi, q7, radius = q_init, q_7, 0.0
        if kw and fast:  # q_init, q_7, q7_search by keyword (once each): the same fast path
            qi, q7 = kw.get("q_init", qi), kw.get("q_7", q7)
            radius = kw.get("q7_search", 0.0)
            fast = (
                len(kw) == ("q_init" in kw) + ("q_7" in kw) + ("q7_search" in kw)
                and (q_init is _NOARG or "q_init" not in kw)
                and (q_7 is _NOARG or "q_7" not in kw)
                and type(radius) is float
                and radius >= 0.0  # (the general path words the error)
            )
        if fast:
            q7 = DEFAULT_Q7 if q7 is _NOARG else q7
            qi = start if qi is _NOARG or qi is None else qi
            jit = LOADED.get(NAME, UNSET)
            if jit is UNSET:
                jit = _backend.load_jit()
            if jit is not None and (
                O_T_EE.dtype is F64 and (qi is start or (type(qi) is ndarray and qi.dtype is F64))
            ):
                if kernel is None:
                    kernel = jit.single(kernel_name)
                out = empty(shape)
                try:
                    if kernel(P, O_T_EE, qi, q7, radius, out):
                        return out
                except (TypeError, ValueError):  # not float64 arrays / a number
                    pass
            elif jit is None:
                q = scalar(O_T_EE, None if qi is start else qi, q7, full=full, radius=radius)
                if q is not None:
                    return q
        args = tuple(a for a in (O_T_EE, q_init, q_7) if a is not _NOARG) + more
        robot = kw.pop("robot", None)
        kin_ = get_kinematics(robot if robot is not None else "fer", kw.pop("F_T_EE", None))
        return kin_._ik_general(full, *args, **kw)

    return ik


ik = _make_ik(_DEFAULT, full=False)
ik.__name__ = ik.__qualname__ = "ik"
ik.__doc__ = """Joint positions (7,) [rad] reaching the EE pose, in the same case as ``q_init``;
NaN if that case has no solution within the joint limits.

``ik(O_T_EE, q_init=START_POSE, q_7=pi/4)`` or ``ik(position, orientation, q_init, q_7)``
with position [m] (3,) and quaternion (x, y, z, w) (4,); each also by keyword. ``q_7``
[rad] is the redundancy parameter. Batches: O_T_EE (N, 4, 4) (or (N, 3) and (N, 4)),
q_init (7,) or (N, 7), q_7 scalar or (N,) -> (N, 7). Keywords: ``q7_search=r`` [rad]
solves at the q7 nearest q_7 within r (``q_7 +- k * Q7_SEARCH_STEP``, + first) that has a
solution in q_init's case, NaN if none (a pose whose solutions lie in a q7 interval
narrower than the step may be missed); ``q7_search=math.inf`` searches joint 7's whole
range (an unknown q7; q_7 then only says where to start, e.g. ``q_init[6]`` to stay near
the current configuration); ``robot`` ("fer", "fr3", ...) the joint limits; ``F_T_EE``
another end effector.
"""

ik_full = _make_ik(_DEFAULT, full=True)
ik_full.__name__ = ik_full.__qualname__ = "ik_full"
ik_full.__doc__ = """All four He-Liu solutions (4, 7) [rad] (NaN rows where a branch has none),
rows ordered as panda-py's: (q6 branch with cos(q5) < 0, q2 >= 0), (.., q2 < 0),
(cos(q5) >= 0, q2 >= 0), (.., q2 < 0). Arguments as :func:`ik`; a batch gives
(N, 4, 7). With ``q7_search``: all four at the q7 that :func:`ik` would pick (found for
q_init's case)."""


def ik_result(*args: Any, robot: Any = "fer", F_T_EE: Any = None, **kwargs: Any) -> IKResult:
    """:func:`ik` and :func:`ik_full` in one, with the reason (:class:`IKStatus`) for
    every branch without a solution and the q7 actually used. Arguments as :func:`ik`."""
    return get_kinematics(robot, F_T_EE).ik_result(*args, **kwargs)
