"""Fixtures of the Panda tests: a lockstep simulator and a Panda connected to it."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

import panda_py
from panda_py.sim import Simulator
from panda_py.sim.api import free_loopback_host


@pytest.fixture
def sim(request: pytest.FixtureRequest) -> Iterator[Simulator]:
    marker = request.node.get_closest_marker("panda_sim")
    options = dict(marker.kwargs) if marker else {}
    options.setdefault("lockstep", True)
    with Simulator(free_loopback_host(), **options) as s:
        yield s


@pytest.fixture
def panda(sim: Simulator) -> Iterator[panda_py.Panda]:
    p = panda_py.Panda(sim.host)
    try:
        yield p
    finally:
        p.close()
