"""The overload binder (panda_py.overloads) binds a call as Python would: the form a
keyword or the first argument's shape picks, only the arguments given, and Python's own
TypeError (in the function's name) for a call no form takes."""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import pytest

from panda_py.overloads import Form, bind


def _is_pair(args: Sequence[Any]) -> bool:
    return isinstance(args[0], tuple)


FORMS = (
    Form(("pair",), ("speed",), ("extra",), fits=_is_pair),
    Form(("x", "y"), ("speed",), ("extra",)),
)


def test_the_first_arguments_shape_picks_the_form() -> None:
    assert bind("f", FORMS, ((1, 2),), {}).index == 0
    assert bind("f", FORMS, (1, 2), {}).index == 1
    bound = bind("f", FORMS, ((1, 2), 0.5), {"extra": 3})
    assert bound.arguments == {"pair": (1, 2), "speed": 0.5, "extra": 3}


def test_a_target_by_keyword_picks_its_form_and_only_given_arguments_appear() -> None:
    bound = bind("f", FORMS, (), {"x": 1, "y": 2})
    assert (bound.index, bound.arguments) == (1, {"x": 1, "y": 2})
    assert bind("f", FORMS, (1,), {"y": 2, "speed": 0.1}).arguments == {
        "x": 1, "y": 2, "speed": 0.1,
    }  # fmt: skip


@pytest.mark.parametrize(
    ("args", "kwargs", "message"),
    [
        ((1,), {}, r"f\(\) missing a required argument: 'y'"),
        (((1, 2), 0.5, 3), {}, r"f\(\) too many positional arguments"),
        (((1, 2), 0.5), {"speed": 0.1}, r"f\(\) multiple values for argument 'speed'"),
        (((1, 2),), {"sped": 0.1}, r"f\(\) got an unexpected keyword argument 'sped'"),
        ((), {}, r"missing a required argument: 'pair' \(its forms take pair, x and y first\)"),
    ],
)
def test_a_call_no_form_takes_is_pythons_type_error(
    args: tuple[Any, ...], kwargs: dict[str, Any], message: str
) -> None:
    with pytest.raises(TypeError, match=message):
        bind("f", FORMS, args, kwargs)
