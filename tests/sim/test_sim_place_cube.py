"""``Simulator.place_cube``: the scene's cube goes where it is asked, upright and at rest,
and stays there; bad positions are refused with the argument named; a simulator without
the scene says it has no cube."""

from __future__ import annotations

import time

import numpy as np
import pytest

from panda_py.sim import Simulator, SimulatorError, free_loopback_host

pytestmark = pytest.mark.timeout(120)


def test_the_cube_rests_where_it_was_placed() -> None:
    with Simulator(free_loopback_host(), lockstep=True) as sim:
        assert np.allclose(sim.cube_position(), [0.5, 0.0, 0.02], atol=1e-3)
        sim.place_cube([0.45, -0.1, 0.02])
        # (the idle simulator runs on meanwhile: the cube may settle into the table's soft
        # contact by a fraction of a millimetre)
        assert np.allclose(sim.cube_position(), [0.45, -0.1, 0.02], atol=5e-4)
        # dropped from 5 cm it falls onto the table and rests there (the idle simulator
        # runs on the wall clock: wait for its time, not for a fixed while)
        sim.place_cube([0.55, 0.1, 0.07])
        start = sim.state()["time"]
        while sim.state()["time"] < start + 1.0:
            time.sleep(0.005)
        assert np.allclose(sim.cube_position(), [0.55, 0.1, 0.02], atol=2e-3)
        with pytest.raises(ValueError, match="position: expected 3 finite"):
            sim.place_cube([0.5, float("nan"), 0.02])
        with pytest.raises(ValueError, match="position: expected 3 finite"):
            sim.place_cube([0.5, 0.0])
        assert np.allclose(sim.cube_position(), [0.55, 0.1, 0.02], atol=2e-3)


def test_without_the_scene_there_is_no_cube() -> None:
    with Simulator(free_loopback_host(), lockstep=True, scene=False) as sim:
        with pytest.raises(SimulatorError, match="no cube"):
            sim.cube_position()
        with pytest.raises(ValueError, match="free body"):
            sim.place_cube([0.5, 0.0, 0.02])
