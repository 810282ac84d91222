"""The live view's signal tail: block means however the DAQ splits its blocks, bounded memory
whatever the run's length, only the last span shown."""

from __future__ import annotations

import numpy as np
import pytest

from bench.live_signal import SignalTail, view_to_json


def _signal(n: int, rate_hz: float, seed: int = 0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    rng = np.random.default_rng(seed)
    t = np.arange(n) / rate_hz
    accel = np.column_stack([np.sin(t), np.cos(t), 9.81 + t * 0.0]) + rng.normal(0, 1e-3, (n, 3))
    table = np.column_stack([10.0 * t, -t, np.zeros(n)])
    return t, accel, table


def _feed(tail: SignalTail, t: np.ndarray, a: np.ndarray, d: np.ndarray, seed: int = 1) -> None:
    rng = np.random.default_rng(seed)
    i = 0
    while i < len(t):
        n = int(rng.integers(1, 97))  # blocks of any size, not multiples of k
        tail.add(t[i : i + n], a[i : i + n], d[i : i + n])
        i += n


def test_points_are_the_means_of_consecutive_blocks_of_k_samples() -> None:
    rate, span, points = 200.0, 5.0, 100  # k = ceil(200 * 5 / 100) = 10
    t, a, d = _signal(1234, rate)
    tail = SignalTail(rate, span, points)
    _feed(tail, t, a, d)
    view = tail.view()
    assert view.samples_per_point == 10
    full = 1234 // 10 * 10  # the last 4 samples wait for the next block
    rows = np.hstack([t[:full, None], a[:full], d[:full]]).reshape(-1, 10, 7).mean(axis=1)
    newest = rows[-1, 0]
    expect = rows[rows[:, 0] >= newest - span][-points:]  # within the span, at most max_points
    np.testing.assert_allclose(view.t_s, expect[:, 0], rtol=0, atol=1e-12)
    np.testing.assert_allclose(view.accel, expect[:, 1:4], rtol=0, atol=1e-12)
    np.testing.assert_allclose(view.table_deg, expect[:, 4:], rtol=0, atol=1e-12)
    assert view.t_s[-1] - view.t_s[0] <= span


def test_memory_stays_bounded_over_an_hour_at_one_kilohertz() -> None:
    rate, span, points = 1000.0, 30.0, 300  # k = 100
    tail = SignalTail(rate, span, points)
    block = 250
    for start in range(0, 3_600_000, 25_000):  # an hour, 25 s per call made of 100 DAQ blocks
        t, a, d = _signal(25_000, rate, seed=start)
        t = t + start / rate
        for i in range(0, 25_000, block):
            tail.add(t[i : i + block], a[i : i + block], d[i : i + block])
        assert len(tail._points) <= points
        assert tail._carry is None or len(tail._carry) < tail.samples_per_point
    view = tail.view()
    assert len(view.t_s) == points
    assert view.t_s[-1] == pytest.approx(3_600_000 / rate - (100 + 1) / 2 / rate)  # mean of the last block
    assert span - 0.1 - 1e-9 <= view.t_s[-1] - view.t_s[0] <= span


def test_a_hold_leaves_no_point_older_than_the_span() -> None:
    rate = 100.0
    tail = SignalTail(rate, span_s=10.0, max_points=100)  # k = 10
    t, a, d = _signal(500, rate)
    tail.add(t, a, d)
    tail.add(t + 100.0, a, d)  # 100 s later (a gap in what the view was given)
    view = tail.view()
    assert min(view.t_s) >= max(view.t_s) - 10.0 and min(view.t_s) > 100.0


def test_json_has_one_list_per_channel_and_axis_and_no_nan() -> None:
    tail = SignalTail(10.0, span_s=2.0, max_points=10)  # k = 2
    t = np.arange(4) / 10.0
    a = np.array([[1.0, 2.0, 3.0], [3.0, 4.0, np.nan], [0.5, 0.5, 0.5], [1.5, 1.5, 1.5]])
    tail.add(t, a, np.array([[1.0, 2.0]] * 4))
    body = view_to_json(tail.view())
    assert body["t_s"] == [0.05, 0.25]
    assert body["ax"] == [2.0, 1.0] and body["ay"] == [3.0, 1.0] and body["az"] == [None, 1.0]
    assert body["table_deg"] == [[1.0, 1.0], [2.0, 2.0]]
    assert body["samples_per_point"] == 2 and body["span_s"] == 2.0


def test_bad_shapes_and_settings_are_refused() -> None:
    tail = SignalTail(100.0)
    with pytest.raises(ValueError, match=r"accel \(3, 2\)"):
        tail.add(np.zeros(3), np.zeros((3, 2)), np.zeros((3, 3)))
    with pytest.raises(ValueError, match="max_points 1"):
        SignalTail(100.0, 30.0, 1)


def test_a_block_across_the_wrap_of_an_angle_stays_at_the_wrap() -> None:
    tail = SignalTail(10.0, span_s=2.0, max_points=10)  # k = 2
    t = np.arange(4) / 10.0
    angles = np.array([[179.0, 10.0], [-179.0, 20.0], [-170.0, 30.0], [-160.0, 40.0]])
    tail.add(t, np.zeros((4, 3)), angles)
    (a0, b0), (a1, b1) = tail.view().table_deg
    assert abs(a0) == pytest.approx(180.0) and b0 == pytest.approx(15.0)  # not (179 - 179) / 2 = 0
    assert a1 == pytest.approx(-165.0) and b1 == pytest.approx(35.0)
