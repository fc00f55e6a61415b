"""Seeing the simulated robot: a video of a run drawn offscreen (``record=``, ``panda-sim
--record``) and MuJoCo's viewer (``viewer=True``, ``panda-sim --viewer``) under Xvfb.

The video tests need the ``video`` extra (imageio-ffmpeg) and EGL; the viewer's need Xvfb
and Pillow (screenshots). Where one is missing they skip, except in CI (``CI=true``),
where the README's command installs them (``.ci/ensure-display``) and a gap is a failure.
"""

from __future__ import annotations

import math
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
from cli_support import connect_when_serving

from panda_py.robots import START_POSE
from panda_py.sim import Simulator, SimulatorError, free_loopback_host
from panda_py.sim.probe import RawClient, follow_joint_positions

FPS = 30.0
MOVE = np.array([0.6, 0, 0, 0, 0, 0, 0])  # [rad] joint 1 turns the whole arm


def _missing(reason: str) -> None:
    if os.environ.get("CI", "").lower() == "true":
        pytest.fail(f"{reason} (CI must run the display tests: see .ci/ensure-display)")
    pytest.skip(reason)


def _frames(path: Path) -> list[np.ndarray]:
    import imageio_ffmpeg

    reader = imageio_ffmpeg.read_frames(str(path))
    meta = next(reader)
    w, h = meta["size"]
    return [np.frombuffer(f, np.uint8).reshape(h, w, 3) for f in reader]


def _arm_pixels(image: np.ndarray) -> np.ndarray:
    """Where the arm's light grey is (the links are 0.95 grey; the table is brown, the
    cube red, the sky black)."""
    rgb = image.astype(int)
    return (rgb.min(axis=2) > 150) & (rgb.max(axis=2) - rgb.min(axis=2) < 40)


def _grey(image: np.ndarray) -> np.ndarray:
    rgb = image.astype(int)
    return (rgb.max(axis=2) > 50) & (rgb.max(axis=2) - rgb.min(axis=2) < 40)


@pytest.fixture
def video_tools() -> None:
    try:
        import imageio_ffmpeg  # noqa: F401
    except ImportError:
        _missing('imageio-ffmpeg is not installed (pip install -e ".[video]")')


@pytest.mark.timeout(60)
def test_record_a_lockstep_run_while_the_arm_moves(tmp_path: Path, video_tools: None) -> None:
    path = tmp_path / "run.mp4"
    q0 = np.array(START_POSE)
    with Simulator(free_loopback_host(), "fr3", lockstep=True, record=path) as sim:
        client = RawClient(sim.host, 10)
        status, _ = follow_joint_positions(
            client, lambda t: q0 + MOVE * math.sin(math.pi * t / 2) ** 2, 1.0
        )
        client.close()
        t_end = sim.state()["time"]  # [s] simulated
        wall = time.monotonic()
    wall = time.monotonic() - wall  # idle ticks go on (on the clock) until the stop
    assert str(status) == "MoveStatus.SUCCESS"
    report = sim.recording
    assert report is not None and report["error"] is None and report["dropped"] == 0
    frames = _frames(path)
    # One frame per 1/30 s of simulated time from the first tick (frames.FrameTaps).
    assert math.floor(t_end * FPS) + 1 <= len(frames) == report["frames"]
    assert len(frames) <= math.floor((t_end + wall + 0.05) * FPS) + 1
    first, last = frames[0], frames[-1]
    assert first.shape == (480, 640, 3)
    arm = _arm_pixels(first)
    assert arm.sum() > 2000, "the arm is not drawn"
    rows, cols = np.nonzero(arm)
    assert 100 < cols.mean() < 540 and rows.mean() < 300  # above the table, in the middle
    # The arm turned: the first and last frames differ where it was and where it went.
    moved = np.abs(first.astype(int) - last.astype(int)).max(axis=2) > 60
    assert moved.sum() > 1000
    grey = [_grey(f) for f in (first, last)]  # the arm, lit or shaded
    assert (moved & (grey[0] | grey[1])).sum() > 0.8 * moved.sum()


