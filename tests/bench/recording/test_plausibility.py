"""Plausibility of a recording (bench.recording.plausibility): each fault a real table and DAQ
have is named in the calibration's ``warnings`` or refused on one line; clean recordings, static
and moving (lever arm steps, oscillation), give nothing."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from bench.calibration import calibrate_recording
from bench.recording import Recording
from bench.recording.plausibility import (
    MAX_ANGLE_SCATTER_DEG,
    NOISE_BLOCK_SAMPLES,
    _local_sigma,
    check_channel_scale,
    fit_findings,
    recording_findings,
)
from tests.support.dynamic_sim import oscillation, rate


@pytest.fixture(scope="module")
def moving() -> Recording:
    return rate(seed=3, rates_deg_s=(50.0, 150.0), dwell_s=3.0)[1]


def _kinds(rec: Recording) -> list[str]:
    return [f.kind for f in recording_findings(rec)]


def _accel(rec: Recording, change) -> Recording:  # type: ignore[no-untyped-def]
    y = rec.accel_raw.copy()
    change(y)
    return replace(rec, accel_raw=y)


def test_clean_recordings_have_no_finding(moving: Recording) -> None:
    assert _kinds(moving) == []
    assert _kinds(oscillation(seed=4, duration_s=30.0)[1]) == []


@pytest.mark.parametrize(("count", "width"), [(1, 1), (20, 1), (3, 3), (1, 4)])
def test_spikes_of_one_or_a_few_samples_are_named(moving: Recording, count: int, width: int) -> None:
    rng = np.random.default_rng(count)
    noise = float(np.median(np.abs(np.diff(moving.accel_raw[:, 1]))))
    starts = rng.choice(np.arange(100, moving.n_samples - 100, 20), size=count, replace=False)

    def spike(y: np.ndarray) -> None:
        for s in starts:
            y[s : s + width, 1] += 200 * noise

    found = recording_findings(_accel(moving, spike))
    assert [f.kind for f in found] == ["spikes"]
    assert found[0].text.startswith(f"channel ay: {count} spike(s) ({count * width} samples")


def test_a_run_longer_than_a_spike_is_not_called_one(moving: Recording) -> None:
    def shelf(y: np.ndarray) -> None:
        y[1000:1040, 0] += 0.5  # 40 samples: a step and back, not a spike

    assert "spikes" not in _kinds(_accel(moving, shelf))


def test_a_channel_stuck_at_its_rail_is_named(moving: Recording) -> None:
    rail = float(np.percentile(moving.accel_raw[:, 2], 90))
    found = recording_findings(_accel(moving, lambda y: np.minimum(y[:, 2], rail, out=y[:, 2])))
    clip = [f for f in found if f.kind == "clipping"]
    assert len(clip) == 1 and clip[0].text.startswith(f"channel az holds its largest value {rail:.6g} in ")


@pytest.mark.parametrize("share", [0.6, 0.9])
def test_a_rail_holding_most_samples_is_named_not_taken_for_quantisation(
    moving: Recording, share: float
) -> None:
    """Clipped below its (1 - share) quantile, most consecutive samples are equal (at the rail);
    the channel is still judged, and the rail's count is the samples at or below that level."""
    rail = float(np.quantile(moving.accel_raw[:, 0], share))
    found = recording_findings(_accel(moving, lambda y: np.maximum(y[:, 0], rail, out=y[:, 0])))
    clip = [f for f in found if f.kind == "clipping"]
    n_rail = int(np.sum(moving.accel_raw[:, 0] <= rail))
    assert len(clip) == 1 and clip[0].text.startswith(
        f"channel ax holds its smallest value {rail:.6g} in {n_rail} "
    )
    q = 20 * float(np.median(np.abs(np.diff(moving.accel_raw[:, 0]))))  # steps of 20x the noise
    coarse = _accel(moving, lambda y: np.multiply(np.round(y[:, 0] / q), q, out=y[:, 0]))
    assert "clipping" not in _kinds(coarse)


