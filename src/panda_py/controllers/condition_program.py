"""A guarded move's condition (:mod:`.conditions`) compiled into a flat program that the
control loop's compiled ticks (:mod:`panda_py.rt._tick`) evaluate on each tick's raw
state datagram, so a guarded move's ticks stay in the compiled loop until its condition
holds; the tick on which it does is handed to Python, where the move's ``check_until``
(:meth:`Condition.holds <.conditions.Condition.holds>`, the reference) decides as on
every other tick.

The program is the condition tree in postfix order, one row of ``COLUMNS`` float64 a
node (every integer in it is exact as a float64):

* a comparison ``quantity op threshold``: ``VALUE`` (one float of the state at a byte
  offset, float32 or float64 as the protocol lays it out: :func:`panda_py.fci.dialect`),
  ``NORM`` (the Euclidean norm of ``COUNT`` of them), ``ELAPSED`` or ``DISTANCE`` (the
  move's :class:`~.plans.Progress`, given by the tick);
* ``ERRORS``: any of the ``COUNT`` error flags (bytes) at the offset set;
* ``AND``, ``OR`` (of the ``COUNT`` results before), ``NOT`` (of the one before).

Its answer is three-valued: ``FALSE``, ``TRUE``, or ``UNKNOWN`` where a value is not
finite or, for a value the program computes otherwise than Python does (a norm, a
Cartesian move's distance: the last bits of their rounding may differ), lies within
``MARGIN`` of its threshold; ``AND``, ``OR``, ``NOT`` combine them as Kleene's logic
does. ``FALSE`` is then certain (the reference would not hold either); ``TRUE`` and
``UNKNOWN`` hand the tick to Python. A condition it cannot express (a function of the
state, ``when(f)``; a condition class of the user's; a field this protocol version lacks)
compiles to None: the move's every tick is Python's, as before.

:func:`evaluate` is written in the subset of Python numba compiles: the compiled ticks
compile it as it is (plain, it is the program's own reference in tests).
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py.controllers import conditions as cond
from panda_py.fci import dialect

__all__ = ["COLUMNS", "compile_condition", "evaluate"]

FloatArray = NDArray[np.float64]

# a row's columns
OP, OFFSET, SIZE, COUNT, CMP, THRESHOLD, APPROX = range(7)
COLUMNS = 7
# OP: the nodes
VALUE, NORM, ELAPSED, DISTANCE, ERRORS, AND, OR, NOT = range(8)
# CMP: the comparisons (conditions.Compare.op)
_CMPS = {"<": 0, "<=": 1, ">": 2, ">=": 3}
# the answers, ordered so that AND is min, OR is max and NOT is TRUE - x (Kleene's logic)
FALSE, UNKNOWN, TRUE = 0.0, 1.0, 2.0
# relative closeness to a threshold within which a value the program computes otherwise
# than Python (APPROX) may compare otherwise: a few ulp apart at most (a norm's sum of
# squares against math.hypot, BLAS's dot against a loop), 1e-12 is some 4,000 ulp
MARGIN = 1e-12


def compile_condition(condition: Any, version: int, *, exact_distance: bool) -> FloatArray | None:
    """``condition`` (of :mod:`.conditions`) as a program over states of robot protocol
    ``version`` (rows of COLUMNS), or None where it cannot be compiled (see the module's
    docstring). ``exact_distance``: whether the ticks compute the move's distance as its
    Python step does, to the bit (a joint move's largest joint error) or not (a norm)."""
    fields = dialect(version).state_dtype.fields
    assert fields is not None
    rows: list[list[float]] = []
    if not _emit(condition, fields, exact_distance, rows):
        return None
    return np.array(rows, dtype=np.float64).reshape(len(rows), COLUMNS)


def _emit(node: Any, fields: Any, exact_distance: bool, rows: list[list[float]]) -> bool:
    """Append ``node``'s rows (its parts' first); False where it cannot be compiled."""
    kind = type(node)
    if kind is cond.All or kind is cond.Any_:
        if not all(_emit(part, fields, exact_distance, rows) for part in node.parts):
            return False
        rows.append([AND if kind is cond.All else OR, 0, 0, len(node.parts), 0, 0, 0])
        return True
    if kind is cond.Not:
        if not _emit(node.part, fields, exact_distance, rows):
            return False
        rows.append([NOT, 0, 0, 1, 0, 0, 0])
        return True
    if kind is cond._ErrorsHold:  # (any byte of the flags set: _ErrorsHold.holds)
        sub, offset = fields["errors"][:2]
        rows.append([ERRORS, offset, 1, sub.itemsize, 0, 0, 0])
        return True
    if kind is not cond.Compare:
        return False  # when(f), a user's condition class: Python's
    q, cmp, threshold = node.quantity, _CMPS[node.op], node.threshold
    if q.source == "elapsed":
        rows.append([ELAPSED, 0, 0, 0, cmp, threshold, 0])
        return True
    if q.source == "distance":
        rows.append([DISTANCE, 0, 0, 0, cmp, threshold, 0 if exact_distance else 1])
        return True
    found = fields.get(q.source)
    if found is None or len(found[0].shape) > 1:
        return False  # this version lacks it (it reads a default), or a matrix: Python's
    sub, offset = found[:2]
    base = sub.base
    if base.kind != "f" or base.itemsize not in (4, 8) or base.byteorder == ">":
        return False
    size = base.itemsize
    if q.index is not None:
        rows.append([VALUE, offset + size * q.index, size, 1, cmp, threshold, 0])
    elif q.stop:
        rows.append([NORM, offset + size * q.start, size, q.stop - q.start, cmp, threshold, 1])
    else:  # a one-value field
        rows.append([VALUE, offset, size, 1, cmp, threshold, 0])
    return True


def evaluate(
    program: FloatArray, stack: FloatArray, data: NDArray[np.uint8], tmp: FloatArray,
    elapsed: float, distance: float,
) -> float:  # fmt: skip
    """``program`` on the state datagram ``data`` (uint8) with the move's ``elapsed``
    and ``distance``: FALSE, UNKNOWN or TRUE. ``stack`` (float64, one a row) and ``tmp``
    (float64, at least one) are its scratch."""
    top = 0
    raw = tmp.view(np.uint8)
    small = tmp.view(np.float32)
    for r in range(program.shape[0]):
        op = int(program[r, OP])
        count = int(program[r, COUNT])
        if op == AND or op == OR:
            top -= count
            v = stack[top]
            for i in range(1, count):
                w = stack[top + i]
                v = min(v, w) if op == AND else max(v, w)
            stack[top] = v
            top += 1
            continue
        if op == NOT:
            stack[top - 1] = TRUE - stack[top - 1]
            continue
        at = int(program[r, OFFSET])
        if op == ERRORS:
            v = FALSE
            for i in range(count):
                if data[at + i] != 0:
                    v = TRUE
            stack[top] = v
            top += 1
            continue
        if op == ELAPSED:
            value = elapsed
        elif op == DISTANCE:
            value = distance
        else:  # VALUE, NORM: floats of the state, decoded to float64 as TickState does
            size = int(program[r, SIZE])
            value = 0.0
            for i in range(count):
                for b in range(size):
                    raw[b] = data[at + size * i + b]
                x = tmp[0] if size == 8 else np.float64(small[0])
                if op == VALUE:
                    value = x
                else:
                    value += x * x
            if op == NORM:
                value = math.sqrt(value)
        threshold = program[r, THRESHOLD]
        if not math.isfinite(value):
            v = UNKNOWN
        elif program[r, APPROX] != 0.0 and abs(value - threshold) < MARGIN * max(
            abs(value), abs(threshold)
        ):
            v = UNKNOWN
        else:
            c = int(program[r, CMP])
            if c == 0:
                held = value < threshold
            elif c == 1:
                held = value <= threshold
            elif c == 2:
                held = value > threshold
            else:
                held = value >= threshold
            v = TRUE if held else FALSE
        stack[top] = v
        top += 1
    return stack[0] if top > 0 else FALSE
