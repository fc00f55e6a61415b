"""Checks of the parts of a Desk's JSON answers that indexing does not check: a text
where an object was due, a token that cannot be sent back in a header, a number that is
none. Each raises ``TypeError`` or ``ValueError`` naming the field, what it expected and
what came; :func:`panda_py.desk.answers.parse` turns that into the Desk's error.
"""

from __future__ import annotations

import math
import re
from typing import Any

from panda_py.checks import MAX_TIMEOUT

_HEADER_TOKEN = re.compile(r"[!-~]+")  # visible ASCII: sent back in a header as it came


def obj(value: Any, name: str = "the answer") -> dict[str, Any]:
    if not isinstance(value, dict):
        raise TypeError(f"{name}: expected an object, got {type(value).__name__}")
    return value


def array(value: Any, name: str = "the answer") -> list[Any]:
    if not isinstance(value, list):
        raise TypeError(f"{name}: expected a list, got {type(value).__name__}")
    return value


def text(value: Any, name: str) -> str:
    if not isinstance(value, str):
        raise TypeError(f"{name}: expected a text, got {type(value).__name__}")
    return value


def ident(value: Any, name: str) -> str:
    """An id as text: the Desk's are numbers or texts."""
    if isinstance(value, bool) or not isinstance(value, int | str):
        raise TypeError(f"{name}: expected a number or a text, got {type(value).__name__}")
    return str(value)


def header_token(value: Any, name: str) -> str:
    """A token the client sends back in a header: visible ASCII (the value is not shown)."""
    if not isinstance(value, str) or not _HEADER_TOKEN.fullmatch(value):
        got = f"a text of {len(value)} characters" if isinstance(value, str) else "no text"
        raise ValueError(f"{name}: expected visible ASCII (sent back in a header), got {got}")
    return value


def number(value: Any, name: str) -> float:
    """A finite number."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TypeError(f"{name}: expected a number, got {type(value).__name__}")
    if not math.isfinite(value):
        raise ValueError(f"{name}: expected a finite number, got {value!r}")
    return float(value)


def seconds(value: Any, name: str) -> float:
    """A duration [s]: a finite number from 0 to ``checks.MAX_TIMEOUT``."""
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise TypeError(f"{name}: expected a number [s], got {type(value).__name__}")
    if not (math.isfinite(value) and 0 <= value <= MAX_TIMEOUT):
        raise ValueError(f"{name}: expected 0 to {MAX_TIMEOUT:g} s, got {value!r}")
    return float(value)


__all__ = ["array", "header_token", "ident", "number", "obj", "seconds", "text"]
