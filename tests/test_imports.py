"""Imports stay light: the package, the client, the kinematics and the pytest plugin load
neither MuJoCo, nor the simulator, nor numba (which loads on the first kinematics call)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

HEAVY = ("mujoco", "numba", "panda_py.sim.api", "panda_py.sim.server", "panda_py.sim.physics")


def _modules_after(statement: str) -> set[str]:
    code = f"import sys, json\n{statement}\nprint(json.dumps(sorted(sys.modules)))"
    out = subprocess.run(
        [sys.executable, "-c", code], capture_output=True, text=True, check=True, timeout=120
    )
    return set(json.loads(out.stdout.splitlines()[-1]))


@pytest.mark.parametrize(
    "module",
    [
        "panda_py",
        "panda_py.libfranka",
        "panda_py.kinematics",
        "panda_py.sim.testing",
        "panda_py.panda",
        "panda_py.controllers",
        "panda_py.constants",
    ],
)
def test_import_pulls_in_no_simulator_mujoco_or_numba(module: str) -> None:
    loaded = _modules_after(f"import {module}")
    assert module in loaded
    assert not [m for m in loaded if m.split(".")[0] in HEAVY or m in HEAVY]
    if module != "panda_py.sim.testing":
        assert not [m for m in loaded if m.startswith("panda_py.sim")]


def test_the_simulator_loads_mujoco_in_its_own_process_only() -> None:
    """``Simulator`` starts the simulated robot in a child process: the caller's process
    loads its API, not MuJoCo or the server (a fifth of a second of every script's start);
    the server, run in process (``panda-sim``), loads MuJoCo."""
    loaded = _modules_after("from panda_py.sim import Simulator, SimConfig")
    assert "panda_py.sim.api" in loaded
    assert not {"mujoco", "numba", "panda_py.sim.server", "panda_py.sim.physics"} & loaded
    assert {"mujoco", "panda_py.sim.physics"} <= _modules_after(
        "from panda_py.sim.server import SimServer"
    )
