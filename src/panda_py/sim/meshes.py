"""The arm's visual meshes in the drawings (the viewer, the video, the camera), where a
package ships them: rtb-data (``pip install 'panda-py[meshes]'``, also in the ``examples``
extra) holds the Panda's link, hand and finger meshes. Without it the arm is drawn as the
capsules it collides with, and a debug line says so; nothing is downloaded.

Only the drawing processes' models get the meshes (:func:`~panda_py.sim.frames.build_model`):
the simulator's physics model is never touched. In a drawing model the meshes are visual
geoms (``contype``/``conaffinity`` 0, no mass: the model's inertials are explicit) in
:data:`VISUAL_GROUP`, and the arm's collision geoms move to :data:`COLLISION_GROUP`, which
MuJoCo's default drawing options (``mjvOption.geomgroup``) leave out; the table, the cube
and the scene's other geoms keep their group and stay drawn. In the viewer, key ``3``
shows the collision geoms again.

The meshes are in franka_description's URDF link frames, which are the modified-DH frames
our bodies follow (:mod:`panda_py.robots.mjcf`): each link's mesh goes in its body as it
is, the hand's in the hand's frame (turned -45 deg about the flange's z), the fingers' at
their joints' origin above it, the right finger's turned 180 deg about z.
"""

from __future__ import annotations

import importlib.util
import logging
import xml.etree.ElementTree as ET
from pathlib import Path

from panda_py.robots.params import DH_FRANKA, get_robot

log = logging.getLogger("panda_py.sim")

VISUAL_GROUP = 2  # the meshes' geom group (drawn by MuJoCo's default options)
COLLISION_GROUP = 3  # the arm's collision geoms in a drawing with meshes (not drawn)
# The directory of the Panda's meshes inside the rtbdata package.
MESH_SUBDIR = ("meshes", "FRANKA-EMIKA", "Panda")
# [m] the fingers' joint frames above the hand's frame (franka_description: panda_finger_joint*)
FINGER_Z = 0.0584

_WHITE = "0.95 0.95 0.95 1"  # the links, as the Panda's white covers
_DARK = "0.25 0.25 0.27 1"  # the hand
_BLACK = "0.12 0.12 0.12 1"  # the fingers
_TURN_Z = "0 0 0 1"  # 180 deg about z (w x y z)

# body -> (mesh file, colour, pos, quat) of the mesh in the body's frame
_PLACES: dict[str, tuple[str, str, str, str]] = {
    **{f"link{i}": (f"link{i}.stl", _WHITE, "0 0 0", "1 0 0 0") for i in range(8)},
    "hand_frame": ("hand.stl", _DARK, "0 0 0", "1 0 0 0"),
    "left_finger": ("finger.stl", _BLACK, f"0 0 {FINGER_Z!r}", "1 0 0 0"),
    "right_finger": ("finger.stl", _BLACK, f"0 0 {FINGER_Z!r}", _TURN_Z),
}

_said = False  # the fallback's debug line, once per process


def mesh_dir() -> Path | None:
    """The directory of the Panda's meshes in an installed rtb-data, or None (and a debug
    line, once) when it is not installed or lacks them. Finds the package without
    importing it."""
    global _said
    try:
        spec = importlib.util.find_spec("rtbdata")
    except (ImportError, ValueError):  # hidden, or a broken entry in sys.modules
        spec = None
    roots = list(spec.submodule_search_locations or []) if spec is not None else []
    for root in roots:
        path = Path(root).joinpath(*MESH_SUBDIR)
        if all((path / name).is_file() for name, *_ in _PLACES.values()):
            return path
    if not _said:
        _said = True
        why = "rtb-data is not installed" if not roots else "rtb-data has no Panda meshes"
        log.debug(
            "the arm is drawn as capsules: %s (pip install 'panda-py[meshes]' for its meshes)",
            why,
        )
    return None


def with_meshes(xml: str, robot: str, directory: Path) -> str:
    """``xml`` (a model of :func:`panda_py.robots.mjcf.model_xml`) with the arm's meshes
    from ``directory`` added as visual geoms, the arm's collision geoms moved out of the
    drawn groups. Unchanged for an arm whose frames are not the Panda's (its own DH)."""
    if get_robot(robot).dh != DH_FRANKA:
        return xml
    root = ET.fromstring(xml)
    asset = root.find("asset")
    if asset is None:
        asset = ET.SubElement(root, "asset")
    bodies = {b.get("name"): b for b in root.iter("body")}
    for name, (file, rgba, pos, quat) in _PLACES.items():
        body = bodies.get(name)
        if body is None:  # no hand (hand=False, the Cobot Pump): its geoms stay drawn
            continue
        mesh = f"panda_{Path(file).stem}"
        if asset.find(f"mesh[@name='{mesh}']") is None:
            ET.SubElement(asset, "mesh", name=mesh, file=str(directory / file))
        for geom in body.findall("geom"):
            geom.set("group", str(COLLISION_GROUP))
        # after the body's inertial and joints (MJCF takes its children in any order)
        ET.SubElement(
            body,
            "geom",
            name=f"{name}_visual",
            type="mesh",
            mesh=mesh,
            pos=pos,
            quat=quat,
            rgba=rgba,
            group=str(VISUAL_GROUP),
            contype="0",
            conaffinity="0",
            mass="0",
        )
    return ET.tostring(root, encoding="unicode")


__all__ = ["COLLISION_GROUP", "FINGER_Z", "VISUAL_GROUP", "mesh_dir", "with_meshes"]
