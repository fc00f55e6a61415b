"""pytest fixtures for code that talks to a robot: a lockstep simulator per test.

Enabled automatically (``pytest11`` entry point) when panda_py is installed::

    def test_my_controller(panda_sim):
        robot = MyClient(panda_sim.host)

Options per test with the ``panda_sim`` marker, e.g.
``@pytest.mark.panda_sim(robot="fr3", versions=(10,), lockstep=False)``.

pytest imports this plugin into every session of every project in the environment, so
it imports neither MuJoCo nor the simulator: they load when a test uses the fixture.
"""

from __future__ import annotations

from collections.abc import Iterator
from typing import TYPE_CHECKING

import pytest

if TYPE_CHECKING:
    from panda_py.sim.api import Simulator


def pytest_configure(config: pytest.Config) -> None:
    config.addinivalue_line(
        "markers", "panda_sim(**options): options of the panda_sim fixture's Simulator"
    )


@pytest.fixture
def panda_sim(request: pytest.FixtureRequest) -> Iterator[Simulator]:
    """A simulated robot on a free loopback address, lockstep unless the marker says
    otherwise; stopped after the test."""
    from panda_py.sim.api import Simulator, free_loopback_host

    marker = request.node.get_closest_marker("panda_sim")
    options = dict(marker.kwargs) if marker else {}
    options.setdefault("lockstep", True)
    host = options.pop("host", None) or free_loopback_host()
    with Simulator(host, **options) as sim:
        yield sim
