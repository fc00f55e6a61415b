"""The console script panda-sim serves until interrupted (the demo: tests/examples)."""

from __future__ import annotations

import signal
import subprocess
import sys

import pytest
from cli_support import connect_when_serving

from panda_py import fci
from panda_py.sim import free_loopback_host
from panda_py.sim.probe import RawClient


@pytest.mark.timeout(60)
def test_panda_sim_cli_serves_until_interrupted():
    host = free_loopback_host()
    cmd = [sys.executable, "-m", "panda_py.sim.cli", "--host", host, "--lockstep", "--version", "5"]
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    try:
        client = connect_when_serving(proc, host, 5)
        assert client.status == fci.ConnectStatus.SUCCESS
        assert client.state()["robot_mode"] == fci.RobotMode.IDLE
        client.close()
        refused = RawClient(host, 10)  # pinned to version 5
        assert refused.status == fci.ConnectStatus.INCOMPATIBLE_LIBRARY_VERSION
        refused.close()
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
    assert "protocol v5" in err


def test_panda_sim_cli_rejects_bad_options():
    proc = subprocess.run(
        [sys.executable, "-m", "panda_py.sim.cli", "--robot", "ur5"],
        capture_output=True, text=True, timeout=30,
    )  # fmt: skip
    assert proc.returncode == 2 and "invalid choice: 'ur5'" in proc.stderr
