"""PolicyServer against a client written here as openpi's is (websockets' sync client,
msgpack with openpi's numpy extension: openpi-client's ``websocket_client_policy.py`` and
``msgpack_numpy.py``), not with the server's own encoder. openpi's own client, end to end
on the simulator: examples/21_openpi_client.py (tests/examples/test_examples.py)."""

from __future__ import annotations

import http.client
import sys
import threading
import time
from collections.abc import Iterator
from typing import Any

import msgpack
import numpy as np
import pytest
from websockets.exceptions import ConnectionClosed
from websockets.sync.client import ClientConnection, connect

from panda_py.learning import PolicyServer

pytestmark = [
    pytest.mark.timeout(60),
    # openpi's client connects without a with block, as the Client below does; websockets
    # 17 warns of that
    pytest.mark.filterwarnings("ignore:connect\\(\\) must be used as a context manager"),
]
REASON = "Internal server error. Traceback included in previous frame."  # openpi's


def _encode(obj: Any) -> Any:
    if isinstance(obj, np.ndarray):
        return {b"__ndarray__": True, b"data": obj.tobytes(), b"dtype": obj.dtype.str,
                b"shape": obj.shape}  # fmt: skip
    if isinstance(obj, np.generic):
        return {b"__npgeneric__": True, b"data": obj.item(), b"dtype": obj.dtype.str}
    return obj


def _decode(obj: dict) -> Any:
    if b"__ndarray__" in obj:
        return np.ndarray(buffer=obj[b"data"], dtype=np.dtype(obj[b"dtype"]), shape=obj[b"shape"])
    if b"__npgeneric__" in obj:
        return np.dtype(obj[b"dtype"]).type(obj[b"data"])
    return obj


def pack(obj: Any) -> bytes:
    return msgpack.packb(obj, default=_encode)


def unpack(data: bytes) -> Any:
    return msgpack.unpackb(data, object_hook=_decode)


class Client:
    """openpi's WebsocketClientPolicy, in short: the metadata on connecting, then
    ``infer``; a text answer is the server's error."""

    def __init__(self, server: PolicyServer) -> None:
        self.ws: ClientConnection = connect(server.url, compression=None, max_size=None)
        self.metadata = unpack(self.ws.recv())

    def infer(self, obs: dict) -> dict:
        self.ws.send(pack(obs))
        response = self.ws.recv()
        if isinstance(response, str):
            raise RuntimeError(f"Error in inference server:\n{response}")
        return unpack(response)

    def close(self) -> None:
        self.ws.close()


def echo(obs: dict) -> dict:
    return {"echo": obs}


@pytest.fixture
def server() -> Iterator[PolicyServer]:
    with PolicyServer(echo, port=0, metadata={"action_horizon": 10}) as server:
        yield server


def assert_closed_with_1011(client: Client) -> None:
    """After the traceback, openpi's server closes the connection: 1011, its reason."""
    with pytest.raises(ConnectionClosed) as closed:
        client.ws.recv()
    assert closed.value.rcvd is not None
    assert (closed.value.rcvd.code, closed.value.rcvd.reason) == (1011, REASON)


def test_metadata_on_connect_then_numpy_round_trips(server: PolicyServer) -> None:
    assert server.port > 0 and server.url == f"ws://127.0.0.1:{server.port}"
    client = Client(server)
    assert client.metadata == {"action_horizon": 10}
    rng = np.random.default_rng(0)
    obs = {
        "observation/exterior_image_1_left": rng.integers(0, 256, (224, 224, 3), np.uint8),
        "observation/joint_position": rng.normal(size=7),
        "observation/gripper_position": np.array([0.25], np.float32),
        "counts": np.arange(6, dtype=">i4").reshape(2, 3),  # big-endian: dtype.str kept
        "mask": np.array([True, False]),
        "scalar": np.float32(1.5),
        "nested": {"list": [1, "two", 3.0], "none": None},
        "prompt": "pick up the cube",
    }
    for n in range(2):
        response = client.infer(obs)
        back = response["echo"]
        assert sorted(back) == sorted(obs)
        for key, value in obs.items():
            if isinstance(value, np.ndarray):
                assert back[key].dtype == value.dtype and back[key].shape == value.shape
                np.testing.assert_array_equal(back[key], value)
        assert type(back["scalar"]) is np.float32 and back["scalar"] == 1.5
        assert back["nested"] == {"list": [1, "two", 3.0], "none": None}
        assert back["prompt"] == "pick up the cube"
        timing = response["server_timing"]
        assert timing["infer_ms"] >= 0.0
        assert ("prev_total_ms" in timing) == (n == 1)  # the previous request's
    client.close()


def test_an_array_is_sent_as_actions() -> None:
    chunks = {"list": lambda obs: [[0.1] * 8] * 10, "array": lambda obs: np.ones((10, 8))}
    for policy in chunks.values():
        with PolicyServer(policy, port=0) as server:
            client = Client(server)
            assert client.metadata == {}
            response = client.infer({"x": 1})
            assert response["actions"].shape == (10, 8)
            assert set(response) == {"actions", "server_timing"}