@pytest.mark.timeout(60)
@pytest.mark.parametrize("how", ["sigterm", "ctrl-c"])
def test_panda_sim_record_finishes_the_video_when_stopped(
    tmp_path: Path, video_tools: None, how: str
) -> None:
    path = tmp_path / "cli.mp4"
    host = free_loopback_host()
    cmd = [sys.executable, "-m", "panda_py.sim.cli", "--host", host, "--lockstep",
           "--no-desk", "--record", str(path)]  # fmt: skip
    # A session of its own: Ctrl-C in a terminal signals the whole process group.
    proc = subprocess.Popen(cmd, stderr=subprocess.PIPE, text=True, start_new_session=True)
    try:
        client = connect_when_serving(proc, host, 5)
        start = int(client.state()["message_id"])  # one per tick; idle ticks run on the clock
        client.wait_state(lambda s: s["message_id"] > start + 250)
        client.close()
    finally:
        if how == "sigterm":
            proc.send_signal(signal.SIGTERM)
        else:
            os.killpg(proc.pid, signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    assert proc.returncode == 0, err
    assert "recorded" in err
    frames = _frames(path)
    assert len(frames) >= 7 and _arm_pixels(frames[-1]).sum() > 2000


def test_record_rejects_bad_input(tmp_path: Path) -> None:
    with pytest.raises(ValueError, match=r"record: expected a file name ending in \.mp4"):
        Simulator(record=tmp_path / "run.avi")
    with pytest.raises(ValueError, match=r"record: the directory .* does not exist"):
        Simulator(record=tmp_path / "nowhere" / "run.mp4")
    with pytest.raises(ValueError, match=r"record_fps: expected 1\.\.120"):
        Simulator(record=tmp_path / "run.mp4", record_fps=0)


# -- the viewer ---------------------------------------------------------------------------


def _no_display_env() -> dict[str, str]:
    return {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY")}


@pytest.mark.timeout(30)
def test_viewer_without_a_display_fails_in_one_line_naming_the_fix(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    with pytest.raises(SimulatorError, match="xvfb-run") as info:
        Simulator(free_loopback_host(), lockstep=True, viewer=True).start()
    assert "\n" not in str(info.value) and "no display" in str(info.value)
    proc = subprocess.run(
        [sys.executable, "-m", "panda_py.sim.cli", "--host", free_loopback_host(), "--viewer"],
        capture_output=True, text=True, timeout=30, env=_no_display_env(),
    )  # fmt: skip
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("panda-sim: viewer: no display"), proc.stderr
    assert "xvfb-run" in lines[0] and "--record" in lines[0]


@pytest.fixture
def xvfb() -> Iterator[str]:
    """A virtual X display (``Xvfb``) of its own; its name (``:N``)."""
    if shutil.which("Xvfb") is None:
        _missing("no Xvfb (apt-get install xvfb)")
    try:
        from PIL import ImageGrab
    except ImportError:
        _missing("no Pillow for screenshots (pip install pillow)")
    number = next(
        n for n in range(100 + os.getpid() % 400, 1000)
        if not os.path.exists(f"/tmp/.X{n}-lock") and not os.path.exists(f"/tmp/.X11-unix/X{n}")
    )  # fmt: skip
    display = f":{number}"
    proc = subprocess.Popen(
        ["Xvfb", display, "-screen", "0", "1024x768x24", "-nolisten", "tcp"],
        stderr=subprocess.DEVNULL,
    )
    try:
        deadline = time.monotonic() + 10
        while True:  # until it accepts connections
            try:
                ImageGrab.grab(xdisplay=display)
                break
            except OSError:
                if proc.poll() is not None or time.monotonic() > deadline:
                    _missing(f"Xvfb did not start on {display} (exit {proc.poll()})")
                time.sleep(0.05)
        yield display
    finally:
        proc.terminate()
        proc.wait(10)


def _screenshot(display: str) -> np.ndarray:
    from PIL import ImageGrab

    return np.asarray(ImageGrab.grab(xdisplay=display).convert("RGB"))


def _wait_screen(display: str, check, timeout: float = 20.0) -> np.ndarray:  # type: ignore[no-untyped-def]
    deadline = time.monotonic() + timeout
    while True:
        shot = _screenshot(display)
        if check(shot) or time.monotonic() > deadline:
            return shot
        time.sleep(0.05)


@pytest.mark.timeout(60)
def test_viewer_opens_under_xvfb_and_follows_the_arm(
    xvfb: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("DISPLAY", xvfb)
    with Simulator(free_loopback_host(), lockstep=True, viewer=True) as sim:
        before = _wait_screen(xvfb, lambda s: _arm_pixels(s).sum() > 2000)
        assert _arm_pixels(before).sum() > 2000, "the viewer does not show the arm"
        q = np.array(START_POSE) + np.array([0.8, 0.3, 0, 0.3, 0, 0, 0])
        sim.set_joint_positions(q)  # the viewer syncs to the new pose
        after = _wait_screen(xvfb, lambda s: (_arm_pixels(s) != _arm_pixels(before)).sum() > 1000)
    changed = _arm_pixels(after) != _arm_pixels(before)
    assert changed.sum() > 1000, "the viewer did not follow the arm"
    assert _arm_pixels(after).sum() > 2000


@pytest.mark.timeout(60)
def test_record_without_offscreen_opengl_fails_in_one_line_naming_the_fix(
    tmp_path: Path, video_tools: None, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("MUJOCO_GL", "no-such-backend")  # the recorder's process inherits it
    with pytest.raises(SimulatorError, match="offscreen rendering failed") as info:
        Simulator(free_loopback_host(), lockstep=True, record=tmp_path / "run.mp4").start()
    message = str(info.value)
    assert "\n" not in message and "libegl1" in message and "no-such-backend" in message
    assert not (tmp_path / "run.mp4").exists()
