"""``lockstep_max_speed``: a lockstep robot whose time never runs ahead of the wall clock
by more than the factor, and which still waits for every command."""

from __future__ import annotations

import pytest
from test_sim_protocol import run_joint_motion

from panda_py.fci import MoveStatus
from panda_py.sim import Simulator, free_loopback_host
from panda_py.sim.cli import main as sim_cli
from panda_py.sim.probe import RawClient

pytestmark = pytest.mark.timeout(60)


def drive(c: RawClient, ticks: int, answer_after: float = 0.0) -> tuple[list[tuple], MoveStatus]:
    """A joint-position motion of ``ticks`` commands (joint 1 eases by 0.05 rad over 300
    ms, less over fewer: the same acceleration), each sent ``answer_after`` seconds after
    its state arrived; returns (wall time, robot ms) at each state, and the motion's end."""
    arrivals: list[float] = []
    states, final = run_joint_motion(
        c, 0.05 * (ticks / 300) ** 2, ticks, answer_after=answer_after, arrivals=arrivals
    )
    return [(t, int(s["message_id"])) for t, s in zip(arrivals, states, strict=True)], final


def test_its_time_runs_at_most_the_factor_faster_than_the_wall_clock() -> None:
    """At 0.25x (unpaced, this robot and client run 1-5x real time here), over 300 ticks:
    at every state the robot's time since the first is at most 0.25 of the wall's, within
    a tick and a half for the states' arrival times (measured: under 0.1 ms); no command
    is lost."""
    speed = 0.25
    with Simulator(free_loopback_host(), "fr3", lockstep=True, lockstep_max_speed=speed) as sim:
        c = RawClient(sim.host, 10)
        try:
            seen, final = drive(c, 300)
        finally:
            c.close()
        stats = sim.stats()
    assert final == MoveStatus.SUCCESS
    assert stats["commands_lost"] == 0
    t0, ms0 = seen[0]
    ahead = [(ms - ms0) - 1e3 * speed * (t - t0) for t, ms in seen]
    assert max(ahead) <= 1.5, f"{max(ahead):.1f} ms of robot time ahead of the pace"
    # and it does run: the wall clock's pace, not a stall (a loaded machine may lag it)
    t1, ms1 = seen[-1]
    assert ms1 - ms0 >= 0.3 * 1e3 * speed * (t1 - t0)


def test_it_still_waits_for_a_client_slower_than_the_pace() -> None:
    """At 1x, a client answering each state 3 ms late: the robot waits for every answer
    (lockstep), so its time falls behind the wall's and nothing is lost."""
    with Simulator(free_loopback_host(), "fr3", lockstep=True, lockstep_max_speed=1.0) as sim:
        c = RawClient(sim.host, 10)
        try:
            seen, final = drive(c, 60, answer_after=0.003)
        finally:
            c.close()
        stats = sim.stats()
    assert final == MoveStatus.SUCCESS
    assert stats["commands_lost"] == 0
    (t0, ms0), (t1, ms1) = seen[0], seen[-1]
    assert ms1 - ms0 == len(seen) - 1  # one tick per answer
    assert 1e3 * (t1 - t0) > 2.5 * (ms1 - ms0)  # the wall ran on while the robot waited


@pytest.mark.parametrize("bad", [0, -1.0, float("nan"), float("inf"), True, "2"])
def test_a_bad_factor_is_refused(bad: object) -> None:
    with pytest.raises(ValueError, match=r"lockstep_max_speed: expected None or a speed factor"):
        Simulator(lockstep=True, lockstep_max_speed=bad)  # type: ignore[arg-type]


def test_a_factor_without_lockstep_is_refused(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(ValueError, match=r"lockstep_max_speed: applies to lockstep only"):
        Simulator(lockstep_max_speed=1.0)
    assert sim_cli(["--lockstep-max-speed", "1"]) == 2
    assert "lockstep_max_speed: applies to lockstep only" in capsys.readouterr().err
    assert sim_cli(["--lockstep", "--lockstep-max-speed", "0"]) == 2
    assert "expected None or a speed factor in (0, 1e6), got 0.0" in capsys.readouterr().err
