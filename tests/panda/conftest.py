"""Fixtures of the Panda tests: a lockstep simulator and a Panda connected to it, fresh per
test (``sim``, ``panda``) or one per module reset before each test (``reset_panda``)."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

import panda_py
from panda_py import constants
from panda_py.rt.process import ControlProcessError
from panda_py.sim import Simulator
from panda_py.sim.api import free_loopback_host

# what a test may change through the robot's setters and what the reset puts back; a
# fresh robot reads these from its state, so the reset checks they are as they were
SETTINGS = ("m_load", "F_x_Cload", "I_load", "NE_T_EE", "EE_T_K")
AT_START = 1e-3  # [rad] every joint this close to the start pose after the reset


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


@pytest.fixture
def paced_panda() -> Iterator[panda_py.Panda]:
    """A Panda on a lockstep simulator held to the wall clock (``lockstep_max_speed=1``:
    it still waits for every command). For a user's loop that runs on the wall clock (or
    reads the robot's clock between sleeps): a lockstep robot let loose runs many times the
    wall clock, and each stall of the test's process becomes many of its milliseconds."""
    with (
        Simulator(free_loopback_host(), lockstep=True, lockstep_max_speed=1.0) as sim,
        panda_py.Panda(sim.host) as p,
    ):
        yield p


@pytest.fixture(scope="module")
def shared_sim() -> Iterator[Simulator]:
    """The lockstep simulator of the module's Panda (``shared_panda``)."""
    with Simulator(free_loopback_host(), lockstep=True) as s:
        yield s


@pytest.fixture(scope="module")
def shared_panda(shared_sim: Simulator) -> Iterator[panda_py.Panda]:
    """One lockstep simulator and Panda for a whole module, for tests that leave no trace
    on them (refused input): starting both takes about 2.5 s a test."""
    with panda_py.Panda(shared_sim.host) as p:
        yield p


@pytest.fixture(scope="module")
def _fresh_settings(shared_panda: panda_py.Panda) -> dict[str, np.ndarray]:
    state = shared_panda.get_robot().read_once()
    return {name: np.array(getattr(state, name), dtype=float) for name in SETTINGS}


@pytest.fixture
def reset_panda(
    request: pytest.FixtureRequest,
    shared_panda: panda_py.Panda,
    _fresh_settings: dict[str, np.ndarray],
) -> panda_py.Panda:
    """The module's Panda as a fresh one is: nothing running, no pending error, no reflex,
    panda-py's default behaviour, the load and frames a fresh robot has, no logging, at
    rest at the start pose. For tests that need no fresh process or simulator (each saves
    the ~2 s their start takes); the reset is checked, so a trace it cannot remove fails
    the test that finds it rather than bending its outcome."""
    if request.node.get_closest_marker("panda_sim") is not None:
        pytest.fail(
            "panda_sim(...) options reach the fresh simulator (the `sim` and `panda` fixtures "
            "of this conftest); this test runs on the module's shared one (reset_panda)",
            pytrace=False,
        )
    p = shared_panda
    if p.is_moving():
        p.stop_controller()
    for _ in range(100):  # the errors the last test left unraised (a dead process: raised)
        try:
            p.raise_error()
            break
        except ControlProcessError:
            raise
        except Exception:  # a reflex, or the exception a user's controller raised
            continue
    p.set_default_behavior()  # recovers, and resets collision behaviour and impedances
    robot = p.get_robot()
    fresh = _fresh_settings
    robot.set_load(float(fresh["m_load"]), fresh["F_x_Cload"], fresh["I_load"])
    robot.set_ee(fresh["NE_T_EE"])
    robot.set_k(fresh["EE_T_K"])
    p.disable_logging()
    assert p.move_to_start(), "the reset could not bring the arm to the start pose"
    state = p.get_robot().read_once()
    assert not state.current_errors and not p.is_moving()
    for name in SETTINGS:
        np.testing.assert_array_equal(getattr(state, name), fresh[name], err_msg=name)
    assert np.abs(np.asarray(state.q) - constants.JOINT_POSITION_START).max() < AT_START
    return p
