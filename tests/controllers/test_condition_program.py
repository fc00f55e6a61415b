"""A guarded move's condition compiled (controllers/condition_program.py) against the
condition's own ``holds`` (the reference), on randomised states of every protocol
layout: every kind of quantity, every comparison, ``&``, ``|``, ``~`` nested, thresholds
on the state's own values (where ``<`` and ``<=`` part), NaN and infinities. The program
may answer UNKNOWN (the tick goes to Python) only where a value it computes otherwise
than Python does lies at its threshold or is not finite; otherwise it answers as
``holds`` does, plain and compiled alike."""

from __future__ import annotations

import importlib
from typing import Any

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from panda_py import fci
from panda_py.controllers.condition_program import (
    FALSE,
    TRUE,
    UNKNOWN,
    compile_condition,
    evaluate,
)
from panda_py.controllers.conditions import (
    Condition,
    Distance,
    Elapsed,
    Errors,
    Field,
    Force,
    ForceEE,
    Moment,
    MomentEE,
    Progress,
    Torque,
    when,
)
from panda_py.libfranka.state import TickState
from panda_py.rt import fastloop

VERSIONS = (3, 5, 10)
SIZES = fci.state_float_fields()
MATRICES = ("accelerometer_top", "accelerometer_bottom")  # (6, 3): Python's alone
VECTORS = [name for name, n in SIZES.items() if n > 1 and name not in MATRICES]
SCALARS = [name for name, n in SIZES.items() if n == 1]
# the moves' loop kernels (where numba runs the ticks)
_TICK = None if fastloop.kernels() is None else importlib.import_module(fastloop.KERNEL_MODULES[2])


def _state(version: int, seed: int) -> TickState:
    """A state of ``version`` with every float field random (some exactly 0, some -0.0,
    some repeated), a few error flags set."""
    d = fci.dialect(version)
    rng = np.random.default_rng(seed)
    r = np.zeros((), d.state_dtype)
    for name in d.state_dtype.names or ():
        sub = d.state_dtype.fields[name][0]  # type: ignore[index]
        if sub.base.kind != "f":
            continue
        values = rng.normal(0.0, 10.0, sub.shape).astype(sub.base)
        values[rng.random(sub.shape) < 0.1] = 0.0
        values[rng.random(sub.shape) < 0.05] = -0.0
        r[name] = values
    if rng.random() < 0.5:
        r["errors"][rng.integers(0, r["errors"].size)] = True
    return TickState(d, r.tobytes())


def _quantities(draw: Any, state: TickState) -> tuple[Any, list[float], bool]:
    """A quantity, values of the state it may be compared against, and whether the
    program computes it to the bit."""
    kind = draw(st.sampled_from(["axis", "torque", "field", "norm", "scalar", "progress"]))
    if kind == "axis":
        vec = draw(st.sampled_from([Force, Moment, ForceEE, MomentEE]))
        axis = draw(st.sampled_from(["x", "y", "z"]))
        q = getattr(vec, axis)
    elif kind == "torque":
        q = Torque[draw(st.integers(0, 6))]
    elif kind == "field":
        name = draw(st.sampled_from(VECTORS))
        q = Field(name)[draw(st.integers(0, SIZES[name] - 1))]
    elif kind == "norm":
        q = draw(st.sampled_from([Force, Moment, ForceEE, MomentEE, Torque])).norm
        if draw(st.booleans()):
            q = Field(draw(st.sampled_from(VECTORS))).norm
        return q, [q.value(state, None)], False
    elif kind == "scalar":
        q = Field(draw(st.sampled_from(SCALARS)))._one
    else:
        q = draw(st.sampled_from([Elapsed, Distance]))
        return q, [], True
    return q, [q.value(state, None)], True


