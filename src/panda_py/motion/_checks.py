"""Argument checks shared by the trajectory classes (each raises a ValueError naming the
argument, what it expects and what it got)."""

from __future__ import annotations

from panda_py.checks import number


def speed_factor(value: object) -> float:
    """A fraction of the robot's velocity and acceleration limits, in (0, 1]."""
    return number("speed_factor", value, low=0.0, low_open=True, high=1.0)


def max_deviation(value: object) -> float:
    """How far blends may cut corners [rad or m], finite and >= 0."""
    return number("max_deviation", value, "[rad or m]", low=0.0)


def timeout(value: object) -> float:
    """Planning time budget [s], > 0 (may be infinite)."""
    try:
        v = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError) as exc:
        raise ValueError(f"timeout: expected a number of seconds > 0, got {value!r}") from exc
    if not v > 0.0:
        raise ValueError(f"timeout: expected a number of seconds > 0, got {value!r}")
    return v
