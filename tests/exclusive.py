"""The ``exclusive`` marker: a test that runs while no other test does.

The suite runs in parallel (pytest-xdist, pyproject's addopts). A test marked
``exclusive`` judges timing on the wall clock (a realtime robot's stream, a 1 kHz loop of
its own) or loads the machine itself. The workers share a readers-writer lock (flock):
every other test holds it shared, an exclusive one holds it alone; a turnstile, taken by
each before the lock, keeps the exclusive one from waiting for ever behind a stream of
shared ones. The root conftest imports the hooks.
"""

from __future__ import annotations

import fcntl
import os
import shutil
import tempfile
from collections.abc import Generator
from pathlib import Path

import pytest

LOCKS = "PANDA_PY_TEST_LOCKS"  # the run's lock directory, for its workers
_DIR = pytest.StashKey[str]()


def pytest_configure(config: pytest.Config) -> None:
    """In the run's main process, before its workers start: their lock directory."""
    if hasattr(config, "workerinput"):
        return  # a worker: the directory is its main process's
    path = tempfile.mkdtemp(prefix="panda-py-test-locks-")
    config.stash[_DIR] = path
    os.environ[LOCKS] = path  # the workers inherit it


def pytest_unconfigure(config: pytest.Config) -> None:
    path = config.stash.get(_DIR, None)
    if path is not None:
        shutil.rmtree(path, ignore_errors=True)


def lock_paths() -> tuple[Path, Path] | None:
    """The turnstile's and the lock's files of this run (None: not an xdist worker)."""
    where = os.environ.get(LOCKS)
    if where is None or "PYTEST_XDIST_WORKER" not in os.environ:
        return None  # one process: nothing runs beside the test
    return Path(where) / "turnstile", Path(where) / "lock"


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_protocol(item: pytest.Item) -> Generator[None, None, None]:
    """Hold the lock, shared or alone, through the test's setup, call and teardown."""
    paths = lock_paths()
    if paths is None:
        yield
        return
    alone = item.get_closest_marker("exclusive") is not None
    with open(paths[0], "a") as turnstile, open(paths[1], "a") as lock:
        fcntl.flock(turnstile, fcntl.LOCK_EX)
        try:
            fcntl.flock(lock, fcntl.LOCK_EX if alone else fcntl.LOCK_SH)
        finally:
            fcntl.flock(turnstile, fcntl.LOCK_UN)
        try:
            yield
        finally:
            fcntl.flock(lock, fcntl.LOCK_UN)
