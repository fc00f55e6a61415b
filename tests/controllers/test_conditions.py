"""Conditions for guarded moves: what each reads, how they combine, how they print and
travel, and the errors for what cannot be a condition."""

from __future__ import annotations

import pickle
from fractions import Fraction
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from panda_py import fci
from panda_py.conditions import (
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
    Quantity,
    Torque,
    when,
)
from panda_py.libfranka.state import RobotState, TickState


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
    for v in base.values():
        if isinstance(v, np.ndarray):
            v.flags.writeable = False  # as the control loop's states have them
    return SimpleNamespace(**base)


AT_START = Progress(elapsed=0.0, distance=0.1)
HIT = state(O_F_ext_hat_K=[0, 0, -12.0, 0, 0, 0])
FREE = state()
LATE = Progress(3.0, 0.0)


def test_each_quantity_reads_its_field_with_libfrankas_sign() -> None:
    pressing = state(O_F_ext_hat_K=[1.0, -2.0, -12.0, 0.0, 0.3, 0.4])
    assert (Force.z < -10.0).holds(pressing, AT_START)  # the robot pushes down
    assert not (Force.z > 0.0).holds(pressing, AT_START)
    assert (Force.x >= 1.0).holds(pressing, AT_START) and (Force.y <= -2.0).holds(
        pressing, AT_START
    )
    assert (Force.norm > 12.2).holds(pressing, AT_START)  # sqrt(149) = 12.21
    assert not (Force.norm > 12.3).holds(pressing, AT_START)
    assert (Moment.norm >= 0.5).holds(pressing, AT_START)
    assert not (Moment.norm > 0.5).holds(pressing, AT_START)
    assert (Moment.y <= 0.3).holds(pressing, AT_START) and not (Moment.x < 0.0).holds(
        pressing, AT_START
    )
    ee = state(K_F_ext_hat_K=[0, 0, 12.0, 0, 0, -1.0])
    assert (ForceEE.z > 5.0).holds(ee, AT_START) and not (Force.z > 5.0).holds(ee, AT_START)
    assert (MomentEE.z < -0.5).holds(ee, AT_START)
    joint = state(tau_ext_hat_filtered=[0, 0, 0, 3.0, 0, 0, -4.0])
    assert (Torque[3] > 2.5).holds(joint, AT_START)
    assert (Torque[6] < -3.5).holds(joint, AT_START)  # 0-based, like NumPy
    assert not (Torque[0] > 0.0).holds(joint, AT_START)
    assert (Torque.norm > 4.9).holds(joint, AT_START) and not (Torque.norm > 5.1).holds(
        joint, AT_START
    )
    moving = state(dq=[0, 0.2, 0, 0, 0, 0, 0])
    assert (Field("dq").norm > 0.1).holds(moving, AT_START)
    assert (Field("dq", 1) >= 0.2).holds(moving, AT_START)
    assert not (Field("dq")[0] > 0.0).holds(moving, AT_START)
    held = SimpleNamespace(m_ee=0.73)  # a one-value field compares as it is
    assert (Field("m_ee") > 0.7).holds(held, AT_START)
    later = Progress(elapsed=2.5, distance=0.004)
    assert (Elapsed > 2.0).holds(FREE, later) and not (Elapsed > 2.0).holds(FREE, AT_START)
    assert (Distance < 0.005).holds(FREE, later) and not (Distance < 0.005).holds(FREE, AT_START)
    assert Errors.holds(state(current_errors=("joint_reflex",)), AT_START)
    assert not Errors.holds(FREE, AT_START)


def real_state(version: int, cls: type = TickState, **fields: Any) -> RobotState:
    d = fci.dialect(version)
    record = np.zeros((), d.state_dtype)
    for name, value in fields.items():
        record[name] = value
    return cls(d, d.encode_state(record))


