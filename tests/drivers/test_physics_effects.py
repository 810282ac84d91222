"""Each catalogue effect alone, noise off: raw − (bias + K·f) against the effect's closed form."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from drivers.sim.motion import AxisProfile, ConstantRate, Hold, Oscillation, TableProfile, TrapezoidMove
from drivers.sim.offline import DEFAULT_AXES, simulate_static, static12_poses_deg
from drivers.sim.physics import G0_M_S2, NoiseSpec, SensorPhysics, SensorTruth, TemperatureModel

G = 9.81535
BIAS = np.array([1.49, 1.51, 1.505])
K = np.array([[0.0176, 2e-5, -1e-5], [3e-5, 0.0178, 1.5e-5], [-2e-5, 1e-5, 0.0175]])
KD = np.diag(K)
FS = 100.0
TEMP = TemperatureModel(ambient_c=21.0, warmup_rise_c=3.0, warmup_tau_s=60.0, cycle_amplitude_c=0.5)


def _physics(effects: dict | None = None, windows=None) -> SensorPhysics:
    truth = SensorTruth(BIAS, K, "V", effects=effects or {}, noise=NoiseSpec.silent())
    return SensorPhysics(truth, DEFAULT_AXES, None, G, seed=3, temperature=TEMP, windows_s=windows)


def _tumble() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Static 12-position run without effects: (t, raw, f) with f the ideal specific force."""
    run = simulate_static(static12_poses_deg(), 2.0, _physics(), FS, lead_s=0.5)
    f = _physics().specific_force(run.profile(run.t_s))
    return run.t_s, run.raw, f


def _effect_raw(effects: dict) -> np.ndarray:
    run = simulate_static(static12_poses_deg(), 2.0, _physics(effects), FS, lead_s=0.5)
    return run.raw


def test_no_effect_is_exactly_first_order():
    _, raw, f = _tumble()
    np.testing.assert_allclose(raw, BIAS + f @ K.T, rtol=0, atol=1e-14)


def test_nonlinearity_quadratic():
    k2 = np.array([1e-3, -2e-3, 1.5e-3])
    _, raw0, f = _tumble()
    raw = _effect_raw({"nonlinearity_quadratic": {"k2_per_g": k2.tolist()}})
    np.testing.assert_allclose(raw - raw0, KD * k2 * f**2 / G0_M_S2, atol=1e-14)
    # at +1 g on z: 1.5e-3 g of error = 1.5 mg
    z_up = np.argmax(f[:, 2])
    assert (raw - raw0)[z_up, 2] / KD[2] / G0_M_S2 == pytest.approx(1.5e-3 * (G / G0_M_S2) ** 2)


def test_scale_asymmetry():
    delta = np.array([2e-3, 0.0, -1e-3])
    _, raw0, f = _tumble()
    raw = _effect_raw({"scale_asymmetry": {"delta": delta.tolist()}})
    np.testing.assert_allclose(raw - raw0, KD * delta / 2 * np.abs(f), atol=1e-14)


def test_cross_coupling():
    c = np.array([[1e-3, 0, 2e-3], [0, -1e-3, 0], [5e-4, 5e-4, 5e-4]])
    _, raw0, f = _tumble()
    raw = _effect_raw({"cross_coupling": {"c_per_g": c.tolist()}})
    fx, fy, fz = f.T
    expected = np.column_stack(
        [KD[i] * (c[i, 0] * fx * fy + c[i, 1] * fx * fz + c[i, 2] * fy * fz) / G0_M_S2 for i in range(3)]
    )
    np.testing.assert_allclose(raw - raw0, expected, atol=1e-14)


def test_temperature_bias_relative_to_25c():
    tc = np.array([1e-3, -5e-4, 2e-3])
    t, raw0, _ = _tumble()
    raw = _effect_raw({"temperature_bias": {"tc_m_s2_per_c": tc.tolist()}})
    temp = 21.0 + 3.0 * (1 - np.exp(-t / 60.0)) + 0.5 * np.sin(2 * math.pi * t / 1800.0)
    np.testing.assert_allclose(raw - raw0, KD * tc * (temp[:, None] - 25.0), atol=1e-14)


def test_bias_drift_from_run_start():
    drift = np.array([1e-5, 0.0, -2e-5])
    t, raw0, _ = _tumble()
    raw = _effect_raw({"bias_drift": {"drift_m_s2_per_s": drift.tolist()}})
    np.testing.assert_allclose(raw - raw0, KD * drift * t[:, None], atol=1e-14)


