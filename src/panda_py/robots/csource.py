"""Generate the C99 source of the native model library (see :mod:`panda_py.robots.clib`).

The library exports exactly the 30 plain-C functions libfranka 0.9.x (protocol v4..v9)
resolves after ``dlopen`` (fci-protocol.md §12.1): the poses ``O_T_J1..O_T_J9``, the zero
Jacobians ``O_J_J1..O_J_J9``, the body Jacobians ``Ji_J_J1..Ji_J_J9`` and the dynamics
``M_NE``, ``c_NE``, ``g_NE``. Frame n is libfranka's ``franka::Frame`` n-1: kJoint1..kJoint7
are the modified-DH frames J1..J7 (so frame J1 sits at z = d1 for q = 0), J8 is the
flange (kFlange) and J9 is the flange times the caller's ``F_T_EE`` (kEndEffector, or
kStiffness when libfranka passes ``F_T_EE * EE_T_K``). All matrices are column-major; a
Jacobian is 6x7 column-major with column j = (v_x, v_y, v_z, w_x, w_y, w_z) of joint j.
``O_J_Jn`` is the Jacobian of frame n's origin in base coordinates; ``Ji_J_Jn`` is the
same twist expressed in frame n.

The dynamics are the recursive Newton-Euler algorithm of :mod:`panda_py.dynamics` written
out in C (the mass matrix column by column: RNEA with ``ddq = e_j``, no velocity, no
gravity). ``g_NE`` is ``-J^T m g``, the torque that holds the arm against ``g_earth``
(libfranka passes ``O_ddP_O`` = (0, 0, -9.81)). Only ``sin`` and ``cos`` come from libm.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from panda_py.robots.params import RobotSpec, get_robot

__all__ = ["EXPORTED_SYMBOLS", "c_source"]

EXPORTED_SYMBOLS: tuple[str, ...] = (
    *(f"O_T_J{n}" for n in range(1, 10)),
    *(f"O_J_J{n}" for n in range(1, 10)),
    *(f"Ji_J_J{n}" for n in range(1, 10)),
    "M_NE",
    "c_NE",
    "g_NE",
)


def _c(x: float) -> str:
    """A C double literal that round-trips exactly (Python's repr is the shortest one)."""
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"cannot print a non-finite parameter {x!r} into C source")
    text = repr(x)
    return text if any(ch in text for ch in ".e") else text + ".0"


def _array(values: Sequence[float]) -> str:
    return "{" + ", ".join(_c(v) for v in values) + "}"


def _table(rows: Sequence[Sequence[float]]) -> str:
    return "{\n    " + ",\n    ".join(_array(r) for r in rows) + "\n}"


