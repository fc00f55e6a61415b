"""The simulator's camera (``camera_size=``, ``Simulator.render``): images of the world as
it is when asked for, drawn offscreen in a process of its own.

Needs EGL (or OSMesa); where it is missing the tests skip, except in CI (``CI=true``),
where a gap is a failure."""

from __future__ import annotations

import os
import time

import numpy as np
import pytest

from panda_py.robots import START_POSE
from panda_py.sim import Simulator, SimulatorError, free_loopback_host

pytestmark = pytest.mark.timeout(120)

TURNED = np.array(START_POSE) + np.array([1.2, 0, 0, 0, 0, 0, 0])  # [rad] joint 1


def _missing(reason: str) -> None:
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"{reason} (CI must run the camera tests: see .ci/ensure-display)")
    pytest.skip(reason)


def _arm_pixels(image: np.ndarray) -> np.ndarray:
    """Where the arm's light grey is (the table is brown, the cube red, the sky black)."""
    rgb = image.astype(int)
    return (rgb.min(axis=2) > 150) & (rgb.max(axis=2) - rgb.min(axis=2) < 40)


def _grey(image: np.ndarray) -> np.ndarray:
    """The arm, lit or shaded."""
    rgb = image.astype(int)
    return (rgb.max(axis=2) > 50) & (rgb.max(axis=2) - rgb.min(axis=2) < 40)


def test_render_shows_the_arm_where_it_is() -> None:
    try:
        sim = Simulator(free_loopback_host(), lockstep=True, camera_size=(200, 150)).start()
    except SimulatorError as exc:
        _missing(f"no offscreen rendering here: {exc}")
    try:
        first = sim.render()
        assert first.shape == (150, 200, 3) and first.dtype == np.uint8
        assert _arm_pixels(first).sum() > 300, "the arm is not drawn"
        # nothing moved: the same image, but for the few pixels of a resting scene still
        # settling (the fingers, the cube in the table's soft contact) between the two
        again = np.abs(sim.render().astype(int) - first.astype(int)).max(axis=2)
        assert (again > 30).sum() < 0.005 * again.size, (again > 30).sum()
        t = sim.state()["time"]
        sim.set_joint_positions(TURNED)
        deadline = time.monotonic() + 30
        while sim.state()["time"] <= t + 0.002:  # a tick has copied the new pose
            assert time.monotonic() < deadline
            time.sleep(0.001)
        turned = sim.render()
    finally:
        sim.stop()
    moved = np.abs(first.astype(int) - turned.astype(int)).max(axis=2) > 60
    assert moved.sum() > 200  # the arm turned away from where it was drawn
    assert (moved & (_grey(first) | _grey(turned))).sum() > 0.8 * moved.sum()
    with pytest.raises(SimulatorError, match="not running"):
        sim.render()


def test_camera_size_and_render_refuse_bad_use() -> None:
    for bad in [(0, 100), (100,), (641, 100), (100, 481), (10.5, 100), "big"]:
        with pytest.raises(ValueError, match=r"camera_size: expected \(width, height\)"):
            Simulator(camera_size=bad)  # type: ignore[arg-type]
    with pytest.raises(SimulatorError, match="has no camera"):
        Simulator().render()
