"""The Desk's duties against a mock transport: payloads checked before anything is
sent, the requests each dialect gets, the stored shapes read back, errors that pickle."""

from __future__ import annotations

import base64
import json
import math
import pickle
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from panda_py.desk import (
    PAYLOAD_MAX,
    BrakesError,
    BringUpStep,
    CertificateChangedError,
    ControlNotGrantedError,
    Desk,
    DeskAnswerError,
    DeskConnectionError,
    DeskHTTPError,
    DeskTimeoutError,
    DeskUnsupportedError,
    FCIRefusedError,
    MockTransport,
    NotInControlError,
    OperatingModeError,
    RecoveryRefusedError,
    Request,
    Response,
    SelfTestFailedError,
    check_payload,
)
from panda_py.desk.end_effector import from_legacy, from_v1, rpy_to_matrix
from panda_py.sim.desk.duties import _matrix, _rpy
from panda_py.sim.desk.link import DeskLink
from panda_py.sim.desk.state import DeskState

HOST = "robot.test"
HAND_T = [0.7071, -0.7071, 0, 0, 0.7071, 0.7071, 0, 0, 0, 0, 1, 0, 0, 0, 0.1034, 1]


def _json(status: int, body: object) -> Response:
    return Response(status, {"content-type": "application/json"}, json.dumps(body).encode())


class FakeDesk:
    """A v1 (or legacy) Desk that holds one end-effector configuration and answers the
    session's requests (control is free, the token "TOK")."""

    def __init__(self, api: str) -> None:
        self.api = api
        # external_gripper_example's endeffector-config.json (the legacy document)
        self.legacy_doc: dict[str, Any] = {
            "name": "Other", "mass": 0.9, "centerOfMass": [0, 0, 0.057], "transformation": HAND_T,
            "inertia": [0.002768, 0, 0, 0, 0.003149, 0, 0, 0, 0.000564],
        }  # fmt: skip
        self.v1_body: dict[str, Any] = {
            "endEffectorConfiguration": {
                "endEffector": {
                    "name": "Other",
                    "params": {
                        "mass": 0.9,
                        "centerOfMass": {"x": 0, "y": 0, "z": 0.057},
                        "inertia": {"x11": 0.002768, "x12": 0, "x13": 0, "x22": 0.003149,
                                    "x23": 0, "x33": 0.000564},
                        "transformation": {
                            "translation": {"x": 0, "y": 0, "z": 0.1034},
                            "rotation": {"roll": 0, "pitch": 0, "yaw": -math.pi / 4},
                        },
                    },
                }
            },
            "network": {"kept": True},
        }  # fmt: skip
        self.writes: list[Any] = []

    def __call__(self, req: Request) -> Response:
        body = json.loads(req.body) if req.body else None
        if self.api == "legacy":
            if req.path == "/api/system":
                return Response(404, {}, b"File not found")
            if req.path == "/admin/api/login":
                return Response(200, {"content-type": "text/plain"}, b"SESSION")
            if req.path == "/admin/api/control-token" and req.method == "GET":
                return _json(200, {"activeToken": None})
            if req.path == "/admin/api/control-token/request":
                return _json(200, {"id": 1, "token": "TOK"})
            if req.path == "/desk/api/robot/end-effector":
                if req.method == "POST":
                    self.writes.append((req.headers.get("X-Control-Token"), body))
                    self.legacy_doc = body
                    return Response(200)
                return _json(200, self.legacy_doc)
            if req.path == "/admin/api/system-status":
                return Response(404, {}, b"File not found")  # a FER on system 4.2
            return Response(200)
        basic = "Basic " + base64.b64encode(b"franka:secret").decode()
        if req.headers.get("Authorization") != basic:
            return _json(401, {"code": "Unauthorized"})
        if req.path == "/api/system":
            return _json(200, {})
        if req.path == "/api/system/control-token":
            return _json(200, {"owner": None, "tokenId": None})
        if req.path == "/api/system/control-token:take":
            return _json(200, {"token": "TOK", "tokenId": 1})
        if req.path == "/api/configuration":
            if req.method == "PATCH":
                self.writes.append((req.headers.get("X-Control-Token"), body))
                ee = body["endEffectorConfiguration"]["endEffector"]
                self.v1_body["endEffectorConfiguration"]["endEffector"] = ee
                return Response(204)
            return _json(200, self.v1_body)
        return Response(204)


