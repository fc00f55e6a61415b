"""panda-py-demo, run as a user runs it (a subprocess), judged by what it prints and
writes: the cube picked up and put back, the paper's straight and curved paths, the PNG;
and the figure itself, drawn from known paths and read back."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import matplotlib.image
import numpy as np
import pytest

from panda_py import demo

pytestmark = pytest.mark.timeout(240)

# the panda_py under test, also where another checkout is installed
SRC = Path(__file__).resolve().parents[2] / "src"  # this checkout's panda_py
ENV = {
    **{k: v for k, v in os.environ.items() if k != "PANDA_PY_PROGRESS"},
    "PYTHONUNBUFFERED": "1",
    "PYTHONPATH": os.pathsep.join([str(SRC), os.environ.get("PYTHONPATH", "")]),
}
BLUE, ORANGE = (0x1F, 0x77, 0xB4), (0xFF, 0x7F, 0x0E)  # matplotlib's tab:blue, tab:orange


def _children(pid: int) -> set[int]:
    """All live descendants of ``pid`` (from /proc)."""
    parents: dict[int, int] = {}
    for entry in Path("/proc").iterdir():
        if entry.name.isdigit():
            try:
                stat = (entry / "stat").read_text()
            except OSError:
                continue
            parents[int(entry.name)] = int(stat.rsplit(")", 1)[1].split()[1])
    found, todo = set(), [pid]
    while todo:
        p = todo.pop()
        kids = {c for c, pp in parents.items() if pp == p}
        found |= kids
        todo.extend(kids)
    return found


def number_in(pattern: str, out: str) -> float:
    match = re.search(pattern, out)
    assert match is not None, f"{pattern!r} not in:\n{out}"
    return float(match[1])


def _state(pid: int) -> str:
    """The process's state letter ("" once it is gone, "Z" a zombie)."""
    try:
        return Path(f"/proc/{pid}/stat").read_text().rsplit(")", 1)[1].split()[0]
    except OSError:
        return ""


@pytest.fixture(scope="module")
def demo_run(tmp_path_factory: pytest.TempPathFactory) -> tuple[subprocess.CompletedProcess, Path]:
    figure = tmp_path_factory.mktemp("demo") / "paths.png"
    t0 = time.monotonic()
    done = subprocess.run(
        [sys.executable, "-m", "panda_py.demo", "--figure", str(figure)],
        capture_output=True, text=True, timeout=200, env=ENV,
    )  # fmt: skip
    print(f"demo took {time.monotonic() - t0:.1f} s")
    return done, figure


def test_demo_picks_the_cube_draws_the_paths_and_writes_the_figure(demo_run) -> None:
    done, figure = demo_run
    assert done.returncode == 0, done.stdout + done.stderr
    out = done.stdout
    for step in ("1. Pick up the cube", "grasped", "2. The paper's two paths", "3. Put the cube"):
        assert step in out
    assert out.count("100%") == 13  # every motion arrived
    assert number_in(r"the cube is ([\d.]+) cm above the table", out) > 10.0  # lifted
    # held through the paper's moves (it slid out of the simulated fingers once)
    assert number_in(r"still in the hand, is ([\d.]+) cm above the table", out) > 30.0
    straight = float(re.search(r"at most ([\d.]+) mm from the straight line", out)[1])
    curve = float(re.search(r"up to ([\d.]+) mm away from it", out)[1])
    assert straight < 2.0 and curve > 10.0
    # the cube travelled with the hand and is back on the table
    cube = re.search(r"cube back at \[([-\d.]+), ([-\d.]+), ([-\d.]+)\] m", out)
    assert cube is not None and float(cube[3]) == pytest.approx(0.02, abs=5e-3)
    # put back where it was (within 2 cm)
    assert float(cube[1]) == pytest.approx(0.5, abs=0.02)
    assert float(cube[2]) == pytest.approx(0.0, abs=0.02)
    assert f"Figure: {figure.resolve()}" in out
    assert b"Matplotlib" in figure.read_bytes()[:200]  # a PNG matplotlib wrote
    image = matplotlib.image.imread(figure)
    assert image.shape[1] == demo.WIDTH * demo.DPI
    # no progress bars where nobody watches (stderr a pipe here)
    assert "panda_py: compiling" not in done.stderr and "%|" not in done.stderr


def _pixels(image: np.ndarray, colour: tuple[int, int, int]) -> tuple[np.ndarray, np.ndarray]:
    """Rows and columns of the pixels of ``colour`` (8-bit RGB) in an RGB(A) image."""
    rgb = np.round(image[..., :3] * 255)
    return np.nonzero(np.all(np.abs(rgb - colour) <= 2, axis=-1))