def test_a_failing_policy_is_reported_and_the_server_serves_on() -> None:
    def policy(obs: dict) -> Any:
        if "fail" in obs:
            raise RuntimeError("the policy failed here")
        if "none" in obs:
            return None
        return {"ok": True}

    with PolicyServer(policy, port=0) as server:
        other = Client(server)  # open all along: unaffected
        client = Client(server)
        with pytest.raises(RuntimeError, match=r"(?s)Traceback.*the policy failed here"):
            client.infer({"fail": 1})
        assert_closed_with_1011(client)
        with pytest.raises(RuntimeError, match="expected a dict or an array of numbers"):
            Client(server).infer({"none": 1})
        assert other.infer({})["ok"] is True
        assert Client(server).infer({})["ok"] is True


@pytest.mark.parametrize(
    "garbage",
    [b"\xc1", b"\x93\x01", "a text message", pack({"x": {b"__ndarray__": True, b"data": b"12",
                                                        b"dtype": "<f8", b"shape": [4]}})],
    ids=["not-msgpack", "truncated", "text", "array-short-of-its-shape"],
)  # fmt: skip
def test_garbage_is_reported_and_the_server_serves_on(
    server: PolicyServer, garbage: bytes | str
) -> None:
    client = Client(server)
    client.ws.send(garbage)
    answer = client.ws.recv()
    assert isinstance(answer, str) and "Traceback (most recent call last)" in answer
    assert_closed_with_1011(client)
    assert Client(server).infer({"x": 1})["echo"] == {"x": 1}


def test_a_client_gone_mid_request_does_not_stop_the_server() -> None:
    started = threading.Event()

    def slow(obs: dict) -> dict:
        started.set()
        time.sleep(0.2)
        return {"done": True}

    with PolicyServer(slow, port=0) as server:
        client = Client(server)
        client.ws.send(pack({}))
        assert started.wait(5)
        client.ws.socket.close()  # no closing handshake: gone
        assert Client(server).infer({})["done"] is True


def test_concurrent_clients_each_get_their_answers_one_inference_at_a_time() -> None:
    active, most = [0], [0]
    lock = threading.Lock()

    def policy(obs: dict) -> dict:
        with lock:
            active[0] += 1
            most[0] = max(most[0], active[0])
        time.sleep(0.005)
        with lock:
            active[0] -= 1
        return {"actions": np.full((10, 8), obs["id"] * 1000 + obs["n"], np.float64)}

    errors: list[BaseException] = []

    def run(client_id: int) -> None:
        try:
            client = Client(server)
            for n in range(15):
                actions = client.infer({"id": client_id, "n": n})["actions"]
                assert (actions == client_id * 1000 + n).all()
            client.close()
        except BaseException as exc:  # reported below
            errors.append(exc)

    with PolicyServer(policy, port=0) as server:
        threads = [threading.Thread(target=run, args=(i,)) for i in range(4)]
        for t in threads:
            t.start()
        for t in threads:
            t.join(30)
    assert not errors, errors
    assert most[0] == 1  # openpi's server runs its policy on its one event loop


def test_healthz_answers_ok(server: PolicyServer) -> None:
    conn = http.client.HTTPConnection("127.0.0.1", server.port, timeout=5)
    conn.request("GET", "/healthz")
    response = conn.getresponse()
    assert response.status == 200 and response.read() == b"OK\n"


def test_close_ends_the_connections_and_is_idempotent() -> None:
    server = PolicyServer(echo, port=0).start()
    client = Client(server)
    server.close()
    with pytest.raises(ConnectionClosed) as closed:
        client.infer({"x": 1})
    assert closed.value.rcvd is not None and closed.value.rcvd.code == 1001  # going away
    server.close()
    with pytest.raises(OSError):
        Client(server)
    with pytest.raises(RuntimeError, match="already serving or closed"):
        server.start()


def test_serve_forever_until_closed_from_another_thread() -> None:
    server = PolicyServer(echo, port=0)
    thread = threading.Thread(target=server.serve_forever)
    thread.start()
    for _ in range(500):  # bound when serve_forever has set the port
        if server.port:
            break
        time.sleep(0.01)
    assert Client(server).infer({"x": 2})["echo"] == {"x": 2}
    server.close()
    thread.join(10)
    assert not thread.is_alive()


def test_a_port_in_use_is_an_os_error(server: PolicyServer) -> None:
    with pytest.raises(OSError):
        PolicyServer(echo, port=server.port).start()


@pytest.mark.parametrize(
    ("kwargs", "says"),
    [
        ({"policy": "not callable"}, "policy: expected a callable"),
        ({"port": -1}, "port: expected a TCP port in 0..65535"),
        ({"port": 65536}, "port: expected a TCP port"),
        ({"port": True}, "port: expected a TCP port"),
        ({"port": "8000"}, "port: expected a TCP port"),
        ({"host": ""}, "host: expected an address"),
        ({"metadata": [1, 2]}, "metadata: expected a dict"),
        ({"metadata": {"f": object()}}, "metadata: expected msgpack-able values"),
    ],
)
def test_bad_arguments_are_clear_errors(kwargs: dict, says: str) -> None:
    args: dict[str, Any] = {"policy": echo, "port": 0, **kwargs}
    with pytest.raises(ValueError, match=says):
        PolicyServer(**args)


def test_without_msgpack_the_error_says_how_to_install_it(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setitem(sys.modules, "msgpack", None)
    hint = r'needs msgpack: pip install "panda-py-pure\[learning\]"'
    with pytest.raises(ImportError, match=hint):
        PolicyServer(echo, port=0)