def test_table_tilt():
    a, b = 2e-3, -3e-3
    phys = _physics({"table_tilt": {"tilt_rad": [a, b]}})
    prof = TableProfile(tuple(AxisProfile((Hold(x, 1.0),)) for x in np.radians([90.0, 0.0, 0.0])))
    raw = phys.sample(np.arange(0.0, 1.0, 0.01), prof).raw
    # Rot(x,a)·Rot(y,b)·e_z = [sin b, −sin a·cos b, cos a·cos b]; outer at 90° turns the
    # room by −90° in the sensor frame: (x, y, z) -> (y, −x, z)
    tilted = np.array([math.sin(b), -math.sin(a) * math.cos(b), math.cos(a) * math.cos(b)])
    f = G * np.array([tilted[1], -tilted[0], tilted[2]])
    np.testing.assert_allclose(raw, np.broadcast_to(BIAS + K @ f, raw.shape), atol=1e-14)


def test_pose_error_per_window():
    pairs = np.array([[1e-3, 0.0], [0.0, -2e-3], [3e-3, 1e-3]])
    windows = [(0.0, 1.0), (2.0, 3.0), (4.0, 5.0)]
    phys = _physics({"pose_error": {"angles_rad": pairs.tolist()}}, windows=windows)
    prof = TableProfile(tuple(AxisProfile((Hold(0.0, 6.0),)) for _ in range(3)))
    t = np.array([0.5, 2.5, 4.5, 5.5])
    raw = phys.sample(t, prof).raw
    for j, w in enumerate([0, 1, 2, 2]):
        a, b = pairs[w]
        # Rot(y,−b)·Rot(x,−a)·e_z
        f = G * np.array([-math.cos(a) * math.sin(b), math.sin(a), math.cos(a) * math.cos(b)])
        np.testing.assert_allclose(raw[j], BIAS + K @ f, atol=1e-14)


def test_pose_error_needs_one_pair_per_window():
    with pytest.raises(ValueError, match="2 angle pairs given, the run has 3 windows"):
        _physics({"pose_error": {"angles_rad": [[0, 0], [0, 0]]}}, windows=[(0, 1), (2, 3), (4, 5)])


def test_encoder_offset_and_wrapping():
    off = [0.0, 30.0, -2.0]
    phys = _physics({"encoder_offset": {"offset_deg": off}})
    angles = np.radians([181.0, 0.0, 2.0])
    prof = TableProfile(tuple(AxisProfile((Hold(x, 1.0),)) for x in angles))
    s = phys.sample(np.array([0.0, 0.5]), prof)
    # the encoders read the controller's angles, wrapped; the table truly stands at angle + offset
    np.testing.assert_allclose(s.encoder_deg, [[-179.0, 0.0, 2.0]] * 2, atol=1e-12)
    f = G * np.array([0.0, math.sin(math.radians(30)), math.cos(math.radians(30))])
    np.testing.assert_allclose(s.raw, np.broadcast_to(BIAS + K @ f, (2, 3)), atol=1e-14)


def test_time_skew_delays_the_table_seen_by_the_sensor():
    delay, omega, theta0 = 0.004, math.radians(50.0), 0.3
    phys = _physics({"time_skew": {"delay_s": delay}})
    prof = TableProfile(
        (
            AxisProfile((Hold(0.0, 10.0),)),
            AxisProfile((ConstantRate(theta0, omega, 1.0, 10.0, omega),)),
            AxisProfile((Hold(0.0, 10.0),)),
        )
    )
    t = np.arange(0.01, 5.0, 0.01)  # t − delay stays inside the profile
    s = phys.sample(t, prof)
    np.testing.assert_allclose(
        np.unwrap(s.encoder_deg[:, 1], period=360.0), np.degrees(theta0 + omega * t), atol=1e-9
    )
    assert s.encoder_deg.min() >= -180.0 and s.encoder_deg.max() < 180.0
    seen = theta0 + omega * (t - delay)
    f = G * np.column_stack([np.zeros_like(t), np.sin(seen), np.cos(seen)])
    np.testing.assert_allclose(s.raw, BIAS + f @ K.T, atol=1e-13)


def test_lever_arm_adds_centripetal_on_the_turning_table():
    r, omega = 0.05, math.radians(120.0)
    phys = _physics({"lever_arm": {"r_m": [0.0, r, 0.0]}})
    prof = TableProfile(
        (
            AxisProfile((ConstantRate(0.0, omega, 1.0, 5.0, omega),)),
            AxisProfile((Hold(0.0, 5.0),)),
            AxisProfile((Hold(0.0, 5.0),)),
        )
    )
    raw = phys.sample(np.arange(0.0, 5.0, 0.01), prof).raw
    f = np.array([0.0, -(omega**2) * r, G])
    np.testing.assert_allclose(raw, np.broadcast_to(BIAS + K @ f, raw.shape), atol=1e-13)