@pytest.mark.parametrize("version", [3, 10])
@pytest.mark.parametrize("cls", [RobotState, TickState])
def test_on_the_robots_state_conditions_read_what_its_attributes_say(
    version: int, cls: type
) -> None:
    wrench = [1.0, -2.0, -12.0, 0.0, 0.25, 0.5]
    tau = [0, 0, 0, 3.0, 0, 0, -4.0]
    s = real_state(version, cls, O_F_ext_hat_K=wrench, tau_ext_hat_filtered=tau)
    assert Force.z.value(s, AT_START) == s.O_F_ext_hat_K[2] == -12.0
    assert Moment.norm.value(s, AT_START) == pytest.approx(np.linalg.norm(wrench[3:]))
    assert Torque.norm.value(s, AT_START) == pytest.approx(5.0)
    assert Field("O_T_EE")[15].value(s, AT_START) == s.O_T_EE[15]
    loaded = real_state(version, cls, m_load=0.5)
    assert (Field("m_load") > 0.4).holds(loaded, AT_START)  # a float on the state
    assert not (Field("m_load") > 0.6).holds(loaded, AT_START)
    # the error flags, read from the datagram's bytes, say what current_errors says
    assert not Errors.holds(s, AT_START) and not s.current_errors
    n = fci.dialect(version).state_dtype["errors"].shape[0]
    for flag in (0, 5, n - 1):
        errors = np.zeros(n, np.uint8)
        errors[flag] = 1
        failed = real_state(version, cls, errors=errors)
        assert failed.current_errors and Errors.holds(failed, AT_START)


def test_conditions_combine_with_and_or_not() -> None:
    contact = Force.z < -10.0
    timeout = Elapsed > 2.0
    either = contact | timeout
    both = contact & timeout
    assert either.holds(HIT, AT_START) and either.holds(FREE, LATE)
    assert not either.holds(FREE, AT_START)
    assert both.holds(HIT, LATE) and not both.holds(HIT, AT_START)
    assert not both.holds(FREE, LATE)
    assert (~contact).holds(FREE, AT_START) and not (~contact).holds(HIT, AT_START)
    assert ~~contact == contact
    # & binds tighter than |, as in Python
    expr = contact | timeout & Errors
    assert expr == contact | (timeout & Errors) != (contact | timeout) & Errors
    assert expr.holds(HIT, AT_START) and not expr.holds(FREE, LATE)
    # a | b | c is one alternative of three, however written
    assert (contact | timeout) | Errors == contact | (timeout | Errors)
    assert repr(contact | timeout | Errors) == "(Force.z < -10.0) | (Elapsed > 2.0) | Errors"


def test_evaluation_stops_at_the_first_part_that_decides() -> None:
    calls: list[str] = []

    def seen(name: str, result: bool) -> Condition:
        def f(s: Any) -> bool:
            calls.append(name)
            return result

        return when(f)

    assert (seen("a", True) | seen("b", True)).holds(FREE, AT_START) and calls == ["a"]
    calls.clear()
    assert not (seen("a", False) & seen("b", True)).holds(FREE, AT_START) and calls == ["a"]


def test_conditions_print_as_written() -> None:
    assert repr(Force.z < -10.0) == "Force.z < -10.0"
    assert (Force.z < -10.0).describe() == "Force.z < -10.0"
    assert repr((Force.z < -10) | (Elapsed > 5)) == "(Force.z < -10.0) | (Elapsed > 5.0)"
    assert repr(~(Torque[2] >= 1.5) & Errors) == "~(Torque[2] >= 1.5) & Errors"
    assert repr(((ForceEE.norm > 1) & (Distance < 0.01)) | Errors) == (
        "((ForceEE.norm > 1.0) & (Distance < 0.01)) | Errors"
    )
    assert repr(Field("tau_J").norm <= 3) == 'Field("tau_J").norm <= 3.0'
    assert repr(Field("tau_J", 3) > 1) == 'Field("tau_J", 3) > 1.0'
    assert repr(Field("m_load") > 1) == 'Field("m_load") > 1.0'
    assert repr(when(is_fast)) == "when(is_fast)"
    assert repr(Force) == "Force" and repr(Field("q", 2)) == 'Field("q", 2)'


