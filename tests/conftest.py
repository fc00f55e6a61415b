"""Fixtures shared across the test tree; the ``exclusive`` marker's lock (exclusive.py)."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest
from exclusive import (  # noqa: F401 (the hooks, used by pytest)
    pytest_configure,
    pytest_runtest_protocol,
    pytest_unconfigure,
)

from panda_py.robots import robot_for_protocol
from panda_py.sim import Simulator, free_loopback_host


def pytest_xdist_auto_num_workers(config: pytest.Config) -> int:
    """``--numprocesses=auto``: a worker per core and one more (pyproject's addopts cap it
    at 4). Much of the suite waits (robot time, the peer clients' sleeps, a grasp held): a
    worker per core left 103-109 of 620 core-seconds idle on a 2-core VM and ran in
    311-314 s; with three workers 25 were idle and it ran in 281-297 s
    (315-320 s in an hour when the machine ran 1.4x slower). The tests that judge
    wall-clock timing run alone whatever the count (``exclusive``)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    return (cores or 1) + 1


def _scheduling() -> tuple[int, int]:
    return os.sched_getscheduler(0), os.sched_getparam(0).sched_priority


@pytest.fixture(autouse=True)
def _scheduling_kept() -> Iterator[None]:
    """A test that leaves its thread under another scheduling policy errors (and the policy
    is put back): a worker left at SCHED_FIFO 99 runs every later test, and the processes
    they start, at realtime priority (SVT-AV1's encoder did, and the doctor's realtime
    check then answered for the worker)."""
    before = _scheduling()
    yield
    after = _scheduling()
    if after != before:
        os.sched_setscheduler(0, before[0], os.sched_param(before[1]))
        pytest.fail(f"the test left its thread's scheduling (policy, priority) at {after}, "
                    f"expected {before}")  # fmt: skip


@pytest.fixture(scope="module")
def sim_for_version() -> Iterator[Callable[..., Simulator]]:
    """``sim_for_version(version, **options)``: a lockstep simulator of the robot whose
    systems speak protocol ``version`` (a FER for 3-5, an FR3 before 5.9 for 6-9, an FR3
    for 10), started on first use and shared by the module's tests."""
    started: dict[tuple[Any, ...], Simulator] = {}

    def get(version: int, **options: Any) -> Simulator:
        robot = robot_for_protocol(version).name
        key = (robot, *sorted(options.items()))
        if key not in started:
            options.setdefault("lockstep", True)
            started[key] = Simulator(free_loopback_host(), robot, **options).start()
        return started[key]

    try:
        yield get
    finally:
        for sim in started.values():
            sim.stop()


# The modules with the suite's longest tests (10-35 s each here), started first: run in
# parallel, a long test started last keeps one process busy after the others are done.
FIRST = (
    "panda/test_grasp_hold.py",
    "examples/test_demo.py",
    "test_kinematics.py",
    "learning/test_learning_sim.py",
    "learning/test_rollouts.py",
    "panda/test_paper.py",
    "examples/test_examples.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    """Modules of FIRST first, in its order; the rest as collected (each module's tests
    stay together, in their order)."""
    root = Path(__file__).resolve().parent

    def rank(item: pytest.Item) -> int:
        try:
            where = item.path.resolve().relative_to(root).as_posix()
        except ValueError:
            return len(FIRST)
        return FIRST.index(where) if where in FIRST else len(FIRST)

    items.sort(key=rank)  # (stable)
