"""A robot that disappears mid-motion: NetworkException within a second."""

from __future__ import annotations

import time

import numpy as np
import pytest

from panda_py import libfranka as lf
from panda_py.robots import robot_for_protocol
from panda_py.sim import Simulator, free_loopback_host


@pytest.mark.timeout(30)
@pytest.mark.parametrize("version", [5, 10])
def test_simulator_killed_mid_motion_raises_network_exception_within_1_s(version):
    robot_kind = robot_for_protocol(version).name
    with Simulator(free_loopback_host(), robot=robot_kind, lockstep=True) as sim:
        robot = lf.Robot(sim.host, version=version)
        killed_at = [0.0]
        n = [0]

        def torque(state, dt):
            n[0] += 1
            if n[0] == 100:
                killed_at[0] = time.monotonic()
                sim.kill()
            return lf.Torques(np.zeros(7))

        with pytest.raises(lf.NetworkException) as info:
            robot.control(torque)
        elapsed = time.monotonic() - killed_at[0]
        assert elapsed < 1.0, f"took {elapsed:.3f} s: {info.value}"
        assert "libfranka:" in str(info.value)
        with pytest.raises(lf.NetworkException):
            robot.read_once()
        robot.close()