@st.composite
def conditions(draw: Any, state: TickState, depth: int = 0) -> tuple[Condition, bool]:
    """A condition tree and whether each of its values is computed to the bit."""
    if depth < 3 and draw(st.integers(0, 2)) == 0:
        parts = [draw(conditions(state, depth + 1)) for _ in range(draw(st.integers(2, 3)))]
        op = draw(st.sampled_from(["&", "|"]))
        c = parts[0][0]
        for p in parts[1:]:
            c = (c & p[0]) if op == "&" else (c | p[0])
        exact = all(p[1] for p in parts)
        return (~c if draw(st.booleans()) else c), exact
    if draw(st.integers(0, 9)) == 0:
        return Errors, True
    q, values, exact = _quantities(draw, state)
    candidates = [*values, 0.0, -5.0, 3.3, 1e-300, 0.05, 0.1]
    if draw(st.booleans()):
        threshold = draw(st.sampled_from(candidates))
    else:
        threshold = draw(st.floats(-50.0, 50.0, allow_nan=False))
    op = draw(st.sampled_from(["<", "<=", ">", ">="]))
    c = {"<": q < threshold, "<=": q <= threshold, ">": q > threshold, ">=": q >= threshold}[op]
    return (~c if draw(st.integers(0, 4)) == 0 else c), exact


def _needs_python(c: Any, version: int) -> bool:
    """Whether ``c`` reads a field ``version`` lacks (it reads a default there)."""
    layout = fci.dialect(version).state_dtype.fields
    for part in getattr(c, "parts", ()) or ([c.part] if hasattr(c, "part") else []):
        if _needs_python(part, version):
            return True
    q = getattr(c, "quantity", None)
    return q is not None and q.source in SIZES and q.source not in layout


def _answers(program: np.ndarray, state: TickState, progress: Progress) -> list[float]:
    """The program's answer, plain and (where numba runs) compiled."""
    data = np.frombuffer(state.raw, np.uint8)
    args = (data, np.zeros(2), progress.elapsed, progress.distance)
    out = [evaluate(program, np.zeros(len(program)), *args)]
    if _TICK is not None:
        out.append(_TICK._condition_holds(program, np.zeros(len(program)), *args))
    return out


@settings(max_examples=400, deadline=None)
@given(data=st.data(), version=st.sampled_from(VERSIONS), seed=st.integers(0, 2**32 - 1))
def test_the_program_answers_as_the_condition_holds(data: Any, version: int, seed: int) -> None:
    state = _state(version, seed)
    condition, exact = data.draw(conditions(state))
    progress = Progress(
        data.draw(st.sampled_from([0.0, 0.05, 0.1, 3.3, 12.5])),
        data.draw(st.sampled_from([0.0, 0.05, 1e-300, 0.1, 2.0])),
    )
    program = compile_condition(condition, version, exact_distance=True)
    if _needs_python(condition, version):
        assert program is None
        return
    assert program is not None
    holds = condition.holds(state, progress)
    answers = _answers(program, state, progress)
    assert len(set(answers)) == 1  # plain and compiled alike
    answer = answers[0]
    if exact:
        assert answer == (TRUE if holds else FALSE), condition
    else:
        assert answer in ((TRUE, UNKNOWN) if holds else (FALSE, UNKNOWN)), condition


