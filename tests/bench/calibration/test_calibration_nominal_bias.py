"""A nominal scale without a nominal zero-g output: refused for V and count channels (whose
output at zero g is not 0, so 'before' would measure the offset, not the scale), implied 0 for
g and m/s² channels."""

from __future__ import annotations

import numpy as np
import pytest

from bench.calibration import calibrate_recording
from tests.bench.calibration.test_calibration import _hand_recording
from tests.support.static_sim import G_LOCAL, random_truth

UPS = ["+x", "-x", "+y", "-y", "+z", "-z"]
F = G_LOCAL * np.vstack([np.eye(3)[i // 2] * (1 if i % 2 == 0 else -1) for i in range(6)])


@pytest.mark.parametrize("unit", ["V", "count"])
def test_scale_without_zero_g_output_is_refused_for_v_and_count(unit: str) -> None:
    rng = np.random.default_rng(11)
    b, K = random_truth(rng)
    rec = _hand_recording(F, b, K, rng, nominal_up=UPS, unit=unit)
    message = rf"^hand.csv: a nominal scale for a {unit} channel needs the nominal zero-g output"
    with pytest.raises(ValueError, match=message):
        calibrate_recording(rec, nominal_scale=float(K[0, 0]))
    with_bias = calibrate_recording(rec, nominal_scale=float(np.mean(np.diag(K))), nominal_bias=b)
    assert with_bias.g_before is not None  # the nominal pair gives a 'before' check


def test_m_s2_channel_takes_zero_as_its_nominal_bias() -> None:
    rng = np.random.default_rng(12)
    b, K = np.array([0.05, -0.03, 0.02]), np.diag([1.002, 0.998, 1.001])
    rec = _hand_recording(F, b, K, rng, nominal_up=UPS, unit="m/s2")
    res = calibrate_recording(rec, nominal_scale=1.0)
    assert res.g_before is not None
    # |f| with b = 0 and K = 1: the error is the unit's bias and scale error, a few 10 mm/s²
    assert abs(res.g_before.mean_error_m_s2) < 0.1
