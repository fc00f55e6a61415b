"""What the simulated Desk's robot logic answers: an HTTP status and a body."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass
class Reply:
    status: int
    body: Any = None  # dict/list: JSON; str: text; None: empty


def error(status: int, code: str, message: str = "", **extra: Any) -> Reply:
    return Reply(status, {"code": code, "message": message or code, **extra})


__all__ = ["Reply", "error"]
