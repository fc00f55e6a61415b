"""``PandaContext``'s schedule on a fake clock (no robot, no sleeps): ticks fall on
``t_0 + k / frequency`` exactly, whatever the loop body costs, late iterations skip whole
periods without shifting the phase, and the loop stops at ``max_iter`` / ``max_runtime``."""

from __future__ import annotations

import types

import pytest

from panda_py.panda import context
from panda_py.panda.context import PandaContext

PERIOD = 1e-3  # [s] a 1 kHz context


class FakeClock:
    """``perf_counter`` and ``sleep`` of a clock that only moves when told to, when slept
    on, or by a quantum per reading (so a spin loop ends)."""

    def __init__(self, quantum: float = 1e-6) -> None:
        self.now = 100.0
        self.quantum = quantum

    def perf_counter(self) -> float:
        self.now += self.quantum
        return self.now

    def sleep(self, seconds: float) -> None:
        assert seconds >= 0.0
        self.now += seconds


class FakePanda:
    def __init__(self) -> None:
        self.error: Exception | None = None

    def raise_error(self) -> None:
        if self.error is not None:
            raise self.error


@pytest.fixture
def clock(monkeypatch: pytest.MonkeyPatch) -> FakeClock:
    fake = FakeClock()
    monkeypatch.setattr(context, "time", types.SimpleNamespace(
        perf_counter=fake.perf_counter, sleep=fake.sleep))  # fmt: skip
    return fake


def _run(clock: FakeClock, work: list[float], **kwargs: float) -> tuple[float, list[float]]:
    """Tick times relative to entering, with ``work[k]`` seconds of loop body after tick
    k (the last value repeats)."""
    ctx = PandaContext(FakePanda(), 1.0 / PERIOD, **kwargs)  # type: ignore[arg-type]
    ticks = []
    with ctx:
        start = clock.now
        k = 0
        while ctx.ok():
            ticks.append(clock.now - start)
            clock.now += work[min(k, len(work) - 1)]
            k += 1
    return start, ticks


@pytest.mark.parametrize("body", [0.0, 0.3 * PERIOD, 0.99 * PERIOD])
def test_ticks_fall_on_the_absolute_schedule(clock: FakeClock, body: float) -> None:
    """A loop body of any length below the period leaves every tick within a few quanta of
    k periods: after 1000 ticks a 1 % drift (10 ms) or a re-anchored schedule shows."""
    _, ticks = _run(clock, [body], max_iter=1000)
    assert len(ticks) == 1000
    for k, t in enumerate(ticks, start=1):
        assert k * PERIOD <= t <= k * PERIOD + 6 * clock.quantum, (k, t)


def test_a_late_iteration_skips_whole_periods_and_keeps_the_phase(clock: FakeClock) -> None:
    # the body after the tick at 10 ms takes 3.5 periods; the others nothing
    _, ticks = _run(clock, [0.0] * 9 + [3.5 * PERIOD] + [0.0], max_iter=20)
    eps = 6 * clock.quantum  # ok() reads the clock a few times
    assert ticks[10] == pytest.approx(13.5 * PERIOD, abs=eps)  # late: at once
    # then back on the grid (k * PERIOD), the missed ticks skipped, not made up
    assert ticks[11] == pytest.approx(14 * PERIOD, abs=eps)
    for t in ticks[11:]:
        phase = (t / PERIOD) % 1.0
        assert min(phase, 1.0 - phase) < eps / PERIOD, t
    assert len(ticks) == 20


def test_max_runtime_ends_the_loop_on_time(clock: FakeClock) -> None:
    _, ticks = _run(clock, [0.0], max_runtime=0.05)
    assert len(ticks) == 49  # ticks at 1..49 ms; the one at 50 ms says stop
    assert ticks[-1] == pytest.approx(0.049, abs=6 * clock.quantum)


def test_a_control_error_is_raised_by_ok(clock: FakeClock) -> None:
    panda = FakePanda()
    ctx = PandaContext(panda, 100.0)  # type: ignore[arg-type]
    with ctx:
        assert ctx.ok()
        panda.error = RuntimeError("reflex")
        with pytest.raises(RuntimeError, match="reflex"):
            ctx.ok()
