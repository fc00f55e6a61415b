"""Conditions for guarded moves: what each reads, how they combine, how they print and
travel, and the errors for what cannot be a condition."""

from __future__ import annotations

import pickle
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from panda_py.conditions import (
    Condition,
    Distance,
    Elapsed,
    Errors,
    Field,
    Force,
    ForceEE,
    Moment,
    Torque,
    when,
)
from panda_py.controllers.moves import Progress


def state(**fields: Any) -> SimpleNamespace:
    base = {
        "O_F_ext_hat_K": np.zeros(6),
        "K_F_ext_hat_K": np.zeros(6),
        "tau_ext_hat_filtered": np.zeros(7),
        "dq": np.zeros(7),
        "current_errors": (),
    }
    base.update({k: np.asarray(v, dtype=float) if k != "current_errors" else v
                 for k, v in fields.items()})  # fmt: skip
    return SimpleNamespace(**base)


AT_START = Progress(elapsed=0.0, distance=0.1)


def test_each_quantity_reads_its_field_with_libfrankas_sign() -> None:
    pressing = state(O_F_ext_hat_K=[1.0, -2.0, -12.0, 0.0, 0.3, 0.4])
    assert (Force.z < -10.0).holds(pressing, AT_START)  # the robot pushes down
    assert not (Force.z > 0.0).holds(pressing, AT_START)
    assert (Force.norm > 12.2).holds(pressing, AT_START)  # sqrt(149) = 12.21
    assert not (Force.norm > 12.3).holds(pressing, AT_START)
    assert (Moment.norm >= 0.5).holds(pressing, AT_START)
    assert (Moment.y <= 0.3).holds(pressing, AT_START)
    assert (ForceEE.z > 5.0).holds(state(K_F_ext_hat_K=[0, 0, 12.0, 0, 0, 0]), AT_START)
    joint = state(tau_ext_hat_filtered=[0, 0, 0, 3.0, 0, 0, -4.0])
    assert (Torque[3] > 2.5).holds(joint, AT_START)
    assert (Torque[6] < -3.5).holds(joint, AT_START)
    assert (Torque.norm > 4.9).holds(joint, AT_START) and not (Torque.norm > 5.1).holds(
        joint, AT_START
    )
    assert (Field("dq").norm > 0.1).holds(state(dq=[0, 0.2, 0, 0, 0, 0, 0]), AT_START)
    later = Progress(elapsed=2.5, distance=0.004)
    assert (Elapsed > 2.0).holds(state(), later) and not (Elapsed > 2.0).holds(state(), AT_START)
    assert (Distance < 0.005).holds(state(), later)
    assert Errors.holds(state(current_errors=("joint_reflex",)), AT_START)
    assert not Errors.holds(state(), AT_START)


def test_conditions_combine_with_and_or_not() -> None:
    hit = state(O_F_ext_hat_K=[0, 0, -12.0, 0, 0, 0])
    free = state()
    late = Progress(3.0, 0.0)
    contact = Force.z < -10.0
    timeout = Elapsed > 2.0
    either = contact | timeout
    both = contact & timeout
    assert either.holds(hit, AT_START) and either.holds(free, late)
    assert not either.holds(free, AT_START)
    assert both.holds(hit, late) and not both.holds(hit, AT_START)
    assert (~contact).holds(free, AT_START) and not (~contact).holds(hit, AT_START)
    # & binds tighter than |, as in Python
    expr = contact | timeout & Errors
    assert expr.holds(hit, AT_START) and not expr.holds(free, late)


def test_conditions_print_as_written() -> None:
    assert repr(Force.z < -10.0) == "Force.z < -10.0"
    assert repr((Force.z < -10) | (Elapsed > 5)) == "(Force.z < -10.0) | (Elapsed > 5.0)"
    assert repr(~(Torque[2] >= 1.5) & Errors) == "~(Torque[2] >= 1.5) & Errors"
    assert repr(Field("tau_J").norm <= 3) == 'Field("tau_J").norm <= 3.0'


def is_fast(state: Any) -> bool:
    return bool(np.abs(state.dq).max() > 1.0)


def test_conditions_travel_by_pickle_and_stay_equal() -> None:
    cond = ((Force.z < -10.0) | (Elapsed > 5.0)) & ~Errors & when(is_fast)
    back = pickle.loads(pickle.dumps(cond))
    assert back == cond and repr(back) == repr(cond)
    fast = state(dq=[0, 0, 2.0, 0, 0, 0, 0], O_F_ext_hat_K=[0, 0, -11.0, 0, 0, 0])
    assert back.holds(fast, AT_START)
    assert pickle.loads(pickle.dumps(Errors)) is Errors


def test_a_function_condition_calls_the_function_and_passes_its_errors() -> None:
    assert when(is_fast).holds(state(dq=[2.0, 0, 0, 0, 0, 0, 0]), AT_START)

    def broken(s: Any) -> bool:
        raise RuntimeError("mine")

    with pytest.raises(RuntimeError, match="mine"):
        when(broken).holds(state(), AT_START)


def test_what_cannot_be_a_condition_is_refused_by_name() -> None:
    with pytest.raises(ValueError, match=r"field: expected one of \[.*'tau_J'.*\], got 'tau'"):
        Field("tau")
    with pytest.raises(ValueError, match=r"Torque\[\]: expected an index 0-6, got 7"):
        Torque[7]
    with pytest.raises(ValueError, match=r"Torque\[\]: expected an index 0-6, got 'a'"):
        Torque["a"]
    with pytest.raises(ValueError, match=r"Force\.z <: expected a finite number, got nan"):
        _ = Force.z < float("nan")
    with pytest.raises(ValueError, match="Elapsed >: expected a finite number, got '5'"):
        _ = Elapsed > "5"
    with pytest.raises(ValueError, match="when: expected a function of the state, got 3"):
        when(3)  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"\|: expected a condition .*got float"):
        _ = (Force.z < 1.0) | 3.0  # type: ignore[operator]
    with pytest.raises(TypeError, match=r"combine conditions with &, \| and ~"):
        _ = (Force.z < 1.0) and (Elapsed > 1.0)
    assert isinstance(Force.z < 1.0, Condition)


def test_which_names_the_alternative_that_held() -> None:
    contact, timeout = Force.z < -10.0, Elapsed > 2.0
    cond = contact | timeout
    assert cond.which(state(O_F_ext_hat_K=[0, 0, -12.0, 0, 0, 0]), AT_START) == contact
    assert cond.which(state(), Progress(3.0, 0.0)) == timeout
    assert cond.which(state(), AT_START) is None
    both = contact & timeout
    held = state(O_F_ext_hat_K=[0, 0, -12.0, 0, 0, 0])
    assert both.which(held, Progress(3.0, 0.0)) == both  # all of it held
