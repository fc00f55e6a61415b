"""The console scripts against misbehaving Desks and bad arguments: one line on stderr
and a failing exit status, never a traceback (issue 46)."""

from __future__ import annotations

from pathlib import Path

import pytest
from fault_servers import FaultServer, Handler, answer, drip, echo, huge

from panda_py import cli

pytestmark = pytest.mark.timeout(60)
PASSWORD = "pa55-w0rd-x"
V1 = {"/api/system": answer(200, b'{"version": "5.8.0"}')}
LEGACY = {"/api/system": answer(404, b"File not found", "text/plain")}

DESKS: dict[str, Handler | dict[str, Handler | bytes]] = {
    "dripping": drip(answer(200, b"{}" + b" " * 200)),
    "huge": huge(200 * 2**20, declared=False),
    "echoing": echo(400),
    "not JSON": {**V1, "/api/system/control-token": answer(200, b"<html>\n<p>no</p>")},
    "wrong shape": {
        **V1,
        "/api/system/control-token": answer(200, b"{}"),
        "/api/system/control-token:take": answer(200, b"[]"),
    },
    "binary session": {**LEGACY, "/admin/api/login": answer(200, b"\x00\xff\n", "text/plain")},
    "garbage": b"\x16\x03\x01 not HTTP at all\r\n\r\n",
}


@pytest.fixture
def env(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("PANDA_PY_DESK_DIR", str(tmp_path / "store"))
    monkeypatch.setenv("PANDA_PY_PASSWORD", PASSWORD)


def _run(argv: list[str], capsys: pytest.CaptureFixture[str]) -> tuple[int, list[str]]:
    try:
        status = cli.unlock(argv)
    except SystemExit as exc:  # argparse's way out
        status = int(exc.code or 0)
    return status, capsys.readouterr().err.splitlines()


@pytest.mark.parametrize("handlers", DESKS.values(), ids=DESKS.keys())
def test_one_line_whatever_the_desk_answers(
    handlers: Handler | dict[str, Handler | bytes],
    tmp_path: Path,
    env: None,
    capsys: pytest.CaptureFixture[str],
) -> None:
    with FaultServer(handlers, tmp_path / "cert") as server:
        status, err = _run([server.hostname, "franka", "--timeout", "2"], capsys)
    assert status == 1
    assert len(err) == 1 and err[0].startswith("panda-unlock: "), err
    assert PASSWORD not in err[0]


@pytest.mark.parametrize("timeout", ["inf", "nan", "0", "-3", "1e300", "soon"])
def test_a_bad_timeout_is_one_clear_line(
    timeout: str, tmp_path: Path, env: None, capsys: pytest.CaptureFixture[str]
) -> None:
    with FaultServer(V1, tmp_path / "cert") as server:
        status, err = _run([server.hostname, "franka", "--timeout", timeout], capsys)
    assert status == 2
    assert len(err) == 1, err
    assert "--timeout" in err[0] and timeout in err[0] and "[s]" in err[0]
