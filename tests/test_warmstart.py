"""Children forked from the warm server behave as spawned ones would: they see the
environment and descriptors their starter gives them at their start, and a setting read
once at import that changed since the server started sends the child to spawn instead."""

from __future__ import annotations

import multiprocessing
import os
from typing import Any

import pytest

from panda_py import warmstart

pytestmark = pytest.mark.timeout(120)


def _report(fd: warmstart.InheritedFd, name: str) -> None:
    """(in the child) write the variable ``name`` as the child sees it to ``fd``"""
    os.write(fd.fd, (os.environ.get(name, "<unset>") + f"|{os.getpid()}").encode())
    os.close(fd.fd)


def _run_child(ctx: Any, name: str, target: Any = _report) -> str:
    """``name`` in the environment of a child started in ``ctx`` (which checks that the
    child had the pipe it was handed)."""
    r, w = os.pipe()
    try:
        proc = ctx.Process(
            target=warmstart.run_with_environ,
            args=(dict(os.environ), target, warmstart.InheritedFd(w), name),
            daemon=True,
        )
        warmstart.start(proc)
        os.close(w)
        w = -1
        proc.join(60)
        assert proc.exitcode == 0
        value, pid = os.read(r, 4096).decode().rsplit("|", 1)
        assert int(pid) == proc.pid
        return value
    finally:
        os.close(r)
        if w >= 0:
            os.close(w)


def test_a_forked_child_sees_the_environment_as_it_is_at_its_start(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    ctx = warmstart.context()
    if ctx.get_start_method() != "forkserver":
        pytest.skip("no fork server here")
    assert _run_child(ctx, "PANDA_PY_WARMSTART_TEST") == "<unset>"
    monkeypatch.setenv("PANDA_PY_WARMSTART_TEST", "set after the server started")
    assert warmstart.context().get_start_method() == "forkserver"  # not read at import
    assert _run_child(ctx, "PANDA_PY_WARMSTART_TEST") == "set after the server started"


@pytest.mark.parametrize("name", ["MUJOCO_GL", "PANDA_PY_NO_JIT", "NUMBA_OPT"])
def test_a_changed_import_time_setting_spawns_the_child(
    monkeypatch: pytest.MonkeyPatch, name: str
) -> None:
    warmstart.context()  # the server's settings are this environment's
    monkeypatch.setenv(name, os.environ.get(name, "") + "-changed")
    ctx = warmstart.context()
    assert ctx.get_start_method() == "spawn"
    assert _run_child(ctx, name) == os.environ[name]  # and it sees the new value
    monkeypatch.undo()  # the server's settings again: forked from it again, where it can be
    warm = "forkserver" if "forkserver" in multiprocessing.get_all_start_methods() else "spawn"
    assert warmstart.context().get_start_method() == warm


def test_a_target_named_by_module_runs_in_the_child() -> None:
    ctx = warmstart.context()
    assert _run_child(ctx, "HOME", target=f"{_report.__module__}:_report") == os.environ["HOME"]


@pytest.mark.parametrize("bad", ["", "panda_py..x", "panda-py.x", 3])
def test_register_refuses_what_is_not_a_module_name(bad: Any) -> None:
    with pytest.raises(ValueError, match="module: expected a dotted module name, got"):
        warmstart.register(bad)


@pytest.mark.parametrize("bad", ["os", "os:", ":getcwd"])
def test_a_target_name_without_its_module_and_function_is_refused(bad: str) -> None:
    with pytest.raises(ValueError, match="target: expected 'module:function', got"):
        warmstart.run_with_environ(dict(os.environ), bad)
