"""The end-effector configuration a robot's Desk stores: what the flange carries (mass,
centre of mass, inertia) and where the end-effector frame sits (``F_T_EE``).

Every controller's gravity and dynamics model depends on it: the robot reports it as
``m_ee``, ``F_x_Cee``, ``I_ee`` and ``F_T_EE``. A payload is checked here, before any
request is sent: a wrong one makes the arm sag or drift, an absurd one (a negative
mass, NaN) has no business reaching a robot.

Two stored shapes (see ``duty_api.py`` for the endpoints and where they were learned):

- Desk API v1, ``GET /api/configuration``: ``endEffectorConfiguration.endEffector`` =
  ``{"name", "params": {"mass", "centerOfMass": {x, y, z}, "inertia": {x11, x12, x13,
  x22, x23, x33}, "transformation": {"translation": {x, y, z}, "rotation": {roll, pitch,
  yaw}}}}`` (as aiofranka's ``config`` command reads and patches it).
- Legacy: the Desk's end-effector file, ``{"name", "mass", "centerOfMass": [3],
  "transformation": [16, column-major], "inertia": [9]}`` (frankaemika/
  external_gripper_example, ``endeffector-config.json``).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from panda_py import checks

PAYLOAD_MAX = 3.0
"""The heaviest payload a Desk accepts [kg]: the FER's and FR3's data sheets' 3 kg, the end
effector included."""
# [m] farthest centre of mass from the flange: unpublished; a tool a metre long already
# exceeds the arm's payload moment (the simulator's limit for loads too).
MAX_COM_OFFSET = 1.0
# [kg m^2] symmetry, positive semi-definiteness and the triangle inequality of an inertia
# hold up to this (plus the same relative to its largest entry).
INERTIA_TOL = 1e-9


@dataclass(eq=False)
class EndEffectorConfig:
    """The end effector as the Desk stores it.

    ``mass`` [kg]; ``center_of_mass`` (3,) [m] in the flange frame; ``inertia`` (3, 3)
    [kg m^2] about the centre of mass; ``F_T_EE`` (4, 4) the flange-to-EE transform
    [m]; ``name`` as the Desk shows it (e.g. ``"Franka Hand"``, ``"Other"``); ``raw``
    the robot's answer as it came (what a write keeps of it).
    """

    name: str
    mass: float
    center_of_mass: NDArray[np.float64]
    inertia: NDArray[np.float64]
    F_T_EE: NDArray[np.float64]
    raw: dict[str, Any] = field(default_factory=dict, repr=False)


def check_payload(
    mass: Any, center_of_mass: Any, inertia: Any, *, max_mass: float = PAYLOAD_MAX
) -> tuple[float, NDArray[np.float64], NDArray[np.float64]]:
    """``mass`` [kg] in [0, ``max_mass``], ``center_of_mass`` 3 finite values [m] within
    :data:`MAX_COM_OFFSET` of the flange, ``inertia`` a 3x3 (or 9 values) [kg m^2] that
    is symmetric, positive semi-definite and obeys the triangle inequality of its
    principal moments. Returns them as (float, (3,), (3, 3)); raises ``ValueError`` naming
    the argument, what was expected and what was given."""
    m = checks.number("mass", mass, "[kg]", low=0.0, high=max_mass)
    com = checks.vector("center_of_mass", center_of_mass, 3, "[m]")
    if not float(np.linalg.norm(com)) <= MAX_COM_OFFSET:
        raise ValueError(
            f"center_of_mass: expected within {MAX_COM_OFFSET:g} m of the flange [m], "
            f"got {com.tolist()}"
        )
    I = checks.vector("inertia", inertia, 9, "[kg m^2]").reshape(3, 3, order="F")
    tol = INERTIA_TOL * (1.0 + float(np.max(np.abs(I))))
    if not np.allclose(I, I.T, rtol=0.0, atol=tol):
        raise ValueError(f"inertia: expected a symmetric 3x3 matrix [kg m^2], got {I.tolist()}")
    moments = np.linalg.eigvalsh(I)  # ascending
    if moments[0] < -tol:
        raise ValueError(
            "inertia: expected a positive semi-definite matrix [kg m^2] (principal moments "
            f">= 0), got {I.tolist()} with principal moments {moments.tolist()}"
        )
    if moments[0] + moments[1] < moments[2] - tol:
        raise ValueError(
            "inertia: expected principal moments obeying the triangle inequality "
            f"(I1 + I2 >= I3) [kg m^2], got {moments.tolist()}"
        )
    return m, com, I


# -- roll, pitch, yaw ---------------------------------------------------------------------
# v1 stores the EE frame's rotation as roll, pitch, yaw [rad]; taken here as rotations about
# the fixed x, y and z axes in that order (R = Rz(yaw) Ry(pitch) Rx(roll), the URDF's
# convention). No public source states the Desk's; this is the one place to correct it.


def rpy_to_matrix(roll: float, pitch: float, yaw: float) -> NDArray[np.float64]:
    cr, sr, cp, sp = math.cos(roll), math.sin(roll), math.cos(pitch), math.sin(pitch)
    cy, sy = math.cos(yaw), math.sin(yaw)
    return np.array(
        [
            [cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr],
            [sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr],
            [-sp, cp * sr, cp * cr],
        ]
    )


# -- the two stored shapes ------------------------------------------------------------------


def _malformed(api: str, exc: Exception) -> ValueError:
    why = f"no {exc.args[0]!r}" if isinstance(exc, KeyError) else f"{type(exc).__name__}: {exc}"
    return ValueError(f"an end-effector configuration ({api}) that cannot be read: {why}")


def from_v1(body: Any) -> EndEffectorConfig:
    """The configuration in ``GET /api/configuration``'s answer; ``ValueError`` if it
    holds none that can be read (the Desk client makes that its ``DeskAnswerError``)."""
    try:
        ee = body["endEffectorConfiguration"]["endEffector"]
        p = ee["params"]
        c, i = p["centerOfMass"], p["inertia"]
        t = p.get("transformation") or {}
        tr, rot = t.get("translation") or {}, t.get("rotation") or {}
        T = np.eye(4)
        T[:3, :3] = rpy_to_matrix(
            float(rot.get("roll", 0.0)), float(rot.get("pitch", 0.0)), float(rot.get("yaw", 0.0))
        )
        T[:3, 3] = [float(tr.get(k, 0.0)) for k in "xyz"]
        inertia = np.array(
            [
                [i["x11"], i["x12"], i["x13"]],
                [i["x12"], i["x22"], i["x23"]],
                [i["x13"], i["x23"], i["x33"]],
            ],
            dtype=float,
        )
        return EndEffectorConfig(
            str(ee.get("name", "")),
            float(p["mass"]),
            np.array([c["x"], c["y"], c["z"]], dtype=float),
            inertia,
            T,
            raw=dict(body),
        )
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise _malformed("v1", exc) from exc


def v1_payload_patch(
    current: EndEffectorConfig, mass: float, com: NDArray[np.float64], inertia: NDArray[np.float64]
) -> dict[str, Any]:
    """``PATCH /api/configuration``'s body: the stored end effector with a new payload
    (its name and frame as the robot stored them, untouched)."""
    ee = copy.deepcopy(current.raw["endEffectorConfiguration"]["endEffector"])
    params = ee.setdefault("params", {})
    params["mass"] = mass
    params["centerOfMass"] = dict(zip("xyz", com.tolist(), strict=True))
    params["inertia"] = {
        f"x{r + 1}{c + 1}": float(inertia[r, c]) for r in range(3) for c in range(r, 3)
    }
    return {"endEffectorConfiguration": {"endEffector": ee}}


def from_legacy(body: Any) -> EndEffectorConfig:
    """The configuration in the legacy Desk's end-effector document; ``ValueError`` if
    it cannot be read."""
    try:
        T = np.array(body["transformation"], dtype=float).reshape(4, 4, order="F")
        return EndEffectorConfig(
            str(body.get("name", "")),
            float(body["mass"]),
            np.array(body["centerOfMass"], dtype=float).reshape(3),
            np.array(body["inertia"], dtype=float).reshape(3, 3, order="F"),
            T,
            raw=dict(body),
        )
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise _malformed("legacy", exc) from exc


def legacy_payload_document(
    current: EndEffectorConfig, mass: float, com: NDArray[np.float64], inertia: NDArray[np.float64]
) -> dict[str, Any]:
    """The legacy end-effector document with a new payload (name and frame kept)."""
    doc = copy.deepcopy(current.raw)
    doc["mass"] = mass
    doc["centerOfMass"] = com.tolist()
    doc["inertia"] = inertia.reshape(9, order="F").tolist()
    return doc


__all__ = [
    "INERTIA_TOL",
    "MAX_COM_OFFSET",
    "PAYLOAD_MAX",
    "EndEffectorConfig",
    "check_payload",
    "from_legacy",
    "from_v1",
    "legacy_payload_document",
    "rpy_to_matrix",
    "v1_payload_patch",
]
