"""Straight-line code for the forward kinematics, generated from the DH table at import.

A forward-kinematics call on one configuration is dominated by interpreter overhead, not
arithmetic: one NumPy ufunc on a 4x4 costs about a microsecond, one Python float operation
about ten nanoseconds. So the chain of DH transforms is multiplied out symbolically here,
with every product by an exact 0 or +-1 (the twist angles are multiples of pi/2) and every
constant scale folded away, and the remaining few hundred scalar operations are emitted as
one flat function. The same source, compiled against ``numpy`` instead of ``math``,
evaluates N configurations at once (every name is then an (N,) array).

Nothing here is hand-tuned for the Panda's numbers: the DH table comes from
:mod:`panda_py.robots.params`, so the generated code follows it.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field

# A twist/rotation constant closer than this to 0 or +-1 is taken as exact [-]: cos(pi/2)
# evaluates to 6e-17 in floating point and would otherwise cost a multiplication.
SNAP_TOL = 1e-12


def _snap(x: float) -> float:
    for exact in (0.0, 1.0, -1.0):
        if abs(x - exact) < SNAP_TOL:
            return exact
    return x


@dataclass(frozen=True)
class Val:
    """``scale * name`` (a generated variable), or the constant ``scale`` if ``name`` is
    None. Keeping the scale symbolic makes multiplication by a constant free."""

    name: str | None
    scale: float = 1.0

    @property
    def is_zero(self) -> bool:
        return self.scale == 0.0


ZERO = Val(None, 0.0)
ONE = Val(None, 1.0)


def const(x: float) -> Val:
    return Val(None, _snap(x))


def _lit(x: float) -> str:
    return repr(float(x))


@dataclass
class Emitter:
    """Collects ``name = expression`` lines; each helper returns the folded :class:`Val`."""

    lines: list[str] = field(default_factory=list)
    count: int = 0
    ops: int = 0

    def fresh(self, expr: str, ops: int) -> str:
        self.count += 1
        name = f"t{self.count}"
        self.lines.append(f"{name} = {expr}")
        self.ops += ops
        return name

    def mul(self, a: Val, b: Val) -> Val:
        if a.is_zero or b.is_zero:
            return ZERO
        if a.name is None:
            return Val(b.name, a.scale * b.scale) if b.name else const(a.scale * b.scale)
        if b.name is None:
            return Val(a.name, a.scale * b.scale)
        return Val(self.fresh(f"{a.name} * {b.name}", 1), a.scale * b.scale)

    def add(self, a: Val, b: Val) -> Val:
        if a.is_zero:
            return b
        if b.is_zero:
            return a
        if a.name is None and b.name is None:
            return const(a.scale + b.scale)
        if a.name is None:
            a, b = b, a
        assert a.name is not None
        if b.name is None:  # k a + c = k (a + c/k)
            return Val(self.fresh(f"{a.name} + {_lit(b.scale / a.scale)}", 1), a.scale)
        ratio = b.scale / a.scale
        if ratio == 1.0:
            return Val(self.fresh(f"{a.name} + {b.name}", 1), a.scale)
        if ratio == -1.0:
            return Val(self.fresh(f"{a.name} - {b.name}", 1), a.scale)
        if b.scale in (1.0, -1.0):  # keep the unit-scale one unscaled: b +- (k/1) a
            op = "+" if b.scale == 1.0 else "-"
            r = a.scale / b.scale
            return Val(self.fresh(f"{_lit(r)} * {a.name} {op} {b.name}", 2), b.scale)
        return Val(self.fresh(f"{a.name} + {_lit(ratio)} * {b.name}", 2), a.scale)

    def lin(self, terms: Sequence[tuple[Val, Val]]) -> Val:
        """sum of products"""
        acc = ZERO
        for a, b in terms:
            acc = self.add(acc, self.mul(a, b))
        return acc

    def materialize(self, v: Val) -> str:
        """An expression for v with its scale applied (for the outputs)."""
        if v.name is None:
            return _lit(v.scale)
        if v.scale == 1.0:
            return v.name
        if v.scale == -1.0:
            return f"-{v.name}"
        return f"{_lit(v.scale)} * {v.name}"


Mat3 = list[list[Val]]
Vec3 = list[Val]


def _rot_const(em: Emitter, R: Mat3, C: Sequence[Sequence[float]]) -> Mat3:
    """R @ C for a constant 3x3 C."""
    return [
        [em.lin([(R[i][k], const(C[k][j])) for k in range(3)]) for j in range(3)] for i in range(3)
    ]


def _rotz(em: Emitter, R: Mat3, c: Val, s: Val) -> Mat3:
    """R @ RotZ(q) with c = cos q, s = sin q."""
    neg_s = Val(s.name, -s.scale)
    out = []
    for row in R:
        x = em.lin([(row[0], c), (row[1], s)])
        y = em.lin([(row[0], neg_s), (row[1], c)])
        out.append([x, y, row[2]])
    return out


def _translate(em: Emitter, R: Mat3, p: Vec3, t: Sequence[float]) -> Vec3:
    """p + R @ t for a constant t."""
    return [em.add(p[i], em.lin([(R[i][k], const(t[k])) for k in range(3)])) for i in range(3)]


def _rotx(alpha: float) -> list[list[float]]:
    c, s = math.cos(alpha), math.sin(alpha)
    return [[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]


@dataclass(frozen=True)
class ChainSpec:
    """Modified-DH chain plus a constant tail transform (flange, end effector).

    ``tail_rotz``/``tail_z`` describe a tail that is a rotation about and a translation
    along the last joint's z axis: it is folded into the last joint angle. Any other tail
    is given as ``tail_R``/``tail_p`` (constant rotation and translation after the last
    joint, applied generically).
    """

    a: tuple[float, ...]
    d: tuple[float, ...]
    alpha: tuple[float, ...]
    flange_d: float
    tail_rotz: float = 0.0
    tail_z: float = 0.0
    tail_R: tuple[tuple[float, ...], ...] | None = None
    tail_p: tuple[float, float, float] | None = None


def generate(spec: ChainSpec, *, output: str = "ee", name: str = "kin") -> tuple[str, int]:
    """Source of ``def name(q1..q7)`` (using global ``sin``/``cos``) and its number of
    arithmetic operations. The function returns a flat tuple:

    * ``output="ee"``: the 16 entries (row-major) of ``O_T_EE``;
    * ``"frames"``: 16 entries for each of J1..J7, flange, EE (libfranka's Frame order);
    * ``"jacobian"``: the 16 of ``O_T_EE`` then the 42 of the geometric Jacobian of the EE
      in the base frame (rows vx, vy, vz, wx, wy, wz; row-major 6x7).
    """
    if output not in ("ee", "frames", "jacobian"):
        raise ValueError(f"output: expected 'ee', 'frames' or 'jacobian', got {output!r}")
    n = len(spec.a)
    em = Emitter()
    args = [f"q{i + 1}" for i in range(n)]
    R: Mat3 = [[ONE, ZERO, ZERO], [ZERO, ONE, ZERO], [ZERO, ZERO, ONE]]
    p: Vec3 = [ZERO, ZERO, ZERO]
    out: list[Val] = []
    joints: list[tuple[Vec3, Vec3]] = []  # (z axis, origin) of each joint frame

    def emit_frame(R: Mat3, p: Vec3) -> None:
        for i in range(3):
            out.extend([R[i][0], R[i][1], R[i][2], p[i]])
        out.extend([ZERO, ZERO, ZERO, ONE])

    fold_tail = spec.tail_R is None and output != "frames"
    for i in range(n):
        R = _rot_const(em, R, _rotx(spec.alpha[i]))
        p = _translate(em, R, p, (spec.a[i], 0.0, 0.0))
        angle = args[i]
        if i == n - 1 and fold_tail and spec.tail_rotz != 0.0:
            angle = f"({angle} + {_lit(spec.tail_rotz)})"
        c = Val(em.fresh(f"cos({angle})", 0))
        s = Val(em.fresh(f"sin({angle})", 0))
        R = _rotz(em, R, c, s)
        p = _translate(em, R, p, (0.0, 0.0, spec.d[i]))
        joints.append(([R[0][2], R[1][2], R[2][2]], p))
        if output == "frames":
            emit_frame(R, p)
    if fold_tail:
        p = _translate(em, R, p, (0.0, 0.0, spec.flange_d + spec.tail_z))
    else:
        p = _translate(em, R, p, (0.0, 0.0, spec.flange_d))
        if output == "frames":
            emit_frame(R, p)
        if spec.tail_R is not None:
            assert spec.tail_p is not None
            p = _translate(em, R, p, spec.tail_p)
            R = _rot_const(em, R, spec.tail_R)
        else:
            p = _translate(em, R, p, (0.0, 0.0, spec.tail_z))
            cz, sz = math.cos(spec.tail_rotz), math.sin(spec.tail_rotz)
            R = _rot_const(em, R, [[cz, -sz, 0.0], [sz, cz, 0.0], [0.0, 0.0, 1.0]])
    emit_frame(R, p)
    if output == "jacobian":
        lin: list[list[Val]] = [[], [], []]
        for z, o in joints:  # v_i = z_i x (p_EE - o_i)
            dx = em.add(p[0], Val(o[0].name, -o[0].scale))
            dy = em.add(p[1], Val(o[1].name, -o[1].scale))
            dz = em.add(p[2], Val(o[2].name, -o[2].scale))
            neg = lambda v: Val(v.name, -v.scale)  # noqa: E731
            lin[0].append(em.lin([(z[1], dz), (neg(z[2]), dy)]))
            lin[1].append(em.lin([(z[2], dx), (neg(z[0]), dz)]))
            lin[2].append(em.lin([(z[0], dy), (neg(z[1]), dx)]))
        for k in range(3):
            out.extend(lin[k])
        for k in range(3):
            out.extend(z[k] for z, _ in joints)
    body = [*em.lines, "return (" + ", ".join(em.materialize(v) for v in out) + ")"]
    src = f"def {name}({', '.join(args)}):\n" + "\n".join("    " + ln for ln in body)
    return src + "\n", em.ops


def compile_chain(spec: ChainSpec, output: str, namespace: Mapping[str, object]) -> object:
    """Generate and compile the function with ``namespace`` providing ``sin``/``cos``
    (``math``'s for scalars, ``numpy``'s for arrays)."""
    src, _ = generate(spec, output=output)
    code = compile(src, f"<panda_py.kinematics generated {output}>", "exec")
    ns = dict(namespace)
    exec(code, ns)
    return ns["kin"]
