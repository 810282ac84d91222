"""Static 12-parameter fit: exact truth, refusal of degenerate sets, honest z-scores, CRB."""

from __future__ import annotations

import numpy as np
import pytest

from bench.estimation.static_design import PARAMETER_NAMES
from bench.estimation.static_fit import fit_static
from bench.estimation.window_noise import pooled_mean_covariances, window_noise
from tests.support.static_sim import G_LOCAL, random_truth, simulate_run, tumble_specific_force


def _fit_run(run, *, f=None):
    noises = [window_noise(w) for w in run.windows]
    y = np.array([q.mean for q in noises])
    return fit_static(run.f_nominal if f is None else f, y, pooled_mean_covariances(noises))


def test_noiseless_windows_give_exact_truth() -> None:
    rng = np.random.default_rng(7)
    b, K = random_truth(rng)
    f = tumble_specific_force()
    y = b + f @ K.T
    V = np.tile(np.diag([1e-12, 2e-12, 3e-12]), (12, 1, 1))
    fit = fit_static(f, y, V)
    np.testing.assert_allclose(fit.bias, b, rtol=0, atol=1e-13)
    np.testing.assert_allclose(fit.K, K, rtol=0, atol=1e-15)
    np.testing.assert_allclose(fit.residuals, 0.0, atol=1e-13)
    assert fit.dof == 24
    assert np.all(fit.excess_var == 0.0)
    # Covariance of a 12-window weighted fit with known variances: bias of channel z has
    # variance (σ² (XᵀX)⁻¹)_00 computed directly.
    X = np.column_stack([np.ones(12), f])
    np.testing.assert_allclose(fit.cov[2, 2], 3e-12 * np.linalg.inv(X.T @ X)[0, 0], rtol=1e-10)
    assert PARAMETER_NAMES[2] == "b_z" and PARAMETER_NAMES[5] == "K_xz"


def test_constant_f_z_is_refused_naming_bias_and_third_column() -> None:
    g = G_LOCAL
    f = np.array([[0, 0, g], [1, 0, g], [0, 1, g], [1, 1, g], [2, -1, g]], dtype=float)
    with pytest.raises(ValueError, match=r"bias and K\[:,2\] \(response to f_z\) are confounded") as err:
        fit_static(f, 1.5 + f * 0.0176, np.tile(np.eye(3) * 1e-10, (5, 1, 1)))
    assert "f_z = +9.815 m/s²" in str(err.value)


def test_horizontal_plane_is_refused_naming_third_column_only() -> None:
    g = G_LOCAL
    f = g * np.array([[1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0], [0.6, 0.8, 0]], dtype=float)
    with pytest.raises(ValueError, match=r"K\[:,2\] \(response to f_z\) cannot be determined") as err:
        fit_static(f, 1.5 + f * 0.0176, np.tile(np.eye(3) * 1e-10, (5, 1, 1)))
    assert "bias" not in str(err.value).split(":")[1]


def test_tilted_plane_names_the_relation() -> None:
    g = G_LOCAL
    # all f on the plane f_x + f_y = 0: K[:,0] and K[:,1] confounded, bias fine
    f = g * np.array([[0.6, -0.6, 0.53], [-0.6, 0.6, 0.53], [0, 0, 1], [0, 0, -1], [0.7, -0.7, 0.1]])
    with pytest.raises(ValueError, match=r"K\[:,0\] .* and K\[:,1\] .* are confounded"):
        fit_static(f, 1.5 + f * 0.0176, np.tile(np.eye(3) * 1e-10, (5, 1, 1)))


def test_too_few_windows_and_bad_values_are_refused() -> None:
    f = tumble_specific_force()[:3]
    with pytest.raises(ValueError, match="at least 4 static windows"):
        fit_static(f, f * 0.0176, np.tile(np.eye(3) * 1e-10, (3, 1, 1)))
    f = tumble_specific_force()
    y = 1.5 + f * 0.0176
    y[5, 1] = np.nan
    with pytest.raises(ValueError, match="window mean of window 5 is not finite"):
        fit_static(f, y, np.tile(np.eye(3) * 1e-10, (12, 1, 1)))
    V = np.tile(np.eye(3) * 1e-10, (12, 1, 1))
    V[3, 2, 2] = 0.0
    with pytest.raises(ValueError, match="window 3: variance of the mean must be positive"):
        fit_static(f, 1.5 + f * 0.0176, V)


def _z_scores(n_runs: int, seed: int, **kw) -> np.ndarray:
    rng = np.random.default_rng(seed)
    z = []
    for _ in range(n_runs):
        run = simulate_run(rng, **kw)
        fit = _fit_run(run)
        truth = np.concatenate([run.bias_true, run.K_true.ravel()])
        z.append((fit.params - truth) / fit.sigma)
    return np.array(z)


def _assert_honest(z: np.ndarray) -> None:
    coverage = np.mean(np.abs(z) < 3.0)
    assert coverage >= 0.99, f"3-sigma coverage {coverage:.4f}"
    assert 0.8 <= z.std() <= 1.25, f"z std {z.std():.3f}"
    per_param = z.std(axis=0)
    bad = {PARAMETER_NAMES[k]: round(float(s), 3) for k, s in enumerate(per_param) if not 0.8 <= s <= 1.25}
    assert not bad, f"per-parameter z std outside 0.8-1.25: {bad}"
    assert np.all(np.abs(z.mean(axis=0)) < 4.0 / np.sqrt(z.shape[0])), "z-scores biased"


def test_z_scores_honest_with_white_and_gauss_markov_noise() -> None:
    """300 runs: 2 mg white + 1 mg Gauss-Markov at 0.05 s + 40 µg wander at 200 s (the example's noise)."""
    _assert_honest(_z_scores(300, seed=11))


@pytest.mark.slow
def test_z_scores_honest_with_pose_errors_between_windows() -> None:
    """400 runs with 1 mrad pose errors: the between-window variance keeps z ~ N(0, 1)."""
    z = _z_scores(400, seed=12, pose_error_rad=1e-3)
    _assert_honest(z)
    # and without the between-window term the same data would give overconfident sigmas
    rng = np.random.default_rng(12)
    run = simulate_run(rng, pose_error_rad=1e-3)
    noises = [window_noise(w) for w in run.windows]
    y = np.array([q.mean for q in noises])
    V = pooled_mean_covariances(noises)
    with_bw, without = fit_static(run.f_nominal, y, V), fit_static(run.f_nominal, y, V, between_window=False)
    assert with_bw.chi2 / with_bw.dof > 3.0
    assert np.all(with_bw.sigma[3:] > without.sigma[3:])
