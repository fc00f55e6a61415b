"""``panda-py-doctor`` against the simulator, a host with nothing listening, a robot in a
reflex, and this machine without realtime rights (a subprocess stripped of CAP_SYS_NICE
and the rtprio limit)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys
from types import SimpleNamespace

import numpy as np
import pytest

from panda_py import doctor
from panda_py.doctor import Status
from panda_py.libfranka import RobotMode
from panda_py.sim import Simulator, free_loopback_host

pytestmark = pytest.mark.timeout(120)


def _run(*args: str, prefix: tuple[str, ...] = ()) -> subprocess.CompletedProcess[str]:
    cmd = [*prefix, sys.executable, "-m", "panda_py.doctor", "--jitter-seconds", "0.2", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=100)


def _by_name(checks: list[dict]) -> dict[str, dict]:
    return {c["name"]: c for c in checks}


@pytest.mark.exclusive  # the realtime stream's loss is judged on the wall clock
def test_a_simulated_robot_passes_the_robot_checks() -> None:
    # realtime, as a robot. States this process passed over while it was late (the VM's
    # stalls: 353-559 of 1000 in a CI run once counted as missing, three runs in a row)
    # are its own, not the link's. What can still be missing is what the simulator never
    # sent: it re-synchronises its clock when the machine keeps it more than 100 ms from
    # its schedule. So one of three runs must pass the stream check, or else, in each run
    # it failed, the simulator itself must have been kept from its schedule, where failing
    # is the check's right answer; the other checks pass either way
    streams = []
    with Simulator(free_loopback_host()) as sim:
        for _ in range(3):
            sim.reset_stats()
            proc = _run("--host", sim.host, "--json")
            stats = sim.stats()
            checks = _by_name(json.loads(proc.stdout))
            stream = checks["state stream"]
            if stream["status"] in ("ok", "warn"):
                break
            late = stats["late_ticks"] + 100 * stats["resyncs"]  # (a resync: 100 ms behind)
            streams.append((stream, stats["late_ticks"], stats["resyncs"], stats["ticks"]))
            assert late > 0.05 * stats["ticks"], (
                f"the stream failed while the simulator kept its schedule: {streams}"
            )
    assert checks["FCI connection"]["status"] == "ok"
    assert "protocol v5 (fer)" in checks["FCI connection"]["found"]
    assert checks["robot mode"]["status"] == "ok"
    assert checks["gripper"]["status"] == "ok"
    assert checks["Desk"]["status"] == "warn"  # no Desk on this simulator
    failed = [c for c in checks.values() if c["status"] == "fail"]
    assert proc.returncode == (1 if failed else 0)


class _Stream:
    """A robot for ``doctor._connected``: its states' times (ms) and the states its reads
    passed over, counted as :attr:`panda_py.libfranka.Robot.skipped_states` counts them."""

    def __init__(self, times: list[int], passed_over: int) -> None:
        self.times, self.passed_over, self.skipped_states = times, passed_over, 0

    def server_version(self) -> int:
        return 5

    def read(self, callback) -> None:  # type: ignore[no-untyped-def]
        self.skipped_states += 7  # queued before the read began: not in its gaps
        for i, t in enumerate(self.times):
            if i and t - self.times[i - 1] > 1:  # after the gap: counted as a read counts
                self.skipped_states += self.passed_over
            state = SimpleNamespace(time=SimpleNamespace(to_msec=lambda t=t: t))
            if not callback(state):
                break

    def read_once(self) -> object:
        return SimpleNamespace(robot_mode=RobotMode.kIdle, current_errors=None)


@pytest.mark.parametrize(
    ("passed_over", "status", "missing"),
    [(100, Status.WARN, 0), (0, Status.FAIL, 100), (40, Status.FAIL, 60)],
)
def test_the_stream_check_tells_states_this_process_passed_over_from_missing_ones(
    monkeypatch, passed_over, status, missing
) -> None:  # type: ignore[no-untyped-def]
    """100 gaps in the robot's clock in a second: the states the reads passed over (this
    process was late) warn and point at the timing; the rest never came (the cable, a
    switch: past 5 % a failure)."""
    clock = iter(np.arange(0.0, 10.0, 1e-3))
    monkeypatch.setattr(doctor.time, "perf_counter", lambda: float(next(clock)))
    times = [t for t in range(1, 1200) if not 500 <= t < 600]  # 100 gaps
    stream = {c.name: c for c in doctor._connected(_Stream(times, passed_over), 0.01)}[
        "state stream"
    ]
    assert stream.status is status
    assert f"{missing} missing, {passed_over} passed over" in stream.found
    assert ("cable" in stream.fix) == (status is Status.FAIL)


def test_nothing_listening_fails_the_fci_check_with_its_fix() -> None:
    proc = _run("--host", free_loopback_host(), "--json")
    checks = _by_name(json.loads(proc.stdout))
    fci = checks["FCI connection"]
    assert fci["status"] == "fail" and "activate_fci" in fci["fix"]
    assert proc.returncode == 1


def test_a_reflex_is_reported_with_the_recovery() -> None:
    with Simulator(free_loopback_host(), lockstep=True) as sim:
        sim.inject_reflex("joint_reflex")
        checks = {c.name: c for c in doctor.robot_checks(sim.host)}
    mode = checks["robot mode"]
    assert mode.status is Status.WARN
    assert "reflex" in mode.found and "joint_reflex" in mode.found
    assert "recover" in mode.fix


@pytest.mark.skipif(not (shutil.which("setpriv") and shutil.which("prlimit")), reason="no setpriv")
def test_without_realtime_rights_the_permission_fails() -> None:
    strip = ("setpriv", "--inh-caps=-sys_nice", "--bounding-set=-sys_nice",
             "prlimit", "--rtprio=0", "--")  # fmt: skip
    proc = _run("--json", prefix=strip)
    checks = _by_name(json.loads(proc.stdout))
    assert checks["realtime permission"]["status"] == "fail"
    assert "rtprio" in checks["realtime permission"]["fix"]
    assert proc.returncode == 1


def test_text_output_marks_each_item_and_bad_input_exits_2() -> None:
    proc = _run()
    assert proc.stdout.splitlines()[0][:1] in ("✓", "!", "✗", "o", "X")
    assert "realtime permission" in proc.stdout
    bad = _run("--host", "no such host!")
    assert bad.returncode == 2 and "expected an IP address or host name" in bad.stderr
    worse = _run("--jitter-seconds", "-1")
    assert worse.returncode == 2 and "--jitter-seconds" in worse.stderr


def test_isolated_cpus_are_named_with_how_to_pin_the_loop_there(tmp_path) -> None:  # type: ignore[no-untyped-def]
    isolated = tmp_path / "isolated"
    isolated.write_text("2-3\n")
    check = doctor.isolated_cpus(str(isolated))
    assert check.status == Status.OK
    assert check.found.startswith("2, 3:") and "Panda(host, cpus={3})" in check.found
    for text in ("\n", "garbage\n"):  # none isolated (or unreadable): fine, and how to
        isolated.write_text(text)
        check = doctor.isolated_cpus(str(isolated))
        assert check.status == Status.OK and check.found.startswith("none (optional: isolcpus")
    assert doctor.isolated_cpus(str(tmp_path / "absent")).found.startswith("none")
