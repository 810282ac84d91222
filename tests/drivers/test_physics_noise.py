"""Noise processes, quantisation, saturation, seeding, streaming and ageing of the truth model."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest

from drivers.sim.motion import AxisProfile, Hold, Oscillation, TableProfile
from drivers.sim.offline import DEFAULT_AXES
from drivers.sim.physics import G0_M_S2, NoiseSpec, SensorPhysics, SensorTruth, TemperatureModel
from drivers.sim.sensor_truth import BIAS_AGEING_M_S2_PER_RT_DAY, SCALE_AGEING_PER_RT_DAY

G = 9.81535
FS = 100.0
LEVEL = TableProfile(tuple(AxisProfile((Hold(0.0, 1e6),)) for _ in range(3)))


def _unit(noise: NoiseSpec, unit: str = "m/s2") -> SensorTruth:
    return SensorTruth(np.zeros(3), np.eye(3), unit, noise=noise)


def _physics(truth: SensorTruth, seed: int = 1, **kw) -> SensorPhysics:
    return SensorPhysics(
        truth, DEFAULT_AXES, None, G, seed=seed, temperature=TemperatureModel.constant(25.0), **kw
    )


def _noise(spec: NoiseSpec, n: int, seed: int = 1) -> np.ndarray:
    t = np.arange(n) / FS
    return _physics(_unit(spec), seed).sample(t, LEVEL).raw - [0.0, 0.0, G]


def test_white_noise_level_from_sample_std():
    n_density = 2.5e-3
    x = _noise(NoiseSpec(white_m_s2_rt_hz=n_density), 40_000)
    expected = n_density * math.sqrt(FS)
    # std of 40 000 normal samples is within 1 % at 3 sigma (relative error 1/√(2n) = 0.35 %)
    np.testing.assert_allclose(x.std(axis=0), expected, rtol=0.011)
    np.testing.assert_allclose(x.mean(axis=0), 0.0, atol=4 * expected / math.sqrt(40_000))
    assert abs(np.corrcoef(x[:-1, 0], x[1:, 0])[0, 1]) < 0.02  # white


def test_random_walk_grows_with_square_root_of_time():
    k = 1e-4
    x = _noise(NoiseSpec(white_m_s2_rt_hz=0.0, random_walk_m_s2_s_rt_hz=k), 100_000)
    assert np.all(x[0] == 0.0)  # the walk starts at zero at the stream's start
    for lag in (10, 100, 1000):
        d = x[lag:] - x[:-lag]
        # increments over lag samples: variance K²·lag·Δt; overlapping estimate, a few % scatter
        var = d[::lag].var(axis=0).mean()
        rel_err = 3 * math.sqrt(2 / (3 * (x.shape[0] // lag)))
        assert var == pytest.approx(k**2 * lag / FS, rel=max(rel_err, 0.03))


def test_gauss_markov_variance_and_correlation():
    b, tau = 4e-4, 2.0
    x = _noise(NoiseSpec(white_m_s2_rt_hz=0.0, bias_instability_m_s2=b, bias_instability_tau_s=tau), 200_000)
    phi = math.exp(-1 / (FS * tau))
    # effective independent samples ≈ n·(1−φ)/(1+φ): ~1000 per axis, so ~5 % on the variance
    np.testing.assert_allclose(x.var(axis=0), b**2, rtol=0.15)
    lag = int(FS * tau)
    corr = np.mean([np.corrcoef(x[:-lag, i], x[lag:, i])[0, 1] for i in range(3)])
    assert corr == pytest.approx(phi**lag, abs=0.08)  # e^-1 at one correlation time


def test_quantization_rounds_to_the_step():
    lsb = 3.0 / 65536
    truth = SensorTruth([1.5, 1.5, 1.5], np.eye(3) * 0.0177, "V", noise=NoiseSpec(1e-3, quantization_lsb=lsb))
    raw = _physics(truth).sample(np.arange(2000) / FS, LEVEL).raw
    codes = raw / lsb
    np.testing.assert_allclose(codes, np.round(codes), atol=1e-6)
    assert np.min(np.diff(np.unique(raw[:, 0]))) == pytest.approx(lsb)


def test_saturation_clips_the_specific_force():
    truth = _unit(NoiseSpec(white_m_s2_rt_hz=0.0, saturation_m_s2=5.0))
    raw = _physics(truth).sample(np.arange(10) / FS, LEVEL).raw
    np.testing.assert_array_equal(raw[:, 2], 5.0)
    truth_g = SensorTruth(np.zeros(3), np.eye(3) / G0_M_S2, "g", noise=NoiseSpec(0.0, saturation_m_s2=5.0))
    np.testing.assert_allclose(_physics(truth_g).sample(np.arange(3) / FS, LEVEL).raw[:, 2], 5.0 / G0_M_S2)


def test_same_seed_same_samples_other_seed_other_samples():
    truth = SensorTruth.typical(seed=4)
    t = np.arange(500) / FS
    a = _physics(truth, seed=9).sample(t, LEVEL).raw
    b = _physics(truth, seed=9).sample(t, LEVEL).raw
    c = _physics(truth, seed=10).sample(t, LEVEL).raw
    np.testing.assert_array_equal(a, b)
    assert np.max(np.abs(a - c)) > 0


def test_chunked_streaming_equals_one_shot():
    noise = NoiseSpec(
        white_m_s2_rt_hz=2e-3,
        bias_instability_m_s2=5e-4,
        bias_instability_tau_s=3.0,
        random_walk_m_s2_s_rt_hz=1e-4,
        saturation_m_s2=60.0,
    )
    effects = {
        "sensor_lowpass": {"tau_s": 0.03},
        "bias_drift": {"drift_m_s2_per_s": [1e-4, 0, 0]},
        "temperature_bias": {"tc_m_s2_per_c": [0, 1e-3, 0]},
        "time_skew": {"delay_s": 0.003},
        "lever_arm": {"r_m": [0.05, 0.0, 0.02]},
    }
    truth = SensorTruth([1.5, 1.5, 1.5], np.eye(3) * 0.0177, "V", effects=effects, noise=noise)
    prof = TableProfile(
        (
            AxisProfile((Oscillation(0.0, 3.0, 9.0, 100.0, 0.5),)),
            AxisProfile((Oscillation(0.3, 1.0, 4.0, 100.0),)),
            AxisProfile((Hold(0.0, 100.0),)),
        )
    )
    temp = TemperatureModel(reading_noise_c=0.02)
    t = np.arange(3000) / FS
    kw = {"seed": 5, "temperature": temp, "sample_rate_hz": FS}
    whole = SensorPhysics(truth, DEFAULT_AXES, None, G, **kw).sample(t, prof)
    streaming = SensorPhysics(truth, DEFAULT_AXES, None, G, **kw)
    cuts = [0, 1, 2, 50, 51, 777, 1500, 2999, 3000]
    parts = [streaming.sample(t[a:b], prof) for a, b in itertools.pairwise(cuts)]
    np.testing.assert_allclose(np.vstack([p.raw for p in parts]), whole.raw, rtol=0, atol=1e-12)
    np.testing.assert_array_equal(np.vstack([p.encoder_deg for p in parts]), whole.encoder_deg)
    np.testing.assert_array_equal(np.concatenate([p.temp_c for p in parts]), whole.temp_c)


def test_blocks_must_move_forward_in_time():
    phys = _physics(_unit(NoiseSpec()))
    phys.sample(np.arange(10) / FS, LEVEL)
    with pytest.raises(ValueError, match="not after the last block"):
        phys.sample(np.arange(5) / FS, LEVEL)


def test_typical_unit_is_adxl325_like():
    truth = SensorTruth.typical("V", seed=2)
    np.testing.assert_allclose(np.diag(truth.K), 0.174 / G0_M_S2, rtol=0.05)
    np.testing.assert_allclose(truth.bias, 1.5, atol=0.05)
    off = truth.K[~np.eye(3, dtype=bool)] / np.diag(truth.K).mean()
    assert 1e-5 < np.abs(off).max() < 5e-3
    counts = SensorTruth.typical("count", seed=2)
    np.testing.assert_allclose(counts.K, truth.K * 65536 / 3.0)  # same unit, a 16-bit converter over 3 V


def test_ageing_is_deterministic_and_starts_from_the_unit():
    unit = SensorTruth.typical(seed=1)
    same = unit.aged(0.0, seed=3)
    np.testing.assert_array_equal(same.bias, unit.bias)
    np.testing.assert_array_equal(same.K, unit.K)
    np.testing.assert_array_equal(unit.aged(7.5, seed=3).bias, unit.aged(7.5, seed=3).bias)
    # one path through the days: a query of 9.5 days lies halfway between days 9 and 10
    halfway = (unit.aged(9.0, seed=3).bias + unit.aged(10.0, seed=3).bias) / 2
    np.testing.assert_allclose(unit.aged(9.5, seed=3).bias, halfway, rtol=0, atol=1e-15)
    assert np.any(unit.aged(10.0, seed=3).bias != unit.aged(10.0, seed=4).bias)
    with pytest.raises(ValueError, match="days"):
        unit.aged(-1.0, seed=3)


def test_ageing_spread_grows_as_square_root_of_days():
    unit = SensorTruth.typical(seed=1)
    kd = np.diag(unit.K)
    seeds = range(400)
    spread = {}
    for days in (1.0, 4.0, 16.0):
        db = np.array([(unit.aged(days, s).bias - unit.bias) / kd for s in seeds])
        ds = np.array([np.diag(unit.aged(days, s).K) / kd - 1 for s in seeds])
        spread[days] = db.std()
        # 1200 draws: the std is within 6 % (3 sigma)
        assert db.std() == pytest.approx(BIAS_AGEING_M_S2_PER_RT_DAY * math.sqrt(days), rel=0.07)
        assert ds.std() == pytest.approx(SCALE_AGEING_PER_RT_DAY * math.sqrt(days), rel=0.07)
    assert spread[1.0] < spread[4.0] < spread[16.0]
