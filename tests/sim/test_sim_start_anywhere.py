"""``Simulator`` starts from any script, as ``Panda``'s control process does: one without
``if __name__ == "__main__":`` (its spawned children used to re-run it and start the
simulator again), a script piped on stdin (which they could not re-run: "simulator
process died on start") and ``python -c``; with its Desk too."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = pytest.mark.timeout(120)

SCRIPT = """\
from panda_py import libfranka
from panda_py.sim import Simulator, free_loopback_host
from panda_py.sim.desk import DeskConfig

desk = DeskConfig() if {desk} else None
sim = Simulator(free_loopback_host(), lockstep=True, desk=desk).start()
with libfranka.Robot(sim.host) as robot:
    print("robot mode:", robot.read_once().robot_mode.name)
print("desk:", sim.desk is not None)
sim.stop()
print("stopped")
"""


def _run(how: str, tmp_path: Path, desk: bool = False) -> str:
    source = SCRIPT.format(desk=desk)
    if how == "file":
        path = tmp_path / "no_main_guard.py"
        path.write_text(source)
        cmd, stdin = [sys.executable, str(path)], None
    elif how == "stdin":
        cmd, stdin = [sys.executable, "-"], source
    else:
        cmd, stdin = [sys.executable, "-c", source], None
    proc = subprocess.run(
        cmd, input=stdin, capture_output=True, text=True, timeout=100, cwd=tmp_path
    )
    assert proc.returncode == 0, proc.stderr[-3000:]
    return proc.stdout


@pytest.mark.parametrize("how", ["file", "stdin", "-c"])
def test_a_script_without_a_main_guard_starts_the_simulator_once(how: str, tmp_path: Path) -> None:
    out = _run(how, tmp_path)
    assert out.splitlines() == ["robot mode: kIdle", "desk: False", "stopped"]


def test_with_its_desk_from_stdin(tmp_path: Path) -> None:
    out = _run("stdin", tmp_path, desk=True)
    assert out.splitlines() == ["robot mode: kIdle", "desk: True", "stopped"]