@pytest.mark.parametrize("version", VERSIONS)
def test_non_finite_values_and_near_thresholds_are_pythons_to_judge(version: int) -> None:
    d = fci.dialect(version)
    r = np.zeros((), d.state_dtype)
    r["O_F_ext_hat_K"] = [3.0, 4.0, np.nan, np.inf, 0.0, 0.0]
    state = TickState(d, r.tobytes())
    progress = Progress(0.5, 0.1)

    def answer(c: Condition, exact_distance: bool = True) -> float:
        program = compile_condition(c, version, exact_distance=exact_distance)
        assert program is not None
        (out, *_) = _answers(program, state, progress)
        return out

    assert answer(Force.z < 0.0) == UNKNOWN  # NaN: holds() says no, ~ of it yes
    assert answer(~(Force.z < 0.0)) == UNKNOWN and (~(Force.z < 0.0)).holds(state, progress)
    assert answer(Moment.x > 0.0) == UNKNOWN  # inf
    assert answer(Field("O_F_ext_hat_K", 0) < 5.0) == TRUE  # a value read as it is
    # the norm 5.0 (3-4-5): at its threshold the program defers, a little off it decides
    force_xy = Field._view("O_F_ext_hat_K", "F", 0, 2).norm
    assert answer(force_xy > 5.0) == UNKNOWN and answer(force_xy >= 5.0) == UNKNOWN
    assert answer(force_xy > 4.999) == TRUE and answer(force_xy < 4.999) == FALSE
    # a distance computed otherwise than Python's: deferred at its threshold only
    assert answer(Distance < 0.1, exact_distance=False) == UNKNOWN
    assert answer(Distance < 0.1) == FALSE and answer(Distance <= 0.1) == TRUE
    assert answer(Distance < 0.1000001, exact_distance=False) == TRUE
    # Kleene's logic: FALSE decides an &, TRUE an |, whatever the unknown part
    assert answer((Force.z < 0.0) & (Elapsed > 1.0)) == FALSE
    assert answer((Force.z < 0.0) | (Elapsed < 1.0)) == TRUE
    assert answer((Force.z < 0.0) | (Elapsed > 1.0)) == UNKNOWN


def test_what_only_python_can_evaluate_compiles_to_none() -> None:
    class Mine(Condition):
        def holds(self, state: Any, progress: Any) -> bool:
            return True

    assert compile_condition(when(lambda s: True), 5, exact_distance=True) is None
    assert compile_condition((Force.z < 0.0) | when(bool), 5, exact_distance=True) is None
    assert compile_condition(Mine() & (Elapsed > 1.0), 5, exact_distance=True) is None
    assert compile_condition(Field("accelerometer_top")[0] > 1.0, 10, exact_distance=True) is None
    # a field the version lacks reads a default (RobotState.O_ddP_O before v5): Python's
    assert compile_condition(Field("O_ddP_O")[2] < 0.0, 4, exact_distance=True) is None
    assert compile_condition(Field("O_ddP_O")[2] < 0.0, 5, exact_distance=True) is not None


@pytest.mark.skipif(_TICK is None, reason="numba runs the ticks")
def test_the_ticks_distance_is_the_moves() -> None:
    """``_until_holds``' distance: a joint move's to the bit (its largest joint error, NaN
    where a joint is), a Cartesian move's within the margin of Python's norm."""
    rng = np.random.default_rng(3)
    for _ in range(200):
        goal, at = rng.normal(0.0, 1.0, 7), rng.normal(0.0, 1.0, 7)
        joint = float(np.abs(goal - at).max())
        pose = float(np.linalg.norm(at[:3] - goal[:3]))
        for distance, joints, n, exact in ((joint, True, 7, True), (pose, False, 3, False)):
            for op in ("<", "<="):
                c = Distance < distance if op == "<" else Distance <= distance
                program = compile_condition(c, 5, exact_distance=exact)
                assert program is not None
                buf = np.zeros(8, np.uint8)
                got = _TICK._until_holds(program, np.zeros(1), buf, np.zeros(2), 0.0, goal, at,
                                         n, joints)  # fmt: skip
                # at its own distance: < does not hold, <= does; a Cartesian move's,
                # computed otherwise, defers to Python (which then decides) at either
                assert got == (op == "<=" or not exact)
    at = np.zeros(7)
    at[4] = np.nan
    program = compile_condition(~(Distance < 1.0), 5, exact_distance=True)
    assert program is not None
    assert _TICK._until_holds(program, np.zeros(1), np.zeros(8, np.uint8), np.zeros(2), 0.0,
                              np.zeros(7), at, 7, True)  # fmt: skip
