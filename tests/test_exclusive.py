"""The ``exclusive`` marker (tests/exclusive.py): run by pytest-xdist on two workers, a test
marked exclusive overlaps no other test, while the others do run side by side."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from exclusive import LOCKS

pytestmark = pytest.mark.timeout(120)

TESTS = Path(__file__).resolve().parent

CONFTEST = f"""
import sys
sys.path.insert(0, {str(TESTS)!r})
from exclusive import pytest_configure, pytest_runtest_protocol, pytest_unconfigure  # noqa
"""

# each test records when it ran; s* share, x* run alone
CASES = """
import os, time
import pytest

def _run(name):
    t0 = time.monotonic()
    time.sleep(0.25)
    with open(os.environ["SPANS"], "a") as f:
        f.write(f"{name} {t0} {time.monotonic()}\\n")

@pytest.mark.parametrize("i", range(8))
def test_s(i):
    _run(f"s{i}")

@pytest.mark.exclusive
@pytest.mark.parametrize("i", range(3))
def test_x(i):
    _run(f"x{i}")
"""


def test_an_exclusive_test_overlaps_no_other(tmp_path: Path) -> None:
    (tmp_path / "conftest.py").write_text(CONFTEST)
    (tmp_path / "test_cases.py").write_text(CASES)
    (tmp_path / "pytest.ini").write_text("[pytest]\nmarkers =\n    exclusive: alone\n")
    spans = tmp_path / "spans.txt"
    done = subprocess.run(
        [sys.executable, "-m", "pytest", "-q", "-p", "no:cacheprovider", "-n", "2",
         "--dist=load", str(tmp_path)],
        cwd=tmp_path, capture_output=True, text=True, timeout=100,
        env={**{k: v for k, v in os.environ.items() if k != LOCKS}, "SPANS": str(spans)},
    )  # fmt: skip
    assert done.returncode == 0, done.stdout + done.stderr
    rows = [line.split() for line in spans.read_text().splitlines()]
    runs = [(name, float(t0), float(t1)) for name, t0, t1 in rows]
    assert len(runs) == 11

    def overlap(a: tuple[str, float, float], b: tuple[str, float, float]) -> bool:
        return a[1] < b[2] and b[1] < a[2]

    for x in (r for r in runs if r[0].startswith("x")):
        others = [r for r in runs if r is not x and overlap(r, x)]
        assert not others, f"{x[0]} ran beside {[r[0] for r in others]}"
    shared = [r for r in runs if r[0].startswith("s")]
    assert any(overlap(a, b) for a in shared for b in shared if a is not b), "nothing in parallel"
