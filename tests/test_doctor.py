"""``panda-py-doctor`` against the simulator, a host with nothing listening, a robot in a
reflex, and this machine without realtime rights (a subprocess stripped of CAP_SYS_NICE
and the rtprio limit)."""

from __future__ import annotations

import json
import shutil
import subprocess
import sys

import pytest

from panda_py import doctor
from panda_py.doctor import Status
from panda_py.sim import Simulator, free_loopback_host

pytestmark = pytest.mark.timeout(120)


def _run(*args: str, prefix: tuple[str, ...] = ()) -> subprocess.CompletedProcess[str]:
    cmd = [*prefix, sys.executable, "-m", "panda_py.doctor", "--jitter-seconds", "0.2", *args]
    return subprocess.run(cmd, capture_output=True, text=True, timeout=100)


def _by_name(checks: list[dict]) -> dict[str, dict]:
    return {c["name"]: c for c in checks}


@pytest.mark.exclusive  # the realtime stream's loss is judged on the wall clock
def test_a_simulated_robot_passes_the_robot_checks() -> None:
    # realtime, as a robot: on this VM a stall of a few ms now and then drops states, and
    # in some seconds more than the 5 % the stream check fails at (44-51 of 1000 seen; a
    # robot's cable would be at fault): one of three runs must pass it
    streams = []
    with Simulator(free_loopback_host()) as sim:
        for _ in range(3):
            proc = _run("--host", sim.host, "--json")
            checks = _by_name(json.loads(proc.stdout))
            streams.append(checks["state stream"])
            if checks["state stream"]["status"] in ("ok", "warn"):
                break
    assert checks["state stream"]["status"] in ("ok", "warn"), streams
    assert checks["FCI connection"]["status"] == "ok"
    assert "protocol v5 (fer)" in checks["FCI connection"]["found"]
    assert checks["robot mode"]["status"] == "ok"
    assert checks["gripper"]["status"] == "ok"
    assert checks["Desk"]["status"] == "warn"  # no Desk on this simulator
    failed = [c for c in checks.values() if c["status"] == "fail"]
    assert proc.returncode == (1 if failed else 0)


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
