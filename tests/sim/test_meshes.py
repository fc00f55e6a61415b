"""The arm's visual meshes in the drawings (sim/meshes.py): in the drawing model where
rtb-data ships them, capsules where it does not, the physics untouched."""

from __future__ import annotations

import importlib.abc
import json
import os
import subprocess
import sys
from pathlib import Path

import mujoco
import numpy as np
import pytest

from panda_py.robots.params import get_robot
from panda_py.sim import meshes
from panda_py.sim.config import SimConfig
from panda_py.sim.frames import build_model
from panda_py.sim.physics import Physics

pytestmark = pytest.mark.timeout(120)

HAS_RTBDATA = meshes.mesh_dir() is not None


def _mesh_geoms(model) -> list[str]:
    return [
        mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
        for g in range(model.ngeom)
        if model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
    ]


class _Hide(importlib.abc.MetaPathFinder):
    def find_spec(self, name, path=None, target=None):
        if name == "rtbdata" or name.startswith("rtbdata."):
            raise ModuleNotFoundError(f"No module named {name!r}")
        return None


@pytest.mark.skipif(not HAS_RTBDATA, reason="rtb-data is not installed")
def test_the_drawing_model_has_the_meshes_and_hides_the_capsules() -> None:
    model = build_model(SimConfig())
    names = _mesh_geoms(model)
    assert sorted(names) == sorted(
        [f"link{i}_visual" for i in range(8)]
        + ["hand_frame_visual", "left_finger_visual", "right_finger_visual"]
    )
    drawn = mujoco.MjvOption().geomgroup
    table = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "table")
    cube = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_GEOM, "cube_geom")
    assert drawn[model.geom_group[table]] and drawn[model.geom_group[cube]]
    for g in range(model.ngeom):
        body = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_BODY, model.geom_bodyid[g])
        mesh = model.geom_type[g] == mujoco.mjtGeom.mjGEOM_MESH
        if mesh:
            assert drawn[model.geom_group[g]] and model.geom_contype[g] == 0
            assert model.geom_conaffinity[g] == 0
        elif body.startswith("link") or body in ("hand_frame", "left_finger", "right_finger"):
            assert not drawn[model.geom_group[g]], body  # the arm's capsule, not drawn


def test_without_rtbdata_capsules_and_a_debug_line(monkeypatch, caplog) -> None:
    monkeypatch.delitem(sys.modules, "rtbdata", raising=False)
    monkeypatch.setattr(sys, "meta_path", [_Hide(), *sys.meta_path])
    monkeypatch.setattr(meshes, "_said", False)
    with caplog.at_level("DEBUG", logger="panda_py.sim"):
        model = build_model(SimConfig())
    assert _mesh_geoms(model) == [] and model.nmesh == 0
    assert any("capsules" in r.getMessage() and r.levelname == "DEBUG" for r in caplog.records)
    plain = build_model(SimConfig(), meshes=False)
    assert model.ngeom == plain.ngeom and np.array_equal(model.geom_group, plain.geom_group)


@pytest.mark.skipif(not HAS_RTBDATA, reason="rtb-data is not installed")
@pytest.mark.parametrize("end_effector", ["hand", "cobot_pump"])
def test_the_physics_is_the_same_with_the_meshes_bit_for_bit(end_effector: str) -> None:
    config = SimConfig(end_effector=end_effector)
    physics = Physics(get_robot(config.robot), end_effector=end_effector).model
    drawing = build_model(config)
    assert physics.nmesh == 0
    assert (physics.nbody, physics.nq, physics.nv, physics.nu) == (
        drawing.nbody, drawing.nq, drawing.nv, drawing.nu
    )  # fmt: skip
    assert physics.ngeom == build_model(config, meshes=False).ngeom
    assert drawing.ngeom > physics.ngeom
    drawing.opt.timestep = physics.opt.timestep
    runs = []
    for model in (physics, drawing):
        data = mujoco.MjData(model)
        data.qpos[:7] = config.q_start
        for k in range(400):  # a push and the arm falling onto the table
            data.qfrc_applied[:7] = 5.0 * np.sin(0.01 * k + np.arange(7))
            mujoco.mj_step(model, data)
        runs.append((data.qpos.copy(), data.qvel.copy(), data.ncon))
    assert np.array_equal(runs[0][0], runs[1][0]) and np.array_equal(runs[0][1], runs[1][1])
    assert runs[0][2] == runs[1][2]


_RENDER = """
import json, sys
import numpy as np
from panda_py.sim.config import SimConfig
from panda_py.sim.frames import offscreen
import mujoco
out = {}
for meshes in (True, False):
    model, renderer, cam = offscreen(SimConfig(), 160, 120, "test", meshes=meshes)
    data = mujoco.MjData(model)
    data.qpos[:7] = SimConfig().q_start
    mujoco.mj_forward(model, data)
    renderer.update_scene(data, cam)
    np.save(sys.argv[1] + f"_{meshes}.npy", renderer.render())
    renderer.close()
print(json.dumps("ok"))
"""


@pytest.mark.skipif(not HAS_RTBDATA, reason="rtb-data is not installed")
def test_a_frame_with_the_meshes_differs_from_the_capsules(tmp_path: Path) -> None:
    env = {**os.environ, "MUJOCO_GL": os.environ.get("MUJOCO_GL", "egl")}
    base = str(tmp_path / "frame")
    run = subprocess.run(
        [sys.executable, "-c", _RENDER, base], env=env, capture_output=True, text=True, timeout=100
    )
    if run.returncode != 0:
        if os.environ.get("CI", "").lower() == "true":
            pytest.fail(run.stderr)
        pytest.skip(f"no offscreen rendering here: {run.stderr[-300:]}")
    assert json.loads(run.stdout) == "ok"
    mesh, capsule = np.load(base + "_True.npy"), np.load(base + "_False.npy")
    assert mesh.shape == capsule.shape == (120, 160, 3)
    differ = np.abs(mesh.astype(int) - capsule.astype(int)).max(axis=2) > 40
    assert differ.sum() > 200  # the arm's outline and the dark hand
