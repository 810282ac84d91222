"""Table kinematics against hand-worked poses, other formulations, and an independent simulator."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bench import kinematics as k
from bench.estimation.windows import window_stats, windows_from_segments
from bench.recording import read_recording

G = 9.81535
X, Y, Z = np.eye(3)
AXES = np.array([Z, X, Z])  # outer vertical, middle horizontal, inner vertical (the format's default)


def test_rot_is_right_handed_and_orthonormal() -> None:
    R = k.rot(Z, np.deg2rad([90.0]))[0]
    np.testing.assert_allclose(R @ X, Y, atol=1e-15)
    np.testing.assert_allclose(k.rot(X, np.pi / 2)[0] @ Y, Z, atol=1e-15)
    np.testing.assert_allclose(k.rot(Y, np.pi / 2)[0] @ Z, X, atol=1e-15)
    u = np.array([1.0, 2.0, 2.0]) / 3.0
    Rs = k.rot(u, np.linspace(-7, 7, 50))
    np.testing.assert_allclose(Rs @ Rs.transpose(0, 2, 1), np.broadcast_to(np.eye(3), Rs.shape), atol=1e-14)
    np.testing.assert_allclose(np.linalg.det(Rs), 1.0, atol=1e-14)
    np.testing.assert_allclose(Rs @ u, np.broadcast_to(u, (50, 3)), atol=1e-14)


@pytest.mark.parametrize(
    "angles_deg,expected",
    [
        ((0, 0, 0), (0, 0, G)),  # z up reads +g
        ((37, 0, 0), (0, 0, G)),  # outer (vertical) axis alone changes nothing
        ((0, 180, 0), (0, 0, -G)),  # middle 180°: z down
        ((0, 90, 0), (0, G, 0)),  # Rot(x, 90°) carries sensor y to base z
        ((0, -90, 0), (0, -G, 0)),
        ((0, 90, 90), (G, 0, 0)),  # then inner 90° brings x up
        ((0, 90, -90), (-G, 0, 0)),
        ((0, 90, 180), (0, -G, 0)),
        ((0, 45, 0), (0, G / np.sqrt(2), G / np.sqrt(2))),
    ],
)
def test_static_specific_force_hand_worked(
    angles_deg: tuple[float, ...], expected: tuple[float, ...]
) -> None:
    R = k.attitude(AXES, np.deg2rad([angles_deg]), np.eye(3))
    np.testing.assert_allclose(k.static_specific_force(R, G)[0], expected, atol=1e-12)


def test_mount_rotation_is_applied_on_the_sensor_side() -> None:
    M = k.rot(Y, -np.pi / 2)[0]  # sensor x -> table z: sensor x points up at zero angles
    R = k.attitude(AXES, np.zeros((1, 3)), M)
    np.testing.assert_allclose(k.static_specific_force(R, G)[0], [G, 0, 0], atol=1e-12)
    q = np.deg2rad([[10.0, 20.0, 30.0]])
    np.testing.assert_allclose(k.attitude(AXES, q, M), k.inner_attitude(AXES, q) @ M, atol=1e-15)


def test_centripetal_and_tangential_terms_by_hand() -> None:
    w, alpha, r = 4.0, 2.5, 0.06  # rad/s, rad/s², m; sensor at r on x of a single vertical axis
    t = np.linspace(0, 1, 11)
    q = (w * t)[:, None]
    f = k.specific_force(Z[None], np.eye(3), [r, 0, 0], q, np.full_like(q, w), np.full_like(q, alpha), G)
    np.testing.assert_allclose(f, np.broadcast_to([-w * w * r, alpha * r, G], f.shape), atol=1e-12)
    # The same with the unit mounted upside down (x kept, z down): reading turns with the sensor.
    M = k.rot(X, np.pi)[0]
    f2 = k.specific_force(Z[None], M, [r, 0, 0], q, np.full_like(q, w), np.full_like(q, alpha), G)
    np.testing.assert_allclose(f2, np.broadcast_to([-w * w * r, -alpha * r, -G], f.shape), atol=1e-12)


def _smooth_motion(n: int = 4001, seed: int = 3) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Angles q(t) = Σ a sin(2π f t + φ) with analytic rates and accelerations."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 2.0, n)
    a, f, ph = rng.uniform(0.3, 2.0, (3, 3)), rng.uniform(0.2, 1.0, (3, 3)), rng.uniform(0, 6, (3, 3))
    arg = 2 * np.pi * f[None] * t[:, None, None] + ph[None]
    q = (a * np.sin(arg)).sum(1)
    qd = (a * 2 * np.pi * f * np.cos(arg)).sum(1)
    qdd = (-a * (2 * np.pi * f) ** 2 * np.sin(arg)).sum(1)
    return t, q, qd, qdd


def test_angular_velocity_and_acceleration_agree_with_differentiated_attitude() -> None:
    t, q, qd, qdd = _smooth_motion()
    axes = np.array([Z, X, [0.0, 0.6, 0.8]])
    R = k.inner_attitude(axes, q)
    Rdot = np.gradient(R, t, axis=0, edge_order=2)
    W = Rdot @ R.transpose(0, 2, 1)  # [ω]× in base coordinates
    w_num = np.stack([W[:, 2, 1], W[:, 0, 2], W[:, 1, 0]], axis=1)
    w = k.angular_velocity(axes, q, qd)
    np.testing.assert_allclose(w[5:-5], w_num[5:-5], atol=2e-5 * np.abs(w).max())
    wdot = k.angular_acceleration(axes, q, qd, qdd)
    wdot_num = np.gradient(w, t, axis=0, edge_order=2)
    np.testing.assert_allclose(wdot[5:-5], wdot_num[5:-5], atol=2e-5 * np.abs(wdot).max())
    # the cross terms matter: without them the acceleration would be visibly wrong
    plain = sum(
        qdd[:, i, None] * (k.inner_attitude(axes[:i], q[:, :i]) @ axes[i] if i else axes[0]) for i in range(3)
    )
    assert np.abs(plain - wdot).max() > 0.1 * np.abs(wdot).max()


def test_specific_force_is_gravity_reaction_plus_second_derivative_of_position() -> None:
    t, q, qd, qdd = _smooth_motion()
    lever = np.array([0.05, -0.02, 0.03])
    M = k.rot([0.0, 0.6, 0.8], 0.7)[0]
    R_in = k.inner_attitude(AXES, q)
    p = R_in @ lever
    pdd = np.gradient(np.gradient(p, t, axis=0, edge_order=2), t, axis=0, edge_order=2)
    R = R_in @ M
    expected = np.einsum("nji,nj->ni", R, pdd + np.array([0.0, 0.0, G]))
    f = k.specific_force(AXES, M, lever, q, qd, qdd, G)
    assert np.abs(pdd).max() > 10.0  # the motion terms are not negligible next to g
    np.testing.assert_allclose(f[10:-10], expected[10:-10], atol=2e-3)


def test_derivatives_savgol_exact_for_cubics_and_gradient_for_irregular_time() -> None:
    t = np.arange(200) * 0.01
    q = np.column_stack([0.3 + 2 * t - 1.5 * t**2 + 0.7 * t**3, -t])
    rates, accels = k.derivatives(t, q)
    np.testing.assert_allclose(rates[:, 0], 2 - 3 * t + 2.1 * t**2, atol=1e-9)
    np.testing.assert_allclose(accels[:, 0], -3 + 4.2 * t, atol=1e-7)
    np.testing.assert_allclose(rates[:, 1], -1, atol=1e-12)
    rng = np.random.default_rng(0)
    tj = np.cumsum(rng.uniform(0.005, 0.015, 400))
    with pytest.raises(ValueError, match="gradient"):
        k.derivatives(tj, np.sin(tj))
    r, a = k.derivatives(tj, np.sin(tj), method="gradient")
    np.testing.assert_allclose(r[2:-2], np.cos(tj[2:-2]), atol=1e-4)
    np.testing.assert_allclose(a[4:-4], -np.sin(tj[4:-4]), atol=5e-3)


def test_bad_inputs_are_refused() -> None:
    with pytest.raises(ValueError, match="unit length"):
        k.attitude([[0, 0, 2.0]], [[0.1]], np.eye(3))
    with pytest.raises(ValueError, match=r"expected \(n, 3\)"):
        k.attitude(AXES, np.zeros((4, 2)), np.eye(3))
    with pytest.raises(ValueError, match="increasing"):
        k.derivatives([0.0, 0.1, 0.1, 0.2], np.zeros(4), method="gradient")


def _truth(independent: Path, name: str) -> tuple[np.ndarray, np.ndarray]:
    tr = json.loads((independent / f"{name}.truth.json").read_text())
    return np.array(tr["bias_v"]), np.array(tr["K_v_per_m_s2"])


# Per-window bias wander of the independent simulator: Gauss-Markov 40 µg (README), in volts.
WANDER_V = 40e-6 * 9.80665 * 0.018


def test_example_static12_window_means_reproduced_from_truth(independent_dir: Path) -> None:
    rec = read_recording(independent_dir / "example_static12.csv")
    bias, K = _truth(independent_dir, "example_static12")
    tb = rec.sidecar.table
    assert tb is not None and rec.table_deg is not None and rec.sidecar.segments is not None
    ws = windows_from_segments(rec.t_s, rec.sidecar.segments)
    st = window_stats(rec.t_s, rec.accel_raw, np.deg2rad(rec.table_deg), None, ws)
    assert st.table_mean_rad is not None
    R = k.attitude(tb.axis_vectors, st.table_mean_rad, tb.mount_matrix)
    f = k.static_specific_force(R, rec.sidecar.g_local_m_s2)
    np.testing.assert_allclose(np.linalg.norm(f, axis=1), rec.sidecar.g_local_m_s2, rtol=1e-12)
    # the twelve poses point the gravity reaction along many directions (not a degenerate set)
    assert np.linalg.matrix_rank(np.column_stack([np.ones(12), f])) == 4
    predicted = bias + f @ K.T
    sigma = np.sqrt((st.std / np.sqrt(st.n[:, None])) ** 2 + WANDER_V**2)
    z = (st.mean - predicted) / sigma
    assert np.abs(z).max() < 4.5, z
    assert np.sqrt(np.mean(z**2)) < 2.0


def test_example_rate_lever_known_reproduced_sample_by_sample(independent_dir: Path) -> None:
    rec = read_recording(independent_dir / "example_rate_lever_known.csv")
    bias, K = _truth(independent_dir, "example_rate_lever_known")
    tb = rec.sidecar.table
    q = rec.table_rad_unwrapped()
    assert tb is not None and q is not None and rec.sidecar.segments is not None
    qd, qdd = k.derivatives(rec.t_s, q)
    assert np.rad2deg(np.abs(qd).max()) == pytest.approx(240.0, rel=1e-3)
    noise_v = 2e-3 * 9.80665 * np.diag(K)  # 2 mg white noise per sample (README)

    def residual(lever: tuple[float, float, float]) -> np.ndarray:
        f = k.specific_force(tb.axis_vectors, tb.mount_matrix, lever, q, qd, qdd, rec.sidecar.g_local_m_s2)
        return rec.accel_raw - (bias + f @ K.T)

    # with the sidecar's lever arm the whole recording, moves included, is explained to its noise
    np.testing.assert_allclose(residual(tb.lever_arm_m).std(axis=0), noise_v, rtol=0.05)
    for w in windows_from_segments(rec.t_s, rec.sidecar.segments):
        mean = residual(tb.lever_arm_m)[w.slice].mean(axis=0)
        assert np.all(np.abs(mean) < 4 * np.hypot(noise_v / np.sqrt(w.stop - w.start), WANDER_V)), w.label
    # without it, the centripetal ω²r (1 m/s² at 240 °/s and 60 mm) stands far out of the noise
    assert residual((0.0, 0.0, 0.0))[:, 0].std() > 10 * noise_v[0]
