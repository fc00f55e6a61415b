"""Fixtures of the learning tests: one lockstep simulator with a camera, a Panda and a
Franka Hand connected to it, shared by a module (starting them takes seconds); each test
starts from the start pose with the hand open."""

from __future__ import annotations

import os
from collections.abc import Iterator
from dataclasses import dataclass

import pytest

import panda_py
from panda_py.libfranka import Gripper
from panda_py.sim import Simulator, SimulatorError, free_loopback_host

CAMERA_SIZE = (96, 72)  # [px] small: software OpenGL draws it in a few ms


@dataclass
class Rig:
    sim: Simulator
    panda: panda_py.Panda
    gripper: Gripper


def missing(reason: str) -> None:
    """Skip, except in CI (``CI=true``), where EGL is installed and a gap is a failure."""
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"{reason} (CI must run the camera tests: see .ci/ensure-display)")
    pytest.skip(reason)


@pytest.fixture(scope="module")
def shared_rig() -> Iterator[Rig]:
    try:
        sim = Simulator(free_loopback_host(), lockstep=True, camera_size=CAMERA_SIZE).start()
    except SimulatorError as exc:
        missing(f"no offscreen rendering here: {exc}")
    try:
        with panda_py.Panda(sim.host) as panda, Gripper(sim.host) as gripper:
            yield Rig(sim, panda, gripper)
    finally:
        sim.stop()


@pytest.fixture
def rig(shared_rig: Rig) -> Rig:
    shared_rig.panda.move_to_start()
    shared_rig.gripper.move(shared_rig.gripper.read_once().max_width, 0.1)
    return shared_rig