_BODY = r"""
typedef struct {
    double m;    /* mass [kg] */
    double h[3]; /* first moment m * com [kg m] */
    double I[9]; /* inertia about the frame origin, row-major [kg m^2] */
} body_t;

static void cross3(const double a[3], const double b[3], double out[3]) {
    double x = a[1] * b[2] - a[2] * b[1];
    double y = a[2] * b[0] - a[0] * b[2];
    double z = a[0] * b[1] - a[1] * b[0];
    out[0] = x;
    out[1] = y;
    out[2] = z;
}

static void mv3(const double m[9], const double v[3], double out[3]) {
    double x = m[0] * v[0] + m[1] * v[1] + m[2] * v[2];
    double y = m[3] * v[0] + m[4] * v[1] + m[5] * v[2];
    double z = m[6] * v[0] + m[7] * v[1] + m[8] * v[2];
    out[0] = x;
    out[1] = y;
    out[2] = z;
}

static void mtv3(const double m[9], const double v[3], double out[3]) {
    double x = m[0] * v[0] + m[3] * v[1] + m[6] * v[2];
    double y = m[1] * v[0] + m[4] * v[1] + m[7] * v[2];
    double z = m[2] * v[0] + m[5] * v[1] + m[8] * v[2];
    out[0] = x;
    out[1] = y;
    out[2] = z;
}

static void mm3(const double a[9], const double b[9], double out[9]) {
    int r, c;
    for (r = 0; r < 3; ++r) {
        for (c = 0; c < 3; ++c) {
            out[3 * r + c] = a[3 * r] * b[c] + a[3 * r + 1] * b[3 + c] + a[3 * r + 2] * b[6 + c];
        }
    }
}

/* R_{i-1,i} = RotX(alpha_i) RotZ(q_i), row-major. */
static void joint_rotation(int i, double q, double R[9]) {
    double cq = cos(q), sq = sin(q), ca = COS_ALPHA[i], sa = SIN_ALPHA[i];
    R[0] = cq;      R[1] = -sq;     R[2] = 0.0;
    R[3] = ca * sq; R[4] = ca * cq; R[5] = -sa;
    R[6] = sa * sq; R[7] = sa * cq; R[8] = ca;
}

/* Parallel-axis shift of an inertia about the centre of mass to the frame origin. */
static void about_origin(double m, const double c[3], const double Ic[9], body_t *b) {
    double c2 = c[0] * c[0] + c[1] * c[1] + c[2] * c[2];
    int r, k;
    b->m = m;
    for (r = 0; r < 3; ++r) {
        b->h[r] = m * c[r];
        for (k = 0; k < 3; ++k) {
            b->I[3 * r + k] = Ic[3 * r + k] + m * ((r == k ? c2 : 0.0) - c[r] * c[k]);
        }
    }
}

/* Links 1..7 about their frame origins; the load (I_load column-major, may be NULL)
   is rigidly attached at the flange, frame J7 shifted by FLANGE_D along z. */
static void make_bodies(double m_load, const double F_x_C[3], const double *I_load, body_t b[7]) {
    double Ic[9], c[3];
    body_t load;
    int i, r, k;
    for (i = 0; i < 7; ++i) {
        const double *in = LINK_INERTIA[i]; /* ixx iyy izz ixy ixz iyz about the COM */
        Ic[0] = in[0]; Ic[1] = in[3]; Ic[2] = in[4];
        Ic[3] = in[3]; Ic[4] = in[1]; Ic[5] = in[5];
        Ic[6] = in[4]; Ic[7] = in[5]; Ic[8] = in[2];
        about_origin(LINK_MASS[i], LINK_COM[i], Ic, &b[i]);
    }
    for (r = 0; r < 3; ++r) {
        for (k = 0; k < 3; ++k) {
            Ic[3 * r + k] = I_load ? I_load[r + 3 * k] : 0.0;
        }
    }
    c[0] = F_x_C[0];
    c[1] = F_x_C[1];
    c[2] = F_x_C[2] + FLANGE_D;
    about_origin(m_load, c, Ic, &load);
    b[6].m += load.m;
    for (r = 0; r < 3; ++r) {
        b[6].h[r] += load.h[r];
    }
    for (r = 0; r < 9; ++r) {
        b[6].I[r] += load.I[r];
    }
}

/* Recursive Newton-Euler: tau for (dq, ddq) with base acceleration a0 (= -gravity).
   Quantities of link i are in frame Ji, moments about its origin. */
static void rnea(const double R[7][9], const body_t b[7], const double dq[7],
                 const double ddq[7], const double a0[3], double tau[7]) {
    double w[3] = {0.0, 0.0, 0.0}, wd[3] = {0.0, 0.0, 0.0}, a[3];
    double f[7][3], n[7][3];
    double t1[3], t2[3], t3[3], wp[3], wdp[3];
    int i, k;
    a[0] = a0[0];
    a[1] = a0[1];
    a[2] = a0[2];
    for (i = 0; i < 7; ++i) {
        cross3(wd, ORIGIN[i], t1);
        cross3(w, ORIGIN[i], t2);
        cross3(w, t2, t3);
        for (k = 0; k < 3; ++k) {
            t1[k] = a[k] + t1[k] + t3[k];
        }
        mtv3(R[i], t1, a);
        mtv3(R[i], w, wp);
        mtv3(R[i], wd, wdp);
        w[0] = wp[0];
        w[1] = wp[1];
        w[2] = wp[2] + dq[i];
        wd[0] = wdp[0] + wp[1] * dq[i];
        wd[1] = wdp[1] - wp[0] * dq[i];
        wd[2] = wdp[2] + ddq[i];
        /* f = m a + wd x h + w x (w x h);  n = I wd + w x (I w) + h x a */
        cross3(w, b[i].h, t1);
        cross3(w, t1, t2);
        cross3(wd, b[i].h, t1);
        for (k = 0; k < 3; ++k) {
            f[i][k] = b[i].m * a[k] + t1[k] + t2[k];
        }
        mv3(b[i].I, w, t1);
        cross3(w, t1, t2);
        mv3(b[i].I, wd, t1);
        cross3(b[i].h, a, t3);
        for (k = 0; k < 3; ++k) {
            n[i][k] = t1[k] + t2[k] + t3[k];
        }
    }
    tau[6] = n[6][2];
    for (i = 5; i >= 0; --i) {
        mv3(R[i + 1], f[i + 1], t1);
        mv3(R[i + 1], n[i + 1], t2);
        cross3(ORIGIN[i + 1], t1, t3);
        for (k = 0; k < 3; ++k) {
            f[i][k] += t1[k];
            n[i][k] += t2[k] + t3[k];
        }
        tau[i] = n[i][2];
    }
}

static void rotations(const double q[7], double R[7][9]) {
    int i;
    for (i = 0; i < 7; ++i) {
        joint_rotation(i, q[i], R[i]);
    }
}

/* Frames 0 (base) .. 8 (flange) in base coordinates: rotation (row-major) and origin. */
static void frames(const double q[7], double OR[9][9], double Op[9][3]) {
    static const double zero_q[7] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    static const double flange[3] = {0.0, 0.0, FLANGE_D};
    double R[9], t[3];
    int i, k;
    if (!q) {
        q = zero_q;
    }
    for (k = 0; k < 9; ++k) {
        OR[0][k] = (k % 4 == 0) ? 1.0 : 0.0;
    }
    Op[0][0] = Op[0][1] = Op[0][2] = 0.0;
    for (i = 0; i < 7; ++i) {
        joint_rotation(i, q[i], R);
        mv3(OR[i], ORIGIN[i], t);
        for (k = 0; k < 3; ++k) {
            Op[i + 1][k] = Op[i][k] + t[k];
        }
        mm3(OR[i], R, OR[i + 1]);
    }
    mv3(OR[7], flange, t);
    for (k = 0; k < 3; ++k) {
        Op[8][k] = Op[7][k] + t[k];
    }
    memcpy(OR[8], OR[7], sizeof(OR[7]));
}

/* Pose of frame n (1..9; 9 = flange * F_T_EE, column-major) as rotation and origin. */
static void frame_pose(const double *q, int n, const double *F_T_EE, double Rn[9], double pn[3]) {
    double OR[9][9], Op[9][3];
    int k;
    frames(q, OR, Op);
    if (n <= 8) {
        memcpy(Rn, OR[n], sizeof(double) * 9);
        memcpy(pn, Op[n], sizeof(double) * 3);
        return;
    }
    {
        double Rf[9], t[3];
        int r, c;
        for (r = 0; r < 3; ++r) {
            for (c = 0; c < 3; ++c) {
                Rf[3 * r + c] = F_T_EE[r + 4 * c];
            }
        }
        mm3(OR[8], Rf, Rn);
        mv3(OR[8], F_T_EE + 12, t);
        for (k = 0; k < 3; ++k) {
            pn[k] = Op[8][k] + t[k];
        }
    }
}

static void pose(const double *q, int n, const double *F_T_EE, double out[16]) {
    double R[9], p[3];
    int r, c;
    frame_pose(q, n, F_T_EE, R, p);
    for (c = 0; c < 3; ++c) {
        for (r = 0; r < 3; ++r) {
            out[4 * c + r] = R[3 * r + c];
        }
        out[4 * c + 3] = 0.0;
    }
    out[12] = p[0];
    out[13] = p[1];
    out[14] = p[2];
    out[15] = 1.0;
}

/* Jacobian of frame n's origin: zero Jacobian (base coordinates) or, with body != 0,
   the same twist expressed in frame n. Joints beyond n do not move frame n. */
static void jacobian(const double *q, int n, const double *F_T_EE, int body, double out[42]) {
    double OR[9][9], Op[9][3], Rn[9], pn[3], z[3], d[3], v[3];
    int j, k;
    frames(q, OR, Op);
    frame_pose(q, n, F_T_EE, Rn, pn);
    for (j = 0; j < 7; ++j) {
        double *col = out + 6 * j;
        if (j + 1 > n) {
            for (k = 0; k < 6; ++k) {
                col[k] = 0.0;
            }
            continue;
        }
        z[0] = OR[j + 1][2];
        z[1] = OR[j + 1][5];
        z[2] = OR[j + 1][8];
        for (k = 0; k < 3; ++k) {
            d[k] = pn[k] - Op[j + 1][k];
        }
        cross3(z, d, v);
        if (body) {
            mtv3(Rn, v, col);
            mtv3(Rn, z, col + 3);
        } else {
            memcpy(col, v, sizeof(v));
            memcpy(col + 3, z, sizeof(z));
        }
    }
}

void M_NE(const double q[7], const double I_load[9], double m_load,
          const double F_x_Cload[3], double M[49]) {
    static const double zero[7] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    double R[7][9], ddq[7], col[7];
    body_t b[7];
    int i, j;
    rotations(q, R);
    make_bodies(m_load, F_x_Cload, I_load, b);
    for (j = 0; j < 7; ++j) {
        for (i = 0; i < 7; ++i) {
            ddq[i] = (i == j) ? 1.0 : 0.0;
        }
        rnea((const double(*)[9])R, b, zero, ddq, zero, col);
        for (i = 0; i < 7; ++i) {
            M[7 * j + i] = col[i];
        }
    }
    /* exact symmetry (the two triangles agree to rounding) */
    for (j = 0; j < 7; ++j) {
        for (i = j + 1; i < 7; ++i) {
            double s = 0.5 * (M[7 * j + i] + M[7 * i + j]);
            M[7 * j + i] = s;
            M[7 * i + j] = s;
        }
    }
}

void c_NE(const double q[7], const double dq[7], const double I_load[9], double m_load,
          const double F_x_Cload[3], double c[7]) {
    static const double zero[7] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    double R[7][9];
    body_t b[7];
    rotations(q, R);
    make_bodies(m_load, F_x_Cload, I_load, b);
    rnea((const double(*)[9])R, b, dq, zero, zero, c);
}

void g_NE(const double q[7], const double g_earth[3], double m_load,
          const double F_x_Cload[3], double g[7]) {
    static const double zero[7] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
    double R[7][9], a0[3];
    body_t b[7];
    rotations(q, R);
    make_bodies(m_load, F_x_Cload, 0, b);
    a0[0] = -g_earth[0];
    a0[1] = -g_earth[1];
    a0[2] = -g_earth[2];
    rnea((const double(*)[9])R, b, zero, zero, a0, g);
}
"""


