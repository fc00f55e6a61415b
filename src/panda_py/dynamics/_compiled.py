"""The recursive Newton-Euler and composite-rigid-body algorithms of :mod:`.dynamics`,
compiled by numba on float64 arrays (the same recursion, term for term), for the control
loop's model terms: under a microsecond a call where the plain-Python recursion takes
40-110 us (the temporaries on the stack, :mod:`panda_py.jit.stack`: no allocation).

Imported by :mod:`.dynamics` on first use unless ``PANDA_PY_NO_JIT=1`` or numba is
missing; compiled once per machine and cached on disk under a key over this file
(:mod:`panda_py.jit.cache`: per user, whichever checkout or install compiled it).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from panda_py import progress
from panda_py.jit import cache, stack
from panda_py.jit.stack import stack_array

__all__ = ["crba", "rnea", "rnea_along", "warmup"]

# the compile cache's key: the kernels compile this file and the stack arrays' helper
# (panda_py.jit.cache)
KEY = cache.source_key([Path(__file__), Path(stack.__file__)])

_N = 7


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _rotations(ca, sa, q, R):  # type: ignore[no-untyped-def,unused-ignore]
    """R_{i-1,i} = RotX(alpha_i) RotZ(q_i), i = 1..7, into ``R`` (7, 3, 3)."""
    for i in range(_N):
        cq, sq = math.cos(q[i]), math.sin(q[i])
        R[i, 0, 0], R[i, 0, 1], R[i, 0, 2] = cq, -sq, 0.0
        R[i, 1, 0], R[i, 1, 1], R[i, 1, 2] = ca[i] * sq, ca[i] * cq, -sa[i]
        R[i, 2, 0], R[i, 2, 1], R[i, 2, 2] = sa[i] * sq, sa[i] * cq, ca[i]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _cross(a, b, out):  # type: ignore[no-untyped-def,unused-ignore]
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _mv(A, x, out):  # type: ignore[no-untyped-def,unused-ignore]
    """``out = A x`` for a 3x3 ``A`` (written out: numba's ``@`` calls BLAS, whose call
    costs more than this product)."""
    x0, x1, x2 = x[0], x[1], x[2]
    for r in range(3):
        out[r] = A[r, 0] * x0 + A[r, 1] * x1 + A[r, 2] * x2


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def _mtv(A, x, out):  # type: ignore[no-untyped-def,unused-ignore]
    """``out = A^T x`` for a 3x3 ``A``."""
    x0, x1, x2 = x[0], x[1], x[2]
    for c in range(3):
        out[c] = A[0, c] * x0 + A[1, c] * x1 + A[2, c] * x2


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def rnea(origin, ca, sa, mass, h, inertia, q, dq, ddq, a_base, tau):  # type: ignore[no-untyped-def,unused-ignore]
    """Joint torques into ``tau`` (7,) for (q, dq, ddq) with base acceleration
    ``a_base`` (``-gravity``); links' ``mass`` (7,), first moments ``h`` (7, 3) and
    inertias about their frame origins (7, 3, 3); frame origins ``origin`` (7, 3)."""
    # (the temporaries on the stack: stack_array, no allocation per call)
    R = stack_array(63).reshape((_N, 3, 3))
    _rotations(ca, sa, q, R)
    w = stack_array(3)
    wd = stack_array(3)
    a = stack_array(3)
    for k in range(3):
        w[k] = 0.0
        wd[k] = 0.0
        a[k] = a_base[k]
    f = stack_array(21).reshape((_N, 3))
    n = stack_array(21).reshape((_N, 3))
    t1 = stack_array(3)
    t2 = stack_array(3)
    t3 = stack_array(3)
    tmp = stack_array(3)
    w_par = stack_array(3)
    wd_par = stack_array(3)
    Iwd = stack_array(3)
    Iw = stack_array(3)
    for i in range(_N):
        p = origin[i]
        _cross(wd, p, t1)  # a_par
        _cross(w, p, t2)
        _cross(w, t2, t3)  # w x (w x p)
        for k in range(3):
            tmp[k] = a[k] + t1[k] + t3[k]
        Ri = R[i]
        _mtv(Ri, w, w_par)
        _mtv(Ri, wd, wd_par)
        _mtv(Ri, tmp, a)
        w[0], w[1], w[2] = w_par[0], w_par[1], w_par[2] + dq[i]
        wd[0] = wd_par[0] + w_par[1] * dq[i]
        wd[1] = wd_par[1] - w_par[0] * dq[i]
        wd[2] = wd_par[2] + ddq[i]
        hi = h[i]
        I = inertia[i]
        _cross(w, hi, t1)
        _cross(w, t1, t2)  # w x (w x h)
        _cross(wd, hi, t3)  # wd x h
        for k in range(3):
            f[i, k] = mass[i] * a[k] + t3[k] + t2[k]
        _mv(I, wd, Iwd)
        _mv(I, w, Iw)
        _cross(w, Iw, t1)
        _cross(hi, a, t2)
        for k in range(3):
            n[i, k] = Iwd[k] + t1[k] + t2[k]
    fo = stack_array(3)
    no = stack_array(3)
    for k in range(3):
        fo[k] = f[_N - 1, k]
        no[k] = n[_N - 1, k]
    fc = stack_array(3)
    nc = stack_array(3)
    tau[_N - 1] = no[2]
    for i in range(_N - 2, -1, -1):
        Rn = R[i + 1]
        _mv(Rn, fo, fc)
        _mv(Rn, no, nc)
        _cross(origin[i + 1], fc, t1)
        for k in range(3):
            fo[k] = f[i, k] + fc[k]
            no[k] = n[i, k] + nc[k] + t1[k]
        tau[i] = no[2]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def crba(origin, ca, sa, mass, h, inertia, q, M):  # type: ignore[no-untyped-def,unused-ignore]
    """The joint-space mass matrix into ``M`` (7, 7) (arguments as :func:`rnea`)."""
    R = stack_array(63).reshape((_N, 3, 3))
    _rotations(ca, sa, q, R)
    cm = stack_array(_N)
    ch = stack_array(21).reshape((_N, 3))
    cI = stack_array(63).reshape((_N, 3, 3))
    cm[_N - 1] = mass[_N - 1]
    for r in range(3):
        ch[_N - 1, r] = h[_N - 1, r]
        for k in range(3):
            cI[_N - 1, r, k] = inertia[_N - 1, r, k]
    h_r = stack_array(3)
    I_r = stack_array(9).reshape((3, 3))
    for i in range(_N - 2, -1, -1):
        Rn, p = R[i + 1], origin[i + 1]
        m = cm[i + 1]
        _mv(Rn, ch[i + 1], h_r)
        Ic = cI[i + 1]
        for r in range(3):  # I_r = Rn Ic Rn^T
            for k in range(3):
                acc = 0.0
                for u in range(3):
                    IR = Ic[u, 0] * Rn[k, 0] + Ic[u, 1] * Rn[k, 1] + Ic[u, 2] * Rn[k, 2]
                    acc += Rn[r, u] * IR
                I_r[r, k] = acc
        p2 = p[0] * p[0] + p[1] * p[1] + p[2] * p[2]
        ph = 2.0 * (p[0] * h_r[0] + p[1] * h_r[1] + p[2] * h_r[2])
        for r in range(3):
            for k in range(3):
                d = 1.0 if r == k else 0.0
                cI[i, r, k] = (
                    inertia[i, r, k]
                    + I_r[r, k]
                    + m * (d * p2 - p[r] * p[k])
                    + (d * ph - p[r] * h_r[k] - h_r[r] * p[k])
                )
        for k in range(3):
            ch[i, k] = h[i, k] + h_r[k] + m * p[k]
        cm[i] = mass[i] + m
    fo = stack_array(3)
    no = stack_array(3)
    fc = stack_array(3)
    nc = stack_array(3)
    t1 = stack_array(3)
    for j in range(_N):
        fo[0], fo[1], fo[2] = -ch[j, 1], ch[j, 0], 0.0  # z x h
        no[0], no[1], no[2] = cI[j, 0, 2], cI[j, 1, 2], cI[j, 2, 2]  # I z
        M[j, j] = no[2]
        for i in range(j - 1, -1, -1):
            Rn = R[i + 1]
            _mv(Rn, fo, fc)
            _mv(Rn, no, nc)
            _cross(origin[i + 1], fc, t1)
            for k in range(3):
                fo[k] = fc[k]
                no[k] = nc[k] + t1[k]
            M[i, j] = no[2]
            M[j, i] = no[2]


@cache.keyed_jit(KEY, nogil=True, error_model="numpy")
def rnea_along(origin, ca, sa, mass, h, inertia, Q, dQ, ddQ, a_base, tau):  # type: ignore[no-untyped-def,unused-ignore]
    """:func:`rnea` at every row of ``Q``, ``dQ``, ``ddQ`` (N, 7) into the rows of
    ``tau`` (N, 7): the torques along a trajectory in one call."""
    for k in range(Q.shape[0]):
        rnea(origin, ca, sa, mass, h, inertia, Q[k], dQ[k], ddQ[k], a_base, tau[k])


def warmup() -> None:
    """Compile (or load from numba's cache) both kernels now, for the C-contiguous
    float64 arrays :class:`panda_py.dynamics.LoadedArm` passes, with a progress bar the
    first time after installing (several seconds)."""
    z7, z73, z733 = np.zeros(_N), np.zeros((_N, 3)), np.zeros((_N, 3, 3))
    with progress.work("panda_py: compiling the dynamics, once after installing", 3) as work:
        rnea(z73, z7, z7, z7, z73, z733, z7, z7, z7, np.zeros(3), np.empty(_N))
        work.advance()
        crba(z73, z7, z7, z7, z73, z733, z7, np.empty((_N, _N)))
        work.advance()
        z17 = np.zeros((1, _N))
        rnea_along(z73, z7, z7, z7, z73, z733, z17, z17, z17, np.zeros(3), np.empty((1, _N)))
        work.advance()
