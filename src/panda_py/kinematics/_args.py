"""ik's arguments: panda-py's two overloads bound (:func:`panda_py.overloads.bind`, as
``Panda``'s moves' are) and sorted into arrays, and the error for the first pose a kernel
refused.

The values are not tested here: the ik kernels test each pose, q_init and q_7 while
solving (``_ik.ik_range``) and mark a bad one, and :func:`raise_invalid` then words the
error for the first of them, naming its batch index.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py import checks
from panda_py.kinematics import _ik, _input
from panda_py.overloads import Form, bind
from panda_py.robots.params import START_POSE

DEFAULT_Q7 = math.pi / 4
"""panda-py's default redundancy parameter ``q_7`` [rad] (``panda_py.ik``'s default): the last
joint's position, chosen before the analytical solution is found."""

FloatArray = NDArray[np.float64]


def _is_position(args: Sequence[Any]) -> bool:
    """``(position, orientation, ...)``: a 3-vector first, or (N, 3) positions before
    quaternions (N, 4)."""
    first = args[0] if isinstance(args[0], np.ndarray) else np.asarray(args[0])
    if first.shape == (3,):
        return True
    return first.ndim == 2 and first.shape[1] == 3 and np.shape(args[1:2])[-1:] == (4,)


IK_FORMS = (
    Form(("O_T_EE",), ("q_init", "q_7"), fits=lambda args: not _is_position(args)),
    Form(("position", "orientation"), ("q_init", "q_7"), fits=_is_position),
)


def parse_ik(
    args: tuple[Any, ...],
    O_T_EE: Any,
    position: Any,
    orientation: Any,
    q_init: Any,
    q_7: Any,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Sort ``(O_T_EE, q_init, q_7)`` and ``(position, orientation, q_init, q_7)``,
    positional or keyword (None: not given), into (T (4, 4) or (N, 4, 4), q_init (7,) or
    (N, 7), q_7 () or (N,)), checked for shape (a quaternion also for norm). A call that
    fits neither form is a ValueError, as a bad value is."""
    named = {"O_T_EE": O_T_EE, "position": position, "orientation": orientation,
             "q_init": q_init, "q_7": q_7}  # fmt: skip
    kwargs = {k: v for k, v in named.items() if v is not None}
    if O_T_EE is not None and (position is not None or orientation is not None):
        raise ValueError("O_T_EE: give either O_T_EE or position and orientation")
    try:
        bound = bind("ik", IK_FORMS, args, kwargs)
    except TypeError as exc:
        raise ValueError(str(exc)) from None
    given = bound.arguments
    if bound.index == 0:
        T = _input.transforms("O_T_EE", given["O_T_EE"], check=False)
    else:
        T = _input.position_orientation(given["position"], given["orientation"])
    n = T.shape[0] if T.ndim == 3 else None
    if given.get("q_init") is None:
        qi = np.array(START_POSE)
    else:
        qi = _input.joints("q_init", given["q_init"], check=False)
        if qi.ndim == 2 and (n is None or qi.shape[0] != n):
            raise ValueError(
                f"q_init: expected shape (7,) or ({n}, 7) to match the poses, got {qi.shape}"
            )
    q_7 = given.get("q_7")
    q7 = _input.scalar_or_batch("q_7", DEFAULT_Q7 if q_7 is None else q_7, n, "rad", check=False)
    return T, qi, q7


def search_radius(q7_search: object) -> float:
    """``q7_search`` [rad] checked: a number >= 0, ``math.inf`` for joint 7's whole range."""
    if isinstance(q7_search, float) and q7_search == math.inf:
        return math.inf
    unit = "[rad] (or math.inf: joint 7's whole range)"
    return checks.number("q7_search", q7_search, unit, low=0.0)


def raise_invalid(T: FloatArray, qi: FloatArray, q7: FloatArray, k: int) -> None:
    """The ValueError for pose k, which a kernel found not to be a finite rigid transform
    or to have a non-finite q_init or q_7 (the first of these, in that order)."""
    batch = T.ndim == 3
    where = f" (batch index {k})" if batch else ""
    for name, item, is_batch in (
        ("O_T_EE", T[k] if batch else T, batch),
        ("q_init", qi[k] if qi.ndim == 2 else qi, qi.ndim == 2),
        ("q_7", q7[k] if q7.ndim == 1 else q7, q7.ndim == 1),
    ):
        if not np.all(np.isfinite(item)):
            raise ValueError(
                f"{name}: expected finite values, got NaN or infinity"
                f"{where if is_batch else ''} in {item!r:.200}"
            )
    M = (T[k] if batch else T).ravel().tolist()
    raise ValueError(_input.rigid_message("O_T_EE", _ik.rigid_error(*M), k if batch else None))
