"""Real, unmodified Desk clients in their own venvs against the simulated Desk:
panda-python 1.1.1's ``Desk`` (legacy, on a FER) and franky 2.0.0's ``Desk`` (API v1,
on an FR3) and ``DeskWebSession`` (legacy, on an FR3)."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import Any

import pytest

sys.path.append(str(Path(__file__).resolve().parents[1] / "conformance"))

from conf_support import PEER_TEST_TIMEOUT, peer_or_skip, run_peer, scenario

from panda_py.sim import Simulator

pytestmark = [pytest.mark.peer, pytest.mark.timeout(PEER_TEST_TIMEOUT)]
USER, PASSWORD = "franka", "franka123"


def _robot(sim: Simulator) -> Any:
    assert sim.desk is not None
    s = sim.desk.status()
    token = s["controlToken"]["activeToken"]
    return {
        "brakes": s["safety"]["brakeState"][0],
        "fci": s["fci"]["active"],
        "owner": None if token is None else token["ownedBy"],
    }


def _handlers(sim: Simulator) -> dict[str, Any]:
    assert sim.desk is not None
    desk = sim.desk

    def safety_error(_: Any) -> None:
        desk.inject_safety_error()

    def press(button: str) -> None:
        desk.press_pilot_button(button)

    return {"status": lambda _: _robot(sim), "safety_error": safety_error, "press": press}


def test_panda_python_desk(fer: Simulator, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    python = peer_or_skip("panda-python")
    assert fer.desk is not None
    fer.desk.power_cycle()
    monkeypatch.setenv("HOME", str(tmp_path))  # its token file: ~/.panda_py/tokens.conf
    # requests lets these override panda-py's verify=False (the robot's certificate is
    # self-signed); a machine that sets them would fail on a real robot too.
    for name in ("REQUESTS_CA_BUNDLE", "CURL_CA_BUNDLE"):
        monkeypatch.delenv(name, raising=False)
    result = run_peer(python, "pp_desk.py", [fer.desk.hostname, USER, PASSWORD], _handlers(fer))
    assert scenario(result, "construct") == {
        "has_control": True,
        "robot": {"brakes": "Locked", "fci": False, "owner": USER},
    }
    expected = {
        "unlock": ("Unlocked", False),
        "activate_fci": ("Unlocked", True),
        "deactivate_fci": ("Unlocked", False),
        "lock": ("Locked", False),
    }
    for step, (brakes, fci) in expected.items():
        assert scenario(result, step)["robot"] == {"brakes": brakes, "fci": fci, "owner": USER}
    assert scenario(result, "release_control")["robot"]["owner"] is None
    # panda-py compares its emptied token's id "" with the robot's "" (nobody): True.
    assert scenario(result, "has_control_after") == {"has_control": True}


@pytest.mark.parametrize("api", ["v1", "legacy"])
def test_franky_desk(api: str, fr3: Simulator, tmp_path: Path) -> None:
    python = peer_or_skip("franky")
    assert fr3.desk is not None
    fr3.desk.power_cycle()
    args = [fr3.desk.hostname, USER, PASSWORD, api]
    result = run_peer(python, "franky_desk.py", args, _handlers(fr3))
    take = scenario(result, "take")
    assert take["has_control"] and take["robot"]["owner"] == USER
    modes = scenario(result, "modes")
    assert modes["execution"] == "Execution"
    unlocked = scenario(result, "unlock_and_fci")
    assert unlocked["brakes"] == "Unlocked"
    assert unlocked["robot"] == {"brakes": "Unlocked", "fci": True, "owner": USER}
    if api == "v1":
        assert (unlocked["fci"], unlocked["fci_after"]) == ("Active", "Inactive")
        assert scenario(result, "self_test")["robot"]["brakes"] == "Unlocked"
        recovery = scenario(result, "recovery")
        assert recovery["pending"]["type"] == "SafetyError" and recovery["after"] is None
    else:
        assert modes["programming"] == "Programming"
    buttons = scenario(result, "buttons")  # poll_buttons over WSS, with this API's auth
    keys = ["check", "circle", "cross", "down", "left", "right", "up"]
    assert buttons["first"] == [[k, False] for k in keys]
    assert buttons["later"] == [["check", True], ["check", False]]
    done = scenario(result, "lock_and_release")
    assert done["brakes"] == "Locked" and not done["has_control"]
    assert done["robot"]["owner"] is None