def is_fast(state: Any) -> bool:
    return bool(np.abs(state.dq).max() > 1.0)


def test_conditions_travel_by_pickle_and_stay_equal() -> None:
    cond = ((Force.z < -10.0) | (Elapsed > 5.0)) & ~Errors & when(is_fast)
    cond = cond | (Field("dq", 2) > 3.0) | (Torque.norm >= 2.0)
    back = pickle.loads(pickle.dumps(cond))
    assert back == cond and repr(back) == repr(cond)
    fast = state(dq=[0, 0, 2.0, 0, 0, 0, 0], O_F_ext_hat_K=[0, 0, -11.0, 0, 0, 0])
    assert back.holds(fast, AT_START) and not back.holds(FREE, AT_START)
    assert pickle.loads(pickle.dumps(Errors)) is Errors
    assert hash(back) == hash(cond)  # immutable: usable as keys


def test_a_function_condition_calls_the_function_and_passes_its_errors() -> None:
    assert when(is_fast).holds(state(dq=[2.0, 0, 0, 0, 0, 0, 0]), AT_START)
    assert not Condition.of(is_fast).holds(FREE, AT_START)
    assert Condition.of(is_fast) == when(is_fast)

    def broken(s: Any) -> bool:
        raise RuntimeError("mine")

    with pytest.raises(RuntimeError, match="mine"):
        when(broken).holds(FREE, AT_START)


@pytest.mark.parametrize("threshold", [3, 3.5, np.float32(3.5), np.int64(-2), Fraction(1, 3)])
def test_any_finite_real_is_a_threshold(threshold: Any) -> None:
    cond = Force.z > threshold
    assert cond.threshold == float(threshold) and type(cond.threshold) is float


@pytest.mark.parametrize(
    "threshold, shown",
    [(float("nan"), "nan"), (float("-inf"), "-inf"), ("5", "'5'"), (None, "None"),
     (True, "True"), (1j, "1j"), (np.array([1.0]), r"array\(\[1.\]\)")],
)  # fmt: skip
def test_a_threshold_that_is_no_finite_number_is_refused(threshold: Any, shown: str) -> None:
    with pytest.raises(ValueError, match=rf"^Elapsed >: expected a finite number, got {shown}$"):
        _ = Elapsed > threshold
    with pytest.raises(ValueError, match=rf"^Force\.z <=: expected a finite number, got {shown}$"):
        _ = Force.z <= threshold


