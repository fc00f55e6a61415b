"""Pinning the control loop and the simulator to CPUs (``Panda(host, cpus=...)``,
``Simulator(cpus=...)``, ``panda-sim --cpus``): each process runs where it was asked to,
the caller's threads keep their CPUs, and a bad set is refused before anything starts."""

from __future__ import annotations

import os

import pytest

import panda_py
from panda_py import checks
from panda_py.sim import Simulator
from panda_py.sim.cli import main as sim_cli

pytestmark = [
    pytest.mark.timeout(60),
    pytest.mark.skipif(not hasattr(os, "sched_setaffinity"), reason="CPU affinity is Linux's"),
]

MINE = os.sched_getaffinity(0) if hasattr(os, "sched_getaffinity") else {0}
CORE = max(MINE)
BAD = [[], [max(MINE) + 64], [-1], "1", 1, [True], [0.5], [None]]
EXPECTED = r"cpus: expected None or a non-empty set of CPU numbers from \["


@pytest.mark.panda_sim(cpus=[CORE])
def test_the_loop_and_the_simulator_run_on_the_cpus_asked_for(sim: Simulator) -> None:
    with panda_py.Panda(sim.host, cpus={CORE}) as panda:
        assert os.sched_getaffinity(sim._process.pid) == {CORE}
        assert os.sched_getaffinity(panda._proc.proc.pid) == {CORE}
        assert panda.move_to_joint_position(panda.q + 0.05) is True
    assert os.sched_getaffinity(0) == MINE  # the caller's own threads keep theirs


def test_unpinned_they_run_where_the_caller_may(sim: Simulator) -> None:
    with panda_py.Panda(sim.host) as panda:
        assert os.sched_getaffinity(sim._process.pid) == MINE
        assert os.sched_getaffinity(panda._proc.proc.pid) == MINE


@pytest.mark.parametrize("bad", BAD, ids=repr)
def test_a_bad_set_is_refused_before_anything_starts(bad: object) -> None:
    # refused by name before a control process starts or a robot is looked for (no robot
    # listens on this address: anything else would fail otherwise)
    with pytest.raises(ValueError, match=EXPECTED):
        panda_py.Panda("127.0.0.1", cpus=bad)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=EXPECTED):
        Simulator(cpus=bad)  # type: ignore[arg-type]


def test_the_command_line_refuses_a_bad_set(capsys: pytest.CaptureFixture[str]) -> None:
    assert sim_cli(["--cpus", str(CORE + 64)]) == 2
    assert f"got ({CORE + 64},)" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        sim_cli(["--cpus", "one"])
    assert exit_.value.code == 2
    assert "expected CPU numbers separated by commas" in capsys.readouterr().err


def test_a_kernel_cpu_list_is_read_as_the_kernel_writes_it() -> None:
    assert checks.cpu_set("0-3,5\n") == {0, 1, 2, 3, 5}
    assert checks.cpu_set("7") == {7} and checks.cpu_set("\n") == set()
    for bad in ("3-1", "a", "1-2-3", "-1"):
        with pytest.raises(ValueError):
            checks.cpu_set(bad)
    with pytest.raises(ValueError, match=r"expected a CPU list such as 0-3,5, got '1-x'"):
        checks.cpu_set("1-x")
    assert set(checks.online_cpus()) >= MINE


def test_the_check_leaves_the_calling_thread_where_it_was() -> None:
    # (it tries the set on the calling thread, then switches back)
    assert checks.cpus("cpus", [CORE]) == (CORE,)
    assert os.sched_getaffinity(0) == MINE
    with pytest.raises(ValueError, match=EXPECTED):
        checks.cpus("cpus", [CORE + 64])
    assert os.sched_getaffinity(0) == MINE
