"""A blocking move interrupted in the user's process (Ctrl-C's KeyboardInterrupt, or any
exception raised while it waits) stops the arm gently before the exception goes on: a
script that catches Ctrl-C to save its log has no arm moving behind its back."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import textwrap
from pathlib import Path

import pytest

pytestmark = pytest.mark.timeout(240)

SRC = Path(__file__).resolve().parents[2] / "src"

# a user's script: a long blocking move on a lockstep simulator, Ctrl-C'd from a timer
# half a second (of the robot's clock) in, caught; then how the arm is a moment later
SCRIPT = textwrap.dedent(
    """
    import json, os, signal, threading, time
    import numpy as np
    import panda_py
    from panda_py.sim import Simulator, free_loopback_host

    sim = Simulator(free_loopback_host(), lockstep=True).start()
    try:
        with panda_py.Panda(sim.host) as panda:
            panda.move_to_start()
            t0 = panda.get_state().time.to_sec()
            goal = np.array(panda.q) + [1.2, -0.4, 0.8, 0.6, 0.0, 0.5, 1.0]

            def interrupt():
                while panda.get_state().time.to_sec() < t0 + 0.5:
                    time.sleep(0.001)
                os.kill(os.getpid(), signal.SIGINT)

            threading.Thread(target=interrupt, daemon=True).start()
            caught = False
            try:
                panda.move_to_joint_position(goal, speed_factor=0.2)
            except KeyboardInterrupt:
                caught = True
            after = panda.get_state()
            moving_then = panda.is_moving()
            speed_then = float(np.abs(after.dq).max())
            t1 = after.time.to_sec()
            while panda.get_state().time.to_sec() < t1 + 0.5:
                time.sleep(0.001)
            later = panda.get_state()
            print(json.dumps({
                "caught": caught,
                "interrupted_at": t1 - t0,
                "moving": moving_then,
                "speed": speed_then,
                "drift": float(np.abs(np.array(later.q) - np.array(after.q)).max()),
                "off_goal": float(np.abs(goal - np.array(later.q)).max()),
                "usable": bool(panda.move_to_start()),
            }))
    finally:
        sim.stop()
    """
)


def _ctrl_c_as_in_a_terminal() -> None:
    """Ctrl-C's default action in the child (a suite run in the background ignores SIGINT,
    and its children would inherit that: Python then raises no KeyboardInterrupt)."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_ctrl_c_in_a_blocking_move_stops_the_arm_before_the_script_goes_on() -> None:
    env = {**os.environ, "PYTHONPATH": str(SRC)}
    done = subprocess.run([sys.executable, "-c", SCRIPT], env=env, capture_output=True,
                          text=True, timeout=220, preexec_fn=_ctrl_c_as_in_a_terminal)  # fmt: skip
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["caught"], out
    # the move was interrupted on its way (it takes seconds), and by the time the script
    # goes on the arm has been brought to rest: nothing runs, nothing moves
    assert out["off_goal"] > 0.3, out
    assert not out["moving"], out
    assert out["speed"] < 0.01, out  # [rad/s]
    assert out["drift"] < 1e-3, out  # [rad] in the half second after
    assert out["usable"], out
