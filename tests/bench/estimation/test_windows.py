"""Static windows: from segments, detected in the data (table and hand-held), and their statistics."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from bench import kinematics as k
from bench.estimation.windows import (
    StaticWindow,
    detect_static_windows,
    window_stats,
    windows_from_segments,
)
from bench.recording import read_recording

G = 9.81


@dataclass(frozen=True)
class Seg:
    start_s: float
    end_s: float
    label: str = ""
    nominal_up: str | None = None


def test_detection_recovers_the_example_segments(independent_dir: Path) -> None:
    rec = read_recording(independent_dir / "example_static12.csv")
    assert rec.table_deg is not None and rec.sidecar.segments is not None
    found = detect_static_windows(rec.t_s, rec.accel_raw, np.deg2rad(rec.table_deg))
    segs = rec.sidecar.segments
    assert len(found) == len(segs) == 12
    # the run starts at rest in the first pose, so the first window may begin earlier than the segment
    assert found[0].start_s <= segs[0].start_s + 1.0
    for w, s in zip(found[1:], segs[1:], strict=True):
        assert abs(w.start_s - s.start_s) <= 1.0, (w, s)
    for w, s in zip(found, segs, strict=True):
        assert abs(w.end_s - s.end_s) <= 1.0, (w, s)
    assert [w.label for w in found[:2]] == ["w01", "w02"]


def _hand_held(seed: int = 5) -> tuple[np.ndarray, np.ndarray, list[tuple[float, float]]]:
    """Six hand-placed poses: 6 s still, 2.5 s turning (smooth), noise 3 mg, 100 Hz, counts-like scale."""
    rng = np.random.default_rng(seed)
    dt = 0.01
    ups = [np.array(v, float) for v in ([0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0])]
    f, truth, t0 = [], [], 0.0
    for i, up in enumerate(ups):
        still = np.tile(G * up, (600, 1))
        truth.append((t0, t0 + 599 * dt))
        f.append(still)
        t0 += 600 * dt
        if i + 1 < len(ups):
            nxt = ups[i + 1]
            axis = np.cross(up, nxt)
            angle = np.pi if np.linalg.norm(axis) < 1e-9 else np.pi / 2
            axis = np.array([0.0, 1.0, 0.0]) if np.linalg.norm(axis) < 1e-9 else axis / np.linalg.norm(axis)
            s = np.linspace(0, 1, 250)
            th = angle * (s - np.sin(2 * np.pi * s) / (2 * np.pi))  # smooth start and stop
            R = k.rot(axis, -th)
            f.append(R @ (G * up) + rng.normal(0, 0.5, (250, 3)))  # hand shake while moving
            t0 += 250 * dt
    fa = np.vstack(f) + rng.normal(0, 3e-3 * G, (sum(len(x) for x in f), 3))
    raw = 32768 + 400.0 * fa  # counts
    return np.arange(len(raw)) * dt, raw, truth


def test_detection_on_a_hand_held_recording() -> None:
    t, raw, truth = _hand_held()
    found = detect_static_windows(t, raw)
    assert len(found) == 6
    for w, (s, e) in zip(found, truth, strict=True):
        assert s - 0.01 <= w.start_s <= s + 1.0
        assert e - 1.0 <= w.end_s <= e + 0.01


def test_outer_axis_turn_is_seen_by_the_encoders_only() -> None:
    """A turn about the vertical axis leaves gravity unchanged; the encoder rate splits the windows."""
    dt = 0.01
    n = 3000
    t = np.arange(n) * dt
    rng = np.random.default_rng(2)
    raw = 1.5 + rng.normal(0, 3e-4, (n, 3))
    outer = np.zeros(n)
    move = (t >= 10) & (t < 14)
    outer[move] = np.deg2rad(90) * (t[move] - 10) / 4
    outer[t >= 14] = np.deg2rad(90)
    q = np.column_stack([outer, np.zeros(n), np.zeros(n)])
    assert len(detect_static_windows(t, raw)) == 1
    found = detect_static_windows(t, raw, q)
    assert len(found) == 2
    assert found[0].end_s <= 10.0 and found[1].start_s >= 14.0


def test_slow_creep_below_the_rate_threshold_splits_on_angle() -> None:
    dt = 0.01
    t = np.arange(4000) * dt
    raw = 1.5 + np.random.default_rng(1).normal(0, 3e-4, (4000, 3))
    q = np.column_stack([np.deg2rad(0.05) * t])  # 0.05 °/s: under the rate limit, 2° over 40 s
    found = detect_static_windows(t, raw, q, max_angle_step_rad=np.deg2rad(0.5))
    assert len(found) >= 3
    for w in found:
        assert np.ptp(q[w.slice]) <= np.deg2rad(0.5)


def test_explicit_threshold_and_garbage_refused() -> None:
    t, raw, _ = _hand_held()
    assert detect_static_windows(t, raw, max_std=1e-9) == []
    with pytest.raises(ValueError, match="shape"):
        detect_static_windows(t, raw[:, :2])
    with pytest.raises(ValueError, match="non-finite"):
        bad = raw.copy()
        bad[100, 1] = np.nan
        detect_static_windows(t, bad)
    with pytest.raises(ValueError, match="increasing"):
        detect_static_windows(t[::-1], raw)
    with pytest.raises(ValueError, match="too short"):
        detect_static_windows(t[:20], raw[:20])
    with pytest.raises(ValueError, match="max_std"):
        detect_static_windows(t, raw, max_std=-1.0)
    with pytest.raises(ValueError, match="table_rad"):
        detect_static_windows(t, raw, np.zeros((10, 3)))


def test_windows_from_segments_include_both_ends() -> None:
    t = np.arange(100) * 0.1
    ws = windows_from_segments(t, [Seg(2.0, 3.0, "b", "-z"), Seg(0.0, 1.0, "a")])
    assert [w.label for w in ws] == ["a", "b"]  # time order
    assert (ws[0].start, ws[0].stop) == (0, 11)
    assert (ws[1].start, ws[1].stop, ws[1].nominal_up) == (20, 31, "-z")
    with pytest.raises(ValueError, match="holds 0 samples"):
        windows_from_segments(t, [Seg(20.0, 21.0, "late")])
    with pytest.raises(ValueError, match="overlap"):
        windows_from_segments(t, [Seg(0.0, 1.0), Seg(1.0, 2.0)])


def test_window_stats_circular_mean_and_moments() -> None:
    t = np.arange(10) * 0.1
    rng = np.random.default_rng(0)
    accel = rng.normal(size=(10, 3))
    wrap = np.deg2rad(np.array([179.9, -179.9, 179.8, -179.8, 180.0]))
    q = np.column_stack([np.concatenate([wrap, np.deg2rad([10, 12, 14, 16, 18.0])]), np.zeros(10)])
    temp = np.array([20, np.nan, 22, 24, 26, 30, 30, 30, 30, 30.0])
    ws = [StaticWindow(0, 5, 0.0, 0.4, "a"), StaticWindow(5, 10, 0.5, 0.9, "b")]
    st = window_stats(t, accel, q, temp, ws)
    np.testing.assert_array_equal(st.n, [5, 5])
    np.testing.assert_allclose(st.mean[1], accel[5:].mean(0))
    np.testing.assert_allclose(st.std[0], accel[:5].std(0, ddof=1))
    assert st.table_mean_rad is not None and st.temp_mean_c is not None
    assert (
        abs(abs(np.rad2deg(st.table_mean_rad[0, 0])) - 180.0) < 1e-9
    )  # not 0 as an arithmetic mean would say
    assert np.rad2deg(st.table_mean_rad[1, 0]) == pytest.approx(14.0, abs=1e-3)
    np.testing.assert_allclose(st.temp_mean_c, [23.0, 30.0])
    np.testing.assert_allclose(st.mid_s, [0.2, 0.7])
    with pytest.raises(ValueError, match="within"):
        window_stats(t, accel, q, temp, [StaticWindow(5, 12, 0.5, 1.1, "x")])