def test_what_cannot_be_a_condition_is_refused_by_name() -> None:
    with pytest.raises(ValueError, match=r"Field\(name\): .* one of \[.*'tau_J'.*\], got 'tau'"):
        Field("tau")
    with pytest.raises(ValueError, match=r"Field\(name\): .*, got 3"):
        Field(3)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"Torque\[\]: expected an index 0-6, got 7"):
        Torque[7]
    with pytest.raises(ValueError, match=r"Torque\[\]: expected an index 0-6, got -1"):
        Torque[-1]
    with pytest.raises(ValueError, match=r"Torque\[\]: expected an index 0-6, got 'a'"):
        Torque["a"]
    with pytest.raises(ValueError, match=r'Field\("O_T_EE"\)\[\]: expected an index 0-15, got 16'):
        Field("O_T_EE", 16)
    with pytest.raises(ValueError, match=r'Field\("q", 3\)\[\]: is one value already'):
        Field("q", 3)[0]
    with pytest.raises(ValueError, match=r'Field\("q", 3\)\.norm: is one value already'):
        _ = Field("q", 3).norm
    with pytest.raises(ValueError, match=r'Field\("m_ee"\)\[\]: is one value already'):
        Field("m_ee")[0]
    with pytest.raises(ValueError, match=r'Field\("m_ee"\)\[\]: is one value already'):
        Field("m_ee", 0)
    # a field of many values is no number
    with pytest.raises(ValueError, match=r"Force <: expected one value, Force has 3: compare "
                                         r"Force\.x, \.y, \.z, or Force\.norm"):  # fmt: skip
        _ = Force < 3.0
    with pytest.raises(ValueError, match=r'Field\("dq"\) >: .* has 7: compare Field\("dq"\)\[i\] '
                                         r'with i 0-6, or Field\("dq"\)\.norm'):  # fmt: skip
        _ = Field("dq") > 1.0
    with pytest.raises(ValueError, match="when: expected a function of the state, got 3"):
        when(3)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="when: expected a function of the state, got 'x'"):
        Condition.of("x")  # type: ignore[arg-type]
    with pytest.raises(TypeError, match=r"\|: expected a condition .*got float"):
        _ = (Force.z < 1.0) | 3.0  # type: ignore[operator]
    with pytest.raises(TypeError, match=r"&: expected a condition .*got int"):
        _ = 3 & (Force.z < 1.0)  # type: ignore[operator]
    with pytest.raises(TypeError, match=r"combine conditions with &, \| and ~"):
        _ = (Force.z < 1.0) and (Elapsed > 1.0)
    with pytest.raises(TypeError, match=r"write a < x < b as \(a < x\) & \(x < b\)"):
        _ = -20.0 < Force.z < -10.0
    assert isinstance(Force.z < 1.0, Condition)


def test_a_quantity_used_as_a_condition_says_to_compare_and_parenthesize() -> None:
    parenthesize = r"Elapsed is a quantity, not a condition: .*\(Force\.z < -10\.0\) \| "
    with pytest.raises(TypeError, match=parenthesize):
        _ = Force.z < -10.0 | Elapsed > 5.0  # type: ignore[operator]
    with pytest.raises(TypeError, match=parenthesize):
        _ = (Force.z < -10.0) | Elapsed  # type: ignore[operator]
    with pytest.raises(TypeError, match=r"Torque\[1\] is a quantity"):
        _ = ~Torque[1]


def test_quantities_are_checked_however_built() -> None:
    assert Quantity('Field("dq")[2]', "dq", 2) == Field("dq")[2]
    with pytest.raises(ValueError, match=r"source: expected one of \[.*'dq'.*\] or \['elapsed', "):
        Quantity("x", "speed")
    with pytest.raises(ValueError, match=r"index: expected 0-6, got 7"):
        Quantity("x", "dq", 7)
    with pytest.raises(ValueError, match=r"start, stop: expected 0 <= start < stop <= 6"):
        Quantity("x", "O_F_ext_hat_K", None, 3, 9)
    with pytest.raises(ValueError, match=r"index, start, stop: m_ee is one value, expected none"):
        Quantity("x", "m_ee", 0)
    with pytest.raises(ValueError, match=r"index, start, stop: elapsed is one value"):
        Quantity("x", "elapsed", None, 0, 1)


def test_which_names_the_alternative_that_held() -> None:
    contact, timeout = Force.z < -10.0, Elapsed > 2.0
    cond = contact | timeout
    assert cond.which(HIT, AT_START) == contact
    assert cond.which(FREE, LATE) == timeout
    assert cond.which(HIT, LATE) == contact  # the first that holds
    assert cond.which(FREE, AT_START) is None
    both = contact & timeout
    assert both.which(HIT, LATE) == both  # all of it held
    assert both.which(HIT, AT_START) is None


def test_the_public_module_has_every_name_of_the_controllers_one() -> None:
    import panda_py.conditions as public
    import panda_py.controllers.conditions as impl

    assert sorted(public.__all__) == sorted(impl.__all__)
    assert all(getattr(public, n) is getattr(impl, n) for n in impl.__all__)
