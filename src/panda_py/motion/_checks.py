"""Argument checks shared by the trajectory classes (each raises a ValueError naming the
argument, what it expects and what it got)."""

from __future__ import annotations

import math


def _number(name: str, value: object) -> float:
    try:
        return float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ValueError(f"{name}: expected a number, got {value!r}") from exc


def speed_factor(value: object) -> float:
    """A fraction of the robot's velocity and acceleration limits, in (0, 1]."""
    v = _number("speed_factor", value)
    if not 0.0 < v <= 1.0:
        raise ValueError(f"speed_factor: expected a number in (0, 1], got {value!r}")
    return v


def max_deviation(value: object) -> float:
    """How far blends may cut corners [rad or m], finite and >= 0."""
    v = _number("max_deviation", value)
    if not (math.isfinite(v) and v >= 0.0):
        raise ValueError(f"max_deviation: expected a finite number >= 0, got {value!r}")
    return v


def timeout(value: object) -> float:
    """Planning time budget [s], > 0 (may be infinite)."""
    v = _number("timeout", value)
    if not v > 0.0:
        raise ValueError(f"timeout: expected a number of seconds > 0, got {value!r}")
    return v
