"""The ring between the simulator's tick and the processes that draw it (sim/frames.py):
frame instants of simulated time, every frame kept for the recorder, the newest for the
viewer, a realtime tick that never waits."""

from __future__ import annotations

import math
import threading
import time

import numpy as np
import pytest

from panda_py.sim.frames import FrameFeed, FrameReader, FrameTaps, close_feed

NQ = 3


def _run(taps: FrameTaps, ticks: int) -> None:
    for tick in range(1, ticks + 1):
        taps.tick(tick, np.full(NQ, float(tick)))


@pytest.mark.parametrize("fps", [30.0, 60.0, 25.0, 7.0])
@pytest.mark.parametrize("ticks", [1, 33, 34, 1000, 2345])
def test_one_frame_per_period_of_simulated_time_from_the_first_tick(fps: float, ticks: int):
    feed = FrameFeed.create(NQ, fps, latest=False, slots=128)
    reader = FrameReader(feed)
    taps = FrameTaps((feed,), lockstep=False)
    got: list[np.ndarray] = []
    for tick in range(1, ticks + 1):
        taps.tick(tick, np.full(NQ, float(tick)))
        while (row := reader.next()) is not None:
            got.append(row)
    assert len(got) == math.floor(ticks * fps / 1000) + 1
    # Frame k is the state after the first tick at or past k / fps [s].
    for k, row in enumerate(got):
        tick = max(1, math.ceil(round(k * 1000 / fps, 9)))
        assert row[0] == pytest.approx(tick / 1000) and np.all(row[1:] == tick)


def test_realtime_drops_frames_when_the_recorder_is_behind():
    feed = FrameFeed.create(NQ, 1000.0, latest=False, slots=8)
    reader = FrameReader(feed)
    _run(FrameTaps((feed,), lockstep=False), 20)  # nobody reads: 8 kept, 12 dropped
    assert reader.dropped == 12
    rows = []
    while (row := reader.next()) is not None:
        rows.append(row[1])
    assert rows == [float(t) for t in range(1, 9)]  # the oldest kept, in order


@pytest.mark.timeout(10)
def test_lockstep_waits_for_the_recorder_and_loses_nothing():
    feed = FrameFeed.create(NQ, 1000.0, latest=False, slots=4)
    reader = FrameReader(feed)
    got: list[float] = []

    def read() -> None:  # a slow recorder: 1 ms a frame
        while True:
            row = reader.next()
            if row is not None:
                got.append(row[1])
                time.sleep(0.001)
            elif reader.closed:
                return
            else:
                time.sleep(0.0002)

    thread = threading.Thread(target=read)
    thread.start()
    taps = FrameTaps((feed,), lockstep=True)
    _run(taps, 50)
    taps.close()
    thread.join(5)
    assert got == [float(t) for t in range(1, 51)] and reader.dropped == 0


def test_a_gone_recorder_is_not_waited_for():
    feed = FrameFeed.create(NQ, 1000.0, latest=False, slots=4)
    reader = FrameReader(feed)
    reader.mark_gone()
    _run(FrameTaps((feed,), lockstep=True), 10)  # returns at once
    assert reader.dropped == 6


def test_the_viewer_sees_the_newest_frame():
    feed = FrameFeed.create(NQ, 60.0, latest=True, slots=4)
    reader = FrameReader(feed)
    assert reader.latest() is None
    _run(FrameTaps((feed,), lockstep=True), 1000)  # never waits, never drops
    row = reader.latest()
    assert row is not None and row[0] == pytest.approx(1.0) and reader.dropped == 0
    assert not reader.closed
    close_feed(feed)
    assert reader.closed
