"""SimClock: simulated time = speed × wall time, checked against a patched wall clock."""

from __future__ import annotations

import itertools
import math
import threading

import pytest

from drivers.sim import clock as clock_mod
from drivers.sim.clock import SimClock


class FakeWall:
    """Stands in for time.monotonic / time.sleep so no test depends on real time."""

    def __init__(self) -> None:
        self.t = 1000.0
        self.slept: list[float] = []

    def monotonic(self) -> float:
        return self.t

    def sleep(self, s: float) -> None:
        self.slept.append(s)
        self.t += s


@pytest.fixture
def wall(monkeypatch: pytest.MonkeyPatch) -> FakeWall:
    fake = FakeWall()
    monkeypatch.setattr(clock_mod.time, "monotonic", fake.monotonic)
    monkeypatch.setattr(clock_mod.time, "sleep", fake.sleep)
    return fake


def test_now_is_speed_times_wall_elapsed(wall: FakeWall) -> None:
    c = SimClock(speed=50.0)
    assert c.now_s() == 0.0
    wall.t += 2.5
    assert c.now_s() == pytest.approx(125.0, rel=1e-12)


def test_sleep_takes_sim_over_speed_wall_seconds(wall: FakeWall) -> None:
    c = SimClock(speed=100.0)
    c.sleep(600.0)  # a ten-minute procedure step
    assert wall.slept == [pytest.approx(6.0)]
    assert c.now_s() == pytest.approx(600.0)


def test_set_speed_keeps_time_continuous(wall: FakeWall) -> None:
    c = SimClock(speed=10.0)
    wall.t += 1.0
    c.set_speed(2.0)
    assert c.now_s() == pytest.approx(10.0)
    wall.t += 1.0
    assert c.now_s() == pytest.approx(12.0)
    assert c.speed == 2.0


@pytest.mark.parametrize("bad", [0.0, -1.0, math.nan, math.inf, "fast"])
def test_bad_speed_is_refused(bad: object) -> None:
    with pytest.raises(ValueError, match="speed"):
        SimClock(speed=bad)  # type: ignore[arg-type]


@pytest.mark.parametrize("bad", [-0.1, math.nan, math.inf])
def test_bad_sleep_is_refused(bad: float) -> None:
    with pytest.raises(ValueError, match="sim_s"):
        SimClock().sleep(bad)


def test_real_clock_is_monotonic_across_threads() -> None:
    c = SimClock(speed=1000.0)
    seen: list[list[float]] = []

    def sample() -> None:
        seen.append([c.now_s() for _ in range(200)])

    threads = [threading.Thread(target=sample) for _ in range(4)]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    for series in seen:
        assert all(b >= a for a, b in itertools.pairwise(series))
