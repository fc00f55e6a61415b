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


@pytest.fixture(scope="module")
def shared_panda() -> Iterator[panda_py.Panda]:
    """One lockstep simulator and Panda for a whole module, for tests that leave no trace
    on them (refused input): starting both takes about 2.5 s a test."""
    with (
        Simulator(free_loopback_host(), lockstep=True) as s,
        panda_py.Panda(s.host) as p,
    ):
        yield p
