"""Progress of long one-time work (panda_py.progress): a bar where someone watches (a
terminal, or PANDA_PY_PROGRESS=1) once a step runs long, nothing otherwise; and the places
that compile or build draw it."""

from __future__ import annotations

import io
import os
import subprocess
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path

import pytest

from panda_py import progress
from panda_py.robots import clib

pytestmark = pytest.mark.timeout(120)

SRC = Path(__file__).resolve().parents[1] / "src"  # this checkout's panda_py


class Terminal(io.StringIO):
    def isatty(self) -> bool:
        return True


@pytest.fixture(autouse=True)
def _no_setting(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv(progress.ENV, raising=False)


def _ticker_threads() -> list[threading.Thread]:
    return [t for t in threading.enumerate() if t.name == "panda_py progress"]


def _until(condition: Callable[[], bool], timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while not condition():
        assert time.monotonic() < deadline, "not within the time limit"
        time.sleep(0.01)


def test_a_long_step_on_a_terminal_draws_the_bar_until_the_work_ends() -> None:
    out = Terminal()
    with progress.work("compiling two kernels", total=2, delay=0.05, file=out) as work:
        work.advance()
        _until(lambda: out.getvalue() != "")  # the second step runs long: drawn meanwhile
        assert "compiling two kernels" in out.getvalue() and "1/2" in out.getvalue()
        work.advance()
    text = out.getvalue()
    assert "2/2" in text and "100%" in text
    assert text.endswith("\n")  # the bar is left complete on its own line
    assert not _ticker_threads()  # nothing keeps running after the work


def test_work_that_finishes_within_the_delay_shows_nothing() -> None:
    out = Terminal()
    with progress.work("loading from the cache", total=3, delay=60.0, file=out) as work:
        for _ in range(3):
            work.advance()
    assert out.getvalue() == ""
    assert not _ticker_threads()


def test_nothing_is_drawn_or_started_where_nobody_watches() -> None:
    out = io.StringIO()  # not a terminal (a pipe, a log file)
    with progress.work("compiling", total=1, delay=0.0, file=out) as work:
        assert not _ticker_threads()
        work.advance()
    assert out.getvalue() == ""
    assert not progress.enabled(out) and progress.enabled(Terminal())


def test_the_setting_turns_it_on_off_the_terminal_and_off_on_it(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv(progress.ENV, "1")
    out = io.StringIO()
    with progress.work("compiling", total=1, delay=0.0, file=out) as work:
        work.advance()
    assert "compiling" in out.getvalue() and "1/1" in out.getvalue()

    monkeypatch.setenv(progress.ENV, "0")
    tty = Terminal()
    with progress.work("compiling", total=1, delay=0.0, file=tty) as work:
        work.advance()
    assert tty.getvalue() == ""


def test_an_unknown_setting_says_so_and_falls_back_to_the_terminal(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.setenv(progress.ENV, "yes")
    with pytest.warns(UserWarning, match=r"PANDA_PY_PROGRESS='yes': expected 1 .*0 .*unset"):
        assert progress.enabled(Terminal())
    with pytest.warns(UserWarning):
        assert not progress.enabled(io.StringIO())


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"total": 0}, r"total: expected a whole number of steps >= 1, got 0"),
        ({"total": 2.5}, r"total: .* got 2.5"),
        ({"delay": -1.0}, r"delay: expected seconds >= 0, got -1.0"),
        ({"delay": float("nan")}, r"delay: .* got nan"),
    ],
)
def test_bad_arguments_are_clear_errors(kwargs: dict, message: str) -> None:
    with pytest.raises(ValueError, match=message), progress.work("x", **kwargs):
        pass


def test_an_error_in_the_work_ends_the_bar_and_propagates() -> None:
    out = Terminal()
    with pytest.raises(RuntimeError, match="the compiler failed"):
        with progress.work("compiling", total=2, delay=0.0, file=out):
            raise RuntimeError("the compiler failed")
    assert "0/2" in out.getvalue()
    assert not _ticker_threads()


def test_the_model_library_build_shows_progress_and_its_cache_does_not(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capfd: pytest.CaptureFixture[str]
) -> None:
    if clib.host_platform() is None or not sys.platform.startswith("linux"):
        pytest.skip("the model library is built for Linux hosts only")
    monkeypatch.setenv("PANDA_PY_CACHE", str(tmp_path))
    monkeypatch.setenv(progress.ENV, "1")
    monkeypatch.setattr(progress, "DELAY", 0.0)  # a build here takes a fraction of a second
    monkeypatch.setattr(clib, "_memory", {})
    arch, system = clib.host_platform()
    try:
        clib.model_library("fr3", architecture=arch, system=system)
    except clib.ModelLibraryUnavailable as exc:
        pytest.skip(f"no model library here: {exc.reason}")
    err = capfd.readouterr().err
    assert "building the FR3 model library" in err and "1/1" in err

    monkeypatch.setattr(clib, "_memory", {})  # a new process: read from the disk cache
    clib.model_library("fr3", architecture=arch, system=system)
    assert capfd.readouterr().err == ""


def test_the_compiling_places_draw_their_bars() -> None:
    """The kinematics, the control laws and the model terms, each compiled (or loaded)
    under a bar; with no delay so that a warm cache draws it too."""
    code = (
        "from panda_py import progress\n"
        "progress.DELAY = 0.0\n"
        "from panda_py import dynamics, kinematics\n"
        "from panda_py.controllers import laws\n"
        "assert kinematics.warmup()\n"
        "laws.warmup()\n"
        "dynamics.LoadedArm('fer')\n"
    )
    env = {**os.environ, progress.ENV: "1", "PYTHONPATH": str(SRC)}
    env.pop("PANDA_PY_NO_JIT", None)
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=env, timeout=110)  # fmt: skip
    assert done.returncode == 0, done.stderr
    lines = done.stderr.replace("\r", "\n").splitlines()
    for what, total in (("the kinematics", 15), ("the control laws", 7), ("the dynamics", 3)):
        done_line = f"{total}/{total}"
        assert any(f"compiling {what}" in line and done_line in line for line in lines), what
    assert done.stdout == ""  # bars go to stderr only
