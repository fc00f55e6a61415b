"""``print(state)`` prints every field as libfranka's ``operator<<`` does (and so
panda-python's ``print(panda.get_state())``): a JSON object in libfranka's field order."""

from __future__ import annotations

import json

import numpy as np
import pytest

from panda_py import libfranka as lf
from panda_py.libfranka.state import PRINTED_FIELDS

pytestmark = pytest.mark.timeout(60)

TAIL = ["current_errors", "last_motion_errors", "control_command_success_rate", "robot_mode",
        "time"]  # fmt: skip


@pytest.mark.parametrize("version", [5, 10])
def test_every_field_in_libfrankas_order_and_format(sim_for_version, version: int) -> None:
    with lf.Robot(sim_for_version(version).host, version=version) as robot:
        state = robot.read_once()
    text = str(state)
    printed = json.loads(text)  # libfranka's format is JSON
    assert list(printed) == [*PRINTED_FIELDS, *TAIL]
    np.testing.assert_allclose(printed["q"], state.q, rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(
        printed["O_T_EE"], np.asarray(state.O_T_EE).ravel(order="F"), rtol=1e-5, atol=1e-6
    )
    assert printed["robot_mode"] == "Idle"
    assert printed["current_errors"] == [] and printed["time"] == state.time.to_msec()
    assert '"m_ee": 0.73,' in text  # C++'s 6 significant digits, no trailing zeros
    assert repr(state).startswith("RobotState(")  # repr stays short


def test_errors_print_by_name(panda_sim) -> None:
    panda_sim.inject_reflex("joint_reflex")
    with lf.Robot(panda_sim.host) as robot:
        state = robot.read_once()
        robot.automatic_error_recovery()
    printed = json.loads(str(state))
    assert printed["current_errors"] == ["joint_reflex"]
    assert printed["robot_mode"] == "Reflex"
