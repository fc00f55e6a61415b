"""Fixtures shared across the test tree."""

from __future__ import annotations

from collections.abc import Callable, Iterator
from typing import Any

import pytest

from panda_py.robots import robot_for_protocol
from panda_py.sim import Simulator, free_loopback_host


@pytest.fixture(scope="module")
def sim_for_version() -> Iterator[Callable[..., Simulator]]:
    """``sim_for_version(version, **options)``: a lockstep simulator of the robot whose
    systems speak protocol ``version`` (a FER for 3-5, an FR3 before 5.9 for 6-9, an FR3
    for 10), started on first use and shared by the module's tests."""
    started: dict[tuple[Any, ...], Simulator] = {}

    def get(version: int, **options: Any) -> Simulator:
        robot = robot_for_protocol(version).name
        key = (robot, *sorted(options.items()))
        if key not in started:
            options.setdefault("lockstep", True)
            started[key] = Simulator(free_loopback_host(), robot, **options).start()
        return started[key]

    try:
        yield get
    finally:
        for sim in started.values():
            sim.stop()