def _exports() -> str:
    lines = []
    for n in range(1, 10):
        if n == 9:
            lines.append(
                "void O_T_J9(const double q[7], const double F_T_EE[16], double out[16]) "
                "{ pose(q, 9, F_T_EE, out); }"
            )
        else:
            lines.append(
                f"void O_T_J{n}(const double q[7], double out[16]) {{ pose(q, {n}, 0, out); }}"
            )
    for prefix, body in (("O_J_J", 0), ("Ji_J_J", 1)):
        lines.append(f"void {prefix}1(double out[42]) {{ jacobian(0, 1, 0, {body}, out); }}")
        for n in range(2, 9):
            lines.append(
                f"void {prefix}{n}(const double q[7], double out[42]) "
                f"{{ jacobian(q, {n}, 0, {body}, out); }}"
            )
        lines.append(
            f"void {prefix}9(const double q[7], const double F_T_EE[16], double out[42]) "
            f"{{ jacobian(q, 9, F_T_EE, {body}, out); }}"
        )
    return "\n".join(lines) + "\n"


def c_source(robot: str | RobotSpec = "fer") -> str:
    """The C99 source of the model library for ``robot``, generated from the parameter
    tables (lengths [m], angles [rad], masses [kg], inertias [kg m^2])."""
    spec = get_robot(robot)
    dh = spec.dh
    ca = [math.cos(a) for a in dh.alpha]
    sa = [math.sin(a) for a in dh.alpha]
    # origin of Ji in J(i-1): RotX(alpha) TransX(a) RotZ(q) TransZ(d) -> RotX(alpha) (a, 0, d)
    origin = [(dh.a[i], -sa[i] * dh.d[i], ca[i] * dh.d[i]) for i in range(7)]
    links = spec.links[1:8]
    head = f"""\
/* Model library of the {spec.name} arm for libfranka 0.9.x (FCI protocol v4..v9).
   Generated by panda_py.robots.csource from panda_py.robots.params; do not edit. */
#include <math.h>
#include <string.h>

static const double COS_ALPHA[7] = {_array(ca)};
static const double SIN_ALPHA[7] = {_array(sa)};
/* origin of frame Ji in frame J(i-1) [m] */
static const double ORIGIN[7][3] = {_table(origin)};
#define FLANGE_D {_c(dh.flange_d)}
/* links 1..7 in their DH frames: mass [kg], centre of mass [m], inertia about the
   centre of mass (ixx, iyy, izz, ixy, ixz, iyz) [kg m^2] */
static const double LINK_MASS[7] = {_array([link.mass for link in links])};
static const double LINK_COM[7][3] = {_table([link.com for link in links])};
static const double LINK_INERTIA[7][6] = {_table([link.inertia for link in links])};
"""
    return head + _BODY + "\n" + _exports()