def make(robot: FakeDesk, tmp_path: Path) -> tuple[Desk, MockTransport]:
    transport = MockTransport(robot)
    desk = Desk(HOST, "franka", "secret", transport=transport, token_dir=str(tmp_path))
    return desk, transport


@pytest.mark.parametrize("api", ["v1", "legacy"])
def test_payload_written_keeps_name_and_frame_and_reads_back(api: str, tmp_path: Path) -> None:
    robot = FakeDesk(api)
    desk, _ = make(robot, tmp_path)
    before = desk.end_effector()
    assert before.mass == 0.9 and before.name == "Other"
    assert np.allclose(before.F_T_EE, np.array(HAND_T).reshape(4, 4, order="F"), atol=1e-4)
    inertia = np.diag([0.01, 0.02, 0.025])
    inertia[0, 1] = inertia[1, 0] = 0.001
    after = desk.set_payload(1.25, (0.01, -0.02, 0.08), inertia)
    assert after.mass == 1.25 and after.name == "Other"
    assert np.allclose(after.center_of_mass, [0.01, -0.02, 0.08])
    assert np.allclose(after.inertia, inertia)
    assert np.allclose(after.F_T_EE, before.F_T_EE)
    ((token, body),) = robot.writes
    assert token == "TOK"
    if api == "v1":  # only the end effector is patched, the rest of the configuration not
        assert set(body) == {"endEffectorConfiguration"}
        params = body["endEffectorConfiguration"]["endEffector"]["params"]
        assert params["inertia"] == {
            "x11": 0.01, "x12": 0.001, "x13": 0.0, "x22": 0.02, "x23": 0.0, "x33": 0.025
        }  # fmt: skip
        assert params["transformation"]["rotation"]["yaw"] == -math.pi / 4


ABSURD = [
    ({"mass": -0.1}, "mass"),
    ({"mass": math.nan}, "mass"),
    ({"mass": math.inf}, "mass"),
    ({"mass": PAYLOAD_MAX + 0.01}, "mass"),
    ({"mass": "1"}, "mass"),
    ({"center_of_mass": (0.0, math.nan, 0.0)}, "center_of_mass"),
    ({"center_of_mass": (0.0, 0.0)}, "center_of_mass"),
    ({"center_of_mass": (0.0, 0.0, 1.5)}, "center_of_mass"),
    ({"inertia": [[0.01, 0.005, 0], [0, 0.01, 0], [0, 0, 0.01]]}, "symmetric"),
    ({"inertia": np.diag([0.01, -0.01, 0.01])}, "positive semi-definite"),
    ({"inertia": np.diag([0.01, 0.01, 0.05])}, "triangle"),
    ({"inertia": np.full((3, 3), math.nan)}, "inertia"),
    ({"inertia": np.eye(2)}, "inertia"),
]


@pytest.mark.parametrize(("bad", "named"), ABSURD)
@pytest.mark.parametrize("api", ["v1", "legacy"])
def test_absurd_payload_refused_before_any_request(
    api: str, bad: dict[str, Any], named: str, tmp_path: Path
) -> None:
    desk, transport = make(FakeDesk(api), tmp_path)
    transport.requests.clear()
    args: dict[str, Any] = {"mass": 1.0, "center_of_mass": (0, 0, 0.05)}
    args["inertia"] = np.eye(3) * 1e-3
    args.update(bad)
    with pytest.raises(ValueError, match=named) as info:
        desk.set_payload(**args)
    assert "expected" in str(info.value) and "got" in str(info.value)
    assert transport.requests == []


def test_payload_limits_accept_the_edges() -> None:
    m, com, inertia = check_payload(PAYLOAD_MAX, [0, 0, 0], np.zeros((3, 3)))
    assert m == PAYLOAD_MAX and com.shape == (3,) and inertia.shape == (3, 3)
    assert check_payload(0, [0, 0, 1.0], np.diag([1.0, 1.0, 2.0]))[0] == 0.0


def test_set_payload_without_control_sends_nothing(tmp_path: Path) -> None:
    desk = Desk(HOST, "franka", "secret", transport=MockTransport(FakeDesk("v1")),
                token_dir=str(tmp_path), connect=False)  # fmt: skip
    with pytest.raises(NotInControlError):
        desk.set_payload(1.0, (0, 0, 0.05), np.eye(3) * 1e-3)


