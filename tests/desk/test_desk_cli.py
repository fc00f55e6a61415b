"""The console scripts against a simulated FER's Desk (called through their main(argv))."""

from __future__ import annotations

import io
from pathlib import Path

import pytest

from panda_py import cli
from panda_py.sim import Simulator

pytestmark = pytest.mark.timeout(120)
PASSWORD = "franka123"


@pytest.fixture
def env(fer: Simulator, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> list[str]:
    assert fer.desk is not None
    fer.desk.power_cycle()
    monkeypatch.setenv("PANDA_PY_DESK_DIR", str(tmp_path / "store"))
    monkeypatch.setenv("PANDA_PY_PASSWORD", PASSWORD)
    return [fer.desk.hostname, "franka"]


def _state(sim: Simulator) -> tuple[str, bool, object]:
    assert sim.desk is not None
    s = sim.desk.status()
    return s["safety"]["brakeState"][0], s["fci"]["active"], s["controlToken"]["activeToken"]


def test_unlock_lock_take_release_reboot(
    fer: Simulator, env: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    assert cli.unlock(env) == 0
    assert _state(fer)[:2] == ("Unlocked", True)
    assert cli.lock([*env, "--platform", "panda"]) == 0
    assert _state(fer)[:2] == ("Locked", False)
    assert cli.take_control(env) == 0
    assert cli.release_control(env) == 0
    assert _state(fer)[2] is None
    assert cli.release_control(env) == 0  # takes (free) and releases: as panda-py
    assert cli.take_control(env) == 0
    assert cli.reboot(env) == 0
    out = "".join(capsys.readouterr())
    assert PASSWORD not in out


def test_a_second_user_is_refused_without_force(
    fer: Simulator, env: list[str], tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    assert cli.take_control(env) == 0
    monkeypatch.setenv("PANDA_PY_DESK_DIR", str(tmp_path / "other"))
    assert cli.unlock(env) == 1
    assert cli.take_control(env) == 1
    assert _state(fer)[0] == "Locked"


def test_password_sources(
    fer: Simulator,
    env: list[str],
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    monkeypatch.delenv("PANDA_PY_PASSWORD")
    monkeypatch.setattr("sys.stdin", io.StringIO(""))  # not a terminal: no prompt
    assert cli.unlock(env) == 2
    assert "PANDA_PY_PASSWORD" in capsys.readouterr().err
    prompted: list[str] = []
    monkeypatch.setattr("sys.stdin", type("Tty", (io.StringIO,), {"isatty": lambda self: True})())
    monkeypatch.setattr(cli.getpass, "getpass", lambda prompt: prompted.append(prompt) or PASSWORD)
    assert cli.unlock(env) == 0
    assert prompted == [f"Desk password for franka@{env[0]}: "]
    assert cli.lock([*env, PASSWORD]) == 0  # still accepted as an argument, with a warning
    err = capsys.readouterr().err
    assert "visible" in err and PASSWORD not in err
    assert cli.lock([*env, "wrong"]) == 1
    assert "401" in capsys.readouterr().err
