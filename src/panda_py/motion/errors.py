"""Exceptions of trajectory planning. Invalid arguments raise :class:`ValueError`."""

from __future__ import annotations


class TrajectoryError(RuntimeError):
    """Root of the planning errors (panda-py raises ``RuntimeError`` here, so does this)."""


class PlanningTimeoutError(TrajectoryError, TimeoutError):
    """Planning did not finish within the ``timeout`` given to the trajectory [s]."""
