"""The noise stretch shared by ``calbench allan`` and ``calbench plan --noise-from``."""

from __future__ import annotations

import numpy as np
import pytest

from bench.calibration.noise_stretch import noise_channels, select_noise_stretch
from bench.recording import G0_M_S2, Recording, Segment, Sidecar

FS_HZ = 10.0


def _recording(
    accel: np.ndarray, *, unit: str = "m/s2", segments: tuple[Segment, ...] | None = None
) -> Recording:
    sc = Sidecar(
        unit_serial="SN-N", channel_unit=unit, sample_rate_hz=FS_HZ, g_local_m_s2=9.81, segments=segments
    )
    return Recording(sidecar=sc, t_s=np.arange(accel.shape[0]) / FS_HZ, accel_raw=accel)


def test_the_stretch_is_the_asked_window_else_the_longest_segment_else_a_detected_window() -> None:
    rng = np.random.default_rng(3)
    a = 1e-3 * rng.standard_normal((600, 3)) + [0.0, 0.0, 9.81]
    segs = (Segment(label="short", start_s=1.0, end_s=5.0), Segment(label="long", start_s=10.0, end_s=40.0))
    rec = _recording(a, segments=segs)
    asked = select_noise_stretch(rec, (2.0, 3.0))
    assert (asked.samples, asked.n) == (slice(20, 31), 11)  # 2.0 <= t <= 3.0 at 10 Hz, both ends in
    longest = select_noise_stretch(rec)
    assert (longest.samples, longest.source) == (slice(100, 401), "longest segment long")
    assert select_noise_stretch(rec, whole=True).samples == slice(0, 600)
    moved = a.copy()
    moved[:200] += 5.0 * np.sin(np.arange(200) / 3.0)[:, None]  # the first 20 s shake: not static
    found = select_noise_stretch(_recording(moved))
    assert found.source == "longest static window found in the data" and found.samples.start >= 200
    for bad in ((3.0, 2.0), (float("nan"), 1.0), (100.0, 200.0)):
        with pytest.raises(ValueError, match="--window-s"):
            select_noise_stretch(rec, bad)


def test_channels_in_g_are_told_in_metres_per_second_squared() -> None:
    a = np.tile([0.0, 0.0, 1.0], (5, 1))
    ch = noise_channels(_recording(a, unit="g"))
    assert ch.unit == "m/s2"
    np.testing.assert_array_equal(ch.data[:, 2], np.full(5, G0_M_S2))
    volts = noise_channels(_recording(a, unit="V"))
    assert volts.unit == "V" and np.array_equal(volts.data, a)


def test_a_turn_between_poses_is_not_the_noise_stretch() -> None:
    """A hand-held session names its still poses (nominal_up); its longer turns are motions."""
    rng = np.random.default_rng(5)
    a = 1e-3 * rng.standard_normal((900, 3)) + [0.0, 0.0, 9.81]
    turn = np.arange(300) / FS_HZ  # 30 s turn by hand about x: gravity sweeps y and z
    a[500:800, 1] = 9.81 * np.sin(2 * np.pi * turn / 30.0)
    a[500:800, 2] = 9.81 * np.cos(2 * np.pi * turn / 30.0)
    segs = (
        Segment(label="z_p", start_s=0.0, end_s=20.0, nominal_up="+z"),
        Segment(label="z_p2", start_s=25.0, end_s=45.0, nominal_up="+z"),
        Segment(label="x_rot", start_s=50.0, end_s=79.9),
    )
    chosen = select_noise_stretch(_recording(a, segments=segs))
    assert chosen.source == "longest segment z_p" and chosen.samples == slice(0, 201)
    # the stretch is still: its spread is the 1e-3 noise, not the turn's 9.81 m/s² sweep
    assert float(np.max(np.std(a[chosen.samples], axis=0))) < 2e-3