def test_the_figure_shows_the_straight_line_against_the_curve_in_two_views(
    tmp_path: Path,
) -> None:
    """Known paths from y = 0.25 to -0.25 m: a straight line, and a curve bulging 15 mm
    in x and 90 mm in z. The PNG, read back, has two panels, each with both paths: the
    line flat in both, the curve higher in the front view than the top view."""
    s = np.linspace(0.0, 1.0, 500)
    line = np.column_stack([np.full_like(s, 0.3), 0.25 - 0.5 * s, np.full_like(s, 0.5)])
    bulge = np.sin(np.pi * s)
    curve = np.column_stack([0.3 + 0.015 * bulge, 0.25 - 0.5 * s, 0.5 + 0.09 * bulge])
    path = tmp_path / "paths.png"
    fig = demo.write_figure(path, line, curve)

    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and b"Matplotlib" in path.read_bytes()
    image = matplotlib.image.imread(path)
    width, height = fig.canvas.get_width_height()  # [px]
    assert width == demo.WIDTH * demo.DPI
    assert image.shape[:2] == (height, width)
    assert [ax.get_title() for ax in fig.axes] == ["Top view", "Front view"]
    assert [ax.get_ylabel() for ax in fig.axes] == ["x [m], \u2191 to the robot's base", "z [m]"]
    assert fig.axes[1].get_xlabel() == "y [m]"
    assert len(fig.legends) == 1
    legend = [t.get_text() for t in fig.legends[0].get_texts()]
    assert legend[0].startswith("move_to_pose: straight, at most 0.0 mm")
    assert legend[1].startswith("move_to_joint_position: curved, at most 91.")
    heights = []
    for ax in fig.axes:
        x0, y0, x1, y1 = ax.get_window_extent().extents  # [px], origin at the bottom left
        panel = image[height - int(y1) : height - int(y0), int(x0) : int(x1)]
        assert panel.std() > 0.05  # drawn on, not blank
        rows, cols = _pixels(panel, BLUE)
        assert np.ptp(cols) > 0.8 * panel.shape[1]  # the line runs across the panel
        assert np.ptp(rows) < 6  # and stays flat: a straight line
        rows, cols = _pixels(panel, ORANGE)
        assert np.ptp(cols) > 0.8 * panel.shape[1]
        heights.append(np.ptp(rows))
        # to scale: the equal-aspect panel's pixels per metre, the same both ways
        (ux0, uy0), (ux1, uy1) = ax.transData.transform([(0.0, 0.0), (0.1, 0.1)])
        assert abs(ux1 - ux0) == pytest.approx(abs(uy1 - uy0), rel=1e-6)
    assert heights[1] > 4 * heights[0] > 20  # 90 mm up against 15 mm out


def test_the_figure_refuses_paths_that_are_not_positions(tmp_path: Path) -> None:
    good = np.zeros((10, 3))
    with pytest.raises(
        ValueError,
        match=r"joint_path: expected finite end-effector "
        r"positions of shape \(N >= 2, 3\) \[m\], got an array of shape \(10, 2\)",
    ):
        demo.write_figure(tmp_path / "f.png", good, np.zeros((10, 2)))
    with pytest.raises(ValueError, match=r"pose_path: .* shape \(2, 3\)"):
        demo.write_figure(tmp_path / "f.png", np.array([[0, 0, 0], [np.nan, 0, 0]]), good)
    assert not (tmp_path / "f.png").exists()


def test_demo_bad_host_says_so() -> None:
    done = subprocess.run(
        [sys.executable, "-m", "panda_py.demo", "--host", "127.0.0.1"],
        capture_output=True, text=True, timeout=60, env=ENV,
    )  # fmt: skip
    assert done.returncode == 1
    assert "no robot answers at 127.0.0.1" in done.stderr


def _ctrl_c_as_in_a_terminal() -> None:
    """In the demo's process before Python starts: Ctrl-C's default action. A suite run as
    a shell's background job (``pytest &``, nohup) ignores SIGINT, its children inherit
    that, and Python then installs no KeyboardInterrupt handler: the demo ran to its end
    and exited 0."""
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def test_demo_ctrl_c_leaves_no_process(tmp_path: Path) -> None:
    proc = subprocess.Popen(
        [sys.executable, "-m", "panda_py.demo", "--figure", str(tmp_path / "f.png")],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=ENV,
        preexec_fn=_ctrl_c_as_in_a_terminal,
    )  # fmt: skip
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            if "1. Pick up the cube" in line:
                break
        kids = _children(proc.pid)
        assert kids  # the simulator and the control process
        proc.send_signal(signal.SIGINT)
        _, err = proc.communicate(timeout=30)
    finally:
        proc.kill()
    assert proc.returncode == 130, err
    assert "interrupted" in err
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline and any(Path(f"/proc/{k}").exists() for k in kids):
        time.sleep(0.1)
    alive = [k for k in kids if _state(k) not in ("", "Z")]
    assert not alive
