"""The paper's first code block, as written, on ``panda-sim --locked``; then
``panda_py.Panda(hostname)`` connects and moves the arm."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import time
from pathlib import Path

import pytest

from panda_py import libfranka as lf
from panda_py.sim import free_loopback_host

pytestmark = pytest.mark.timeout(90)


def _wait_for_fci_listener(host: str, proc: subprocess.Popen[str]) -> None:
    deadline = time.monotonic() + 60
    while True:
        try:
            socket.create_connection((host, 1337), timeout=1).close()
            return
        except OSError:
            if time.monotonic() > deadline or proc.poll() is not None:
                raise
            time.sleep(0.1)


def test_paper_first_code_block_on_a_locked_sim(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    host = free_loopback_host()
    # Port 443 as on a robot needs root (CI runs as root); otherwise a high port.
    port = 443 if os.geteuid() == 0 else 20000 + os.getpid() % 20000
    cmd = [
        sys.executable, "-m", "panda_py.sim.cli", "--host", host, "--lockstep", "--locked",
        "--desk-port", str(port), "--desk-cert-dir", str(tmp_path / "cert"),
    ]  # fmt: skip
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True)
    monkeypatch.setenv("PANDA_PY_DESK_DIR", str(tmp_path / "store"))
    try:
        _wait_for_fci_listener(host, proc)
        import panda_py

        with pytest.raises(lf.NetworkException):  # the FCI is not active after power-up
            panda_py.Panda(host)
        hostname = host if port == 443 else f"{host}:{port}"
        username, password = "franka", "franka123"

        desk = panda_py.Desk(hostname, username, password)
        desk.unlock()
        desk.activate_fci()

        with panda_py.Panda(host) as panda:
            assert panda.get_state().robot_mode == lf.RobotMode.kIdle
            pose = panda.get_pose()
            pose[2, 3] -= 0.05
            assert panda.move_to_pose(pose)  # the brakes are open: the arm moves
    finally:
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=20)
    assert proc.returncode == 0, err
