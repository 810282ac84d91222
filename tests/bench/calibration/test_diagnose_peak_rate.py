"""The largest table rate between windows, taken in chunks, sees every step, those across chunk ends too."""

from __future__ import annotations

import numpy as np
import pytest

from bench.calibration import diagnose


@pytest.mark.parametrize("step_at", [0, 6, 7, 8, 13, 14, 98])
def test_peak_rate_finds_the_one_fast_step_wherever_it_is(
    monkeypatch: pytest.MonkeyPatch, step_at: int
) -> None:
    monkeypatch.setattr(diagnose, "PEAK_RATE_CHUNK", 7)
    t = np.arange(100) * 0.01
    q = np.zeros((100, 2))
    q[:, 0] = 0.2 * t  # 0.2 rad/s everywhere on axis 1
    q[step_at + 1 :, 1] -= 0.03  # one step of 0.03 rad in 0.01 s on axis 2: 3 rad/s
    assert diagnose._peak_rate_rad_s(q, t) == pytest.approx(3.0, rel=1e-9)


def test_peak_rate_of_one_sample_is_zero() -> None:
    assert diagnose._peak_rate_rad_s(np.zeros((1, 3)), np.zeros(1)) == 0.0