@pytest.mark.parametrize("q_deg", [0.07, 0.37])
def test_encoders_on_a_coarse_grid_are_named(moving: Recording, q_deg: float) -> None:
    """Rounded to q, a moving encoder scatters by q/√12 about its smooth motion (q incommensurate
    with the simulated motion, whose angles fall on a lattice of 0.5°: rounded to that they stay
    exact)."""
    assert moving.table_deg is not None
    rounded = replace(moving, table_deg=np.round(moving.table_deg / q_deg) * q_deg)
    found = [f for f in recording_findings(rounded) if f.kind == "encoder_resolution"]
    moved = [i for i in range(moving.table_deg.shape[1]) if np.ptp(moving.table_deg[:, i]) > 1.0]
    assert [f.text.split(":")[0] for f in found] == [f"table_{i + 1}" for i in moved]
    for f in found:
        sigma = float(f.text.split("scatter by ")[1].split("°")[0])
        assert 0.3 < sigma * np.sqrt(12) / q_deg < 1.5, f.text  # the error is uniform only roughly here
    fine = replace(moving, table_deg=np.round(moving.table_deg / 1e-3) * 1e-3)
    assert 1e-3 / np.sqrt(12) < MAX_ANGLE_SCATTER_DEG and "encoder_resolution" not in _kinds(fine)


@pytest.mark.parametrize("channel", [0, 1, 2])
@pytest.mark.parametrize("factor", [1e6, 1e-6])
def test_a_channel_scaled_by_a_million_is_refused_naming_it(
    moving: Recording, channel: int, factor: float
) -> None:
    name = ("ax", "ay", "az")[channel]
    scaled = _accel(moving, lambda y: y[:, channel].__imul__(factor))
    with pytest.raises(ValueError, match=rf"^recording: channel {name} spans") as err:
        calibrate_recording(scaled)
    assert "wrong gain or unit" in str(err.value) and "singular" not in str(err.value)


def test_channels_of_one_triad_within_the_ratio_pass() -> None:
    y = np.random.default_rng(1).standard_normal((1000, 3)) * np.array([1.0, 300.0, 1.0])
    check_channel_scale(y, "V")  # a channel that sees only noise beside ones that see g


def test_fit_findings_mirror_turn_gains_and_lag() -> None:
    K = np.diag([0.1, 0.1, 0.1])
    assert fit_findings(K, frame_known=True, channel_unit="V") == ()
    mirror = fit_findings(np.diag([0.1, 0.1, -0.1]), frame_known=True, channel_unit="V")
    assert [f.kind for f in mirror] == ["frame"] and "mirror image" in mirror[0].text
    c, s = np.cos(np.radians(180.0)), np.sin(np.radians(180.0))
    turned = fit_findings(
        0.1 * np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]]), frame_known=True, channel_unit="V"
    )
    assert "turned 180.0°" in turned[0].text
    assert fit_findings(np.diag([0.1, 0.1, -0.1]), frame_known=False, channel_unit="V") == ()
    gains = fit_findings(np.diag([0.1, 0.1, 100.0]), frame_known=True, channel_unit="V")
    assert [f.kind for f in gains] == ["gains"] and "1e+03 times" in gains[0].text
    lag = fit_findings(K, frame_known=True, channel_unit="V", time_skew_s=0.02, sample_rate_hz=1000.0)
    assert [f.kind for f in lag] == ["encoder_lag"] and "(20 samples" in lag[0].text
    assert fit_findings(K, frame_known=True, channel_unit="V", time_skew_s=5e-4, sample_rate_hz=1000.0) == ()


@pytest.mark.slow
def test_an_encoder_lag_of_twenty_samples_is_a_warning_of_the_calibration(moving: Recording) -> None:
    assert moving.table_deg is not None
    lagged = moving.table_deg.copy()
    lagged[20:] = moving.table_deg[:-20]
    warnings = calibrate_recording(replace(moving, table_deg=lagged)).warnings
    assert any("the encoders and the DAQ are" in w for w in warnings), warnings
    assert not any("encoders and the DAQ" in w for w in calibrate_recording(moving).warnings)


@pytest.mark.parametrize("n", [1, 31, 32, 33, 1000, 4097])
@pytest.mark.parametrize("zero_share", [0.0, 0.4, 1.0])
def test_local_sigma_is_the_median_of_each_blocks_nonzero_departures(n: int, zero_share: float) -> None:
    """The vectorised block medians against np.median block by block: equal to the bit, with
    blocks of zeros only (a flat stretch), a short last block and even and odd counts."""
    rng = np.random.default_rng(n)
    dep = np.round(rng.normal(size=n), 2)
    dep[rng.random(n) < zero_share] = 0.0
    size = NOISE_BLOCK_SAMPLES
    sig = []
    for i in range(0, n, size):
        moving = np.abs(dep[i : i + size][dep[i : i + size] != 0])
        sig.append(1.4826 * float(np.median(moving)) if moving.size else 0.0)
    padded = np.array([sig[0], *sig, sig[-1]])
    local = np.maximum(np.maximum(padded[:-2], padded[1:-1]), padded[2:])
    expected = np.repeat(np.maximum(local, 0.005), size)[:n]
    assert np.array_equal(_local_sigma(dep, 0.005), expected)
