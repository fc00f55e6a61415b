"""panda-py's overloaded signatures bound as Python binds a call: one binder for every
function whose first arguments take different forms (``move_to_joint_position``'s
positions or waypoints, ``move_to_pose``'s four, ``ik``'s two).

A function's forms are :class:`Form` s: the parameters in order, positional or keyword,
of which the leading ``target`` ones are required, with a test on the first target value
that says whether a call given it positionally is of that form. :func:`bind` picks the
form (a target named by keyword picks its form; else the first form whose test accepts
the positional arguments; else the first form) and binds the call to it with
:mod:`inspect`'s binder, so a wrong call gets the error Python gives (``TypeError``:
missing, unexpected or doubled arguments) in the function's name. Parameters not given
are absent from the result, not defaulted: the caller's defaults stay the caller's.
"""

from __future__ import annotations

import inspect
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

__all__ = ["Bound", "Form", "bind"]


class _Absent:
    def __repr__(self) -> str:
        return "<not given>"


_ABSENT = _Absent()


@dataclass(frozen=True)
class Form:
    """One overload: ``target`` (the required leading parameters), then ``options`` (in
    order, positional or keyword), then ``keywords`` (keyword only); ``fits(args)``:
    whether a call with these positional arguments has this form (shape tests of the
    first ones)."""

    target: tuple[str, ...]
    options: tuple[str, ...] = ()
    keywords: tuple[str, ...] = ()
    fits: Callable[[Sequence[Any]], bool] = field(default=lambda args: True, compare=False)
    signature: inspect.Signature = field(init=False, compare=False, repr=False)

    def __post_init__(self) -> None:
        P = inspect.Parameter
        params = [P(name, P.POSITIONAL_OR_KEYWORD) for name in self.target]
        params += [P(name, P.POSITIONAL_OR_KEYWORD, default=_ABSENT) for name in self.options]
        params += [P(name, P.KEYWORD_ONLY, default=_ABSENT) for name in self.keywords]
        object.__setattr__(self, "signature", inspect.Signature(params))


@dataclass(frozen=True)
class Bound:
    """A call bound to ``forms[index]``: its ``arguments`` by name (only those given)."""

    index: int
    arguments: dict[str, Any]


def bind(what: str, forms: Sequence[Form], args: Sequence[Any], kwargs: Mapping[str, Any]) -> Bound:
    """Bind ``what(*args, **kwargs)`` to one of ``forms`` (see the module's docstring);
    ``TypeError`` as Python's own for a call that fits none."""
    index = _pick(forms, args, kwargs)
    form = forms[index]
    if not kwargs and len(args) == len(form.target):  # the common call, bound at once
        return Bound(index, dict(zip(form.target, args, strict=True)))
    try:
        bound = form.signature.bind(*args, **kwargs)
    except TypeError as exc:
        names = ", ".join(" and ".join(f.target) for f in forms)
        raise TypeError(f"{what}() {exc} (its forms take {names} first)") from None
    given = {k: v for k, v in bound.arguments.items() if v is not _ABSENT}
    return Bound(index, given)


def _pick(forms: Sequence[Form], args: Sequence[Any], kwargs: Mapping[str, Any]) -> int:
    for i, form in enumerate(forms):  # a target by keyword names its form
        if form.target[0] in kwargs:
            return i
    if args:
        for i, form in enumerate(forms):
            if form.fits(args):
                return i
    return 0