def test_a_legacy_desk_without_system_status_has_no_self_test(tmp_path: Path) -> None:
    desk, _ = make(FakeDesk("legacy"), tmp_path)
    with pytest.raises(DeskUnsupportedError) as info:
        desk.self_test_due_in()
    assert (info.value.feature, info.value.api) == ("self_test", "legacy")
    assert desk.pending_recoveries() == []


def test_the_stored_rotation_reads_the_same_on_both_sides() -> None:
    rng = np.random.default_rng(7)
    for roll, pitch, yaw in rng.uniform(-3, 3, (20, 3)):
        pitch = pitch / 2.1  # away from the gimbal lock
        assert np.allclose(rpy_to_matrix(roll, pitch, yaw), _matrix(roll, pitch, yaw))
        assert np.allclose(_matrix(*_rpy(_matrix(roll, pitch, yaw))), _matrix(roll, pitch, yaw))


@pytest.mark.parametrize("robot", ["fer", "fr3"])
def test_the_simulated_desks_stored_shapes_read_as_the_hand(robot: str) -> None:
    state = DeskState(robot, {"franka": "pw"}, DeskLink.create(locked=True))
    v1, legacy = from_v1(state.end_effector_v1()), from_legacy(state.end_effector_legacy())
    for cfg in (v1, legacy):
        assert cfg.name == "Franka Hand" and cfg.mass == pytest.approx(0.73)
        assert np.allclose(cfg.center_of_mass, [-0.01, 0.0, 0.03])
        assert np.allclose(cfg.F_T_EE[:3, 3], [0, 0, 0.1034])
    assert np.allclose(v1.F_T_EE, legacy.F_T_EE) and np.allclose(v1.inertia, legacy.inertia)


def test_the_simulated_desk_refuses_absurd_payloads_and_changes_nothing() -> None:
    state = DeskState("fr3", {"franka": "pw"}, DeskLink.create(locked=True))
    before = state.end_effector_legacy()
    for mass in (-1.0, math.nan, 4.0):
        doc = {**before, "mass": mass}
        assert state.configure_legacy(doc).status == 400
    body = state.end_effector_v1()
    body["endEffectorConfiguration"]["endEffector"]["params"]["inertia"]["x11"] = -1.0
    assert state.configure_v1(body).status == 400
    assert state.configure_v1({"endEffectorConfiguration": {}}).status == 400
    assert state.end_effector_legacy() == before
    # a PATCH changes only what it gives
    assert state.configure_v1({"network": {}}).status == 200
    patch = {"endEffectorConfiguration": {"endEffector": {"params": {"mass": 1.1}}}}
    assert state.configure_v1(patch).status == 200
    assert state.end_effector_legacy() == {**before, "mass": 1.1}


def _same(a: BaseException, b: BaseException) -> None:
    assert type(a) is type(b) and str(a) == str(b)
    fields = {k: v for k, v in vars(a).items() if not k.startswith("__")}
    assert fields == {k: v for k, v in vars(b).items() if not k.startswith("__")}


def test_errors_pickle_with_their_fields() -> None:
    http = DeskHTTPError("POST", "/api/fci:activate", 424, '{"code": "X", "reason": "Y"}')
    errors: list[BaseException] = [
        http,
        CertificateChangedError("robot", "AA", "BB"),
        DeskUnsupportedError("self_test", "legacy", "no self-test"),
        ControlNotGrantedError("robot", "held", holder="alice", reason="Timeout"),
        RecoveryRefusedError.from_http("robot", "refused", http, kind="SafetyError"),
        SelfTestFailedError("robot", "did not pass", due_in=0.0),
        OperatingModeError("robot", "no"),
        BrakesError("robot", "still locked", brakes=("Locked",) * 7),
        DeskConnectionError("reset", host="robot", what="GET /api/system"),
        DeskTimeoutError(2.0, host="robot", what="GET /api/system", received=3, start="HTT"),
        DeskAnswerError("GET", "/api/fci", 200, "JSON of another shape", "[1]"),
        FCIRefusedError.from_http("robot", "refused", http),
    ]
    for e in errors:
        _same(e, pickle.loads(pickle.dumps(e)))
    assert (http.code, http.reason) == ("X", "Y")
    refused = errors[-1]
    assert isinstance(refused, FCIRefusedError) and refused.step is BringUpStep.FCI
    assert (refused.status, refused.code, refused.reason) == (424, "X", "Y")
    assert isinstance(errors[3], NotInControlError)
