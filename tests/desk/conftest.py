"""Simulated robots with a Desk for the Desk tests: one FER and one FR3 per module."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from desk_support import desk_sim

from panda_py.sim import Simulator


@pytest.fixture(scope="module")
def fer(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Simulator]:
    with desk_sim("fer", tmp_path_factory.mktemp("fer-cert")) as sim:
        yield sim


@pytest.fixture(scope="module")
def fr3(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Simulator]:
    with desk_sim("fr3", tmp_path_factory.mktemp("fr3-cert")) as sim:
        yield sim


@pytest.fixture
def tokens(tmp_path: Path) -> str:
    """A fresh token and certificate store (a new user's machine)."""
    return str(tmp_path / "desk-store")