def test_proof_mass_offsets_each_axis_at_its_own_place():
    omega = math.radians(180.0)
    rho = [[0.01, 0.0, 0.0], [0.0, 0.02, 0.0], [0.005, 0.0, 0.0]]
    phys = _physics({"lever_arm": {"r_m": [0.03, 0.0, 0.0]}, "proof_mass_offsets": {"rho_m": rho}})
    prof = TableProfile(
        (
            AxisProfile((ConstantRate(0.0, omega, 1.0, 5.0, omega),)),
            AxisProfile((Hold(0.0, 5.0),)),
            AxisProfile((Hold(0.0, 5.0),)),
        )
    )
    raw = phys.sample(np.arange(0.0, 5.0, 0.01), prof).raw
    # x mass at (0.04, 0, 0), y mass at (0.03, 0.02, 0): each reads −ω² times its own coordinate
    f = np.array([-(omega**2) * 0.04, -(omega**2) * 0.02, G])
    np.testing.assert_allclose(raw, np.broadcast_to(BIAS + K @ f, raw.shape), atol=1e-13)


def test_sensor_lowpass_follows_the_differential_equation():
    tau = 0.05
    phys = _physics({"sensor_lowpass": {"tau_s": tau}})
    prof = TableProfile(
        (
            AxisProfile((Hold(0.0, 6.0),)),
            AxisProfile((Oscillation(0.5, 0.6, 0.8, 6.0, 0.2),)),
            AxisProfile((Hold(0.0, 6.0),)),
        )
    )
    t = np.arange(0.0, 6.0, 0.001)  # the filter is exact for input linear between samples: error O(dt²)
    raw = phys.sample(t, prof).raw
    ideal = _physics()

    def rhs(tt: float, y: np.ndarray) -> np.ndarray:
        return (ideal.specific_force(prof(np.array([tt])))[0] - y) / tau

    y0 = ideal.specific_force(prof(np.array([0.0])))[0]
    sol = solve_ivp(rhs, (0.0, t[-1]), y0, t_eval=t, rtol=1e-10, atol=1e-10, method="DOP853")
    f = sol.y.T
    np.testing.assert_allclose(np.linalg.solve(K, (raw - BIAS).T).T, f, atol=1e-4)
    # and the filter matters: the unfiltered force differs by far more
    assert np.max(np.abs(ideal.specific_force(prof(t)) - f)) > 0.5


def test_settling_rings_after_a_move_and_dies_out():
    duration = 1.5
    move = TrapezoidMove(0.0, math.radians(90.0), math.radians(30.0), math.radians(60.0))
    prof = TableProfile(
        (
            AxisProfile((Hold(0.0, 10.0),)),
            AxisProfile((Hold(0.0, 1.0), move, Hold(math.radians(90.0), 5.0))),
            AxisProfile((Hold(0.0, 10.0),)),
        )
    )
    stop = 1.0 + move.duration_s
    phys = _physics({"settling": {"duration_s": duration}})
    t = np.arange(0.0, 9.0, 0.01)
    raw = phys.sample(t, prof).raw
    s = t - stop
    tau = duration / math.log(0.05 / 1e-4)
    ring = np.where(s >= 0, math.radians(0.05) * np.exp(-np.maximum(s, 0) / tau) * np.sin(4 * math.pi * s), 0)
    after = t >= stop
    theta = math.radians(90.0) + ring[after]
    f = G * np.column_stack([np.zeros_like(theta), np.sin(theta), np.cos(theta)])
    np.testing.assert_allclose(raw[after], BIAS + f @ K.T, atol=1e-12)
    assert np.max(np.abs(np.degrees(ring[s >= duration]))) < 1e-4
    # before the move there is nothing to ring
    np.testing.assert_allclose(
        raw[t < 1.0], np.broadcast_to(BIAS + K @ [0, 0, G], raw[t < 1.0].shape), atol=1e-14
    )


@pytest.mark.parametrize(
    ("effects", "message"),
    [
        ({"warp_drive": {}}, "unknown effect 'warp_drive'"),
        ({"lever_arm": {"r": [0, 0, 0]}}, "expected exactly"),
        ({"lever_arm": {"r_m": [0, 0]}}, "shape"),
        ({"time_skew": {"delay_s": float("nan")}}, "finite"),
        ({"sensor_lowpass": {"tau_s": 0.0}}, "> 0"),
    ],
)
def test_bad_effects_are_rejected_with_a_reason(effects, message):
    with pytest.raises(ValueError, match=message):
        SensorTruth(BIAS, K, "V", effects=effects)
