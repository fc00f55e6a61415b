"""The lockstep spin's gate: it spins while the mean count of runnable threads over its
window is at most the cores, reads the count once a period, and spins as configured
where the count cannot be read (no file, a malformed one)."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

from panda_py.sim.spin import SpinGate

SPIN = 300e-6


def loadavg(path: Path, runnable: int) -> None:
    path.write_text(f"0.52 0.58 0.59 {runnable}/812 4242\n")


def test_it_spins_while_a_core_is_spare_and_stops_when_threads_wait(tmp_path: Path) -> None:
    path = tmp_path / "loadavg"
    loadavg(path, 2)
    gate = SpinGate(SPIN, path=str(path), cores=2, period=1.0, window=3)
    assert gate.budget(0.0) == SPIN  # 2 runnable on 2 cores
    loadavg(path, 6)
    assert gate.budget(0.5) == SPIN  # read once a period: not read yet
    assert gate.budget(1.0) == 0.0  # mean (2 + 6) / 2 = 4 > 2
    loadavg(path, 1)
    assert gate.budget(2.0) == 0.0  # (2 + 6 + 1) / 3 = 3
    assert gate.budget(3.0) == 0.0  # (6 + 1 + 1) / 3 = 2.7: the 2 left the window
    assert gate.budget(4.0) == SPIN  # (1 + 1 + 1) / 3
    gate.close()
    assert gate.budget(5.0) == SPIN  # closed: no count, as configured


def test_the_cores_bound_the_mean(tmp_path: Path) -> None:
    path = tmp_path / "loadavg"
    loadavg(path, 4)
    assert SpinGate(SPIN, path=str(path), cores=4).budget(0.0) == SPIN
    assert SpinGate(SPIN, path=str(path), cores=3).budget(0.0) == 0.0


@pytest.mark.parametrize("text", ["", "0.52 0.58 0.59\n", "0.52 0.58 0.59 x/812 1\n"])
def test_a_count_that_cannot_be_read_spins_as_configured(tmp_path: Path, text: str) -> None:
    path = tmp_path / "loadavg"
    path.write_text(text)
    gate = SpinGate(SPIN, path=str(path), cores=1)
    assert gate.budget(0.0) == SPIN
    loadavg(path, 9)  # it stopped reading the file that failed it
    assert gate.budget(1.0) == SPIN
    assert SpinGate(SPIN, path=str(tmp_path / "missing"), cores=1).budget(0.0) == SPIN


def test_no_spin_configured_is_no_spin(tmp_path: Path) -> None:
    path = tmp_path / "loadavg"
    loadavg(path, 1)
    assert SpinGate(0.0, path=str(path), cores=8).budget(0.0) == 0.0


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="/proc/loadavg is Linux's")
def test_this_machines_count_is_read() -> None:
    # at least this thread is runnable while it reads: never <= 0 cores, always <= 10**6
    assert SpinGate(SPIN, cores=0).budget(0.0) == 0.0
    assert SpinGate(SPIN, cores=10**6).budget(0.0) == SPIN
