"""The unbiased (MINQUE) excess of the budget's Type A line, on window means drawn directly.

Window means of a 12-position tumble y_w = b + K f_w + e_w, e_w with the windows' own variance
V and, per case, no excess, each channel's own excess τ² = V, or a pose error (tilt variance t
per axis) as large as the noise across gravity. The fit is told V only; its estimator's Type A
variance (``type_a_without_type_b``, no Type B input) is checked against the truth over 300
sessions: with no excess none is found on average (each component within 4 standard errors
of zero: not clipped), the spread of the errors over the RMS stated u is inside 1 ± 0.18 on
every parameter (the sampling error of a spread over 300 runs is 4.1 %; 0.18 is 4.4 of it),
the z RMS pooled over the parameters inside 0.8–1.25, and k u with k = t_95.45 %(ν) of the
stated degrees of freedom covers the error in 95.45 % of the cases less three standard errors
(at most 99 %). A variance estimated from 8 residual degrees of freedom per channel makes z
heavier-tailed than normal (t_ν: RMS √(ν/(ν − 2)), 1.22 pooled with the own excess when
written), which k carries. With no excess the fit's own σ (clipped Paule-Mandel excess,
inflated by ν/(ν − 2)) states more than the spread: 0.83–0.94 of it when written.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.stats import t as student_t

from bench.estimation.static_design import design_rows
from bench.estimation.static_fit import between_window_excess, fit_static
from bench.estimation.window_noise import pose_scatter
from bench.uncertainty import excess_moments as em
from bench.uncertainty.type_a import type_a_without_type_b
from tests.support.static_sim import tumble_specific_force

F = tumble_specific_force()
SIGMA = 3e-6
V = np.tile(np.eye(3) * SIGMA**2, (12, 1, 1))
RUNS = 300
SE = 1 / np.sqrt(2 * (RUNS - 1))
"""Relative standard error of a spread from RUNS normal errors (4.1 %)."""
BAND = 0.18
COVER_FLOOR = 0.9545 - 3 * np.sqrt(0.9545 * 0.0455 / RUNS)
"""Coverage of k u (k = t_95.45 %(ν)) pooled over the 12 parameters: 95.45 % less three
standard errors of a fraction from RUNS sessions (the parameters of a session are correlated)."""
MISREAD_HIGH = 1.3
MISREAD_COVER = 0.9
"""An own excess as large as the window noise is read in part as pose scatter (12 windows tell
the two apart only by the reading along gravity and the cross-channel terms; the model is chosen
by restricted likelihood, ``excess_moments.MODELS``): the biases and the diagonal of K, which
pose errors do not reach, are left short, spread/u up to 1.22 and coverage 0.92 when written
(the fit's σ: 1.19 and 0.94); docs/noise-model.md states the limit."""


def _sessions(rng: np.random.Generator, own: float, pose: float) -> dict[str, np.ndarray]:
    err, u, comp, fit_sigma, k = [], [], [], [], []
    for _ in range(RUNS):
        K = np.diag(0.0177 * (1 + 0.01 * rng.standard_normal(3))) + 2e-5 * rng.standard_normal((3, 3))
        b = 1.5 + 1e-3 * rng.standard_normal(3)
        cov = V + own * np.eye(3)[None] + pose * pose_scatter(K, F)
        e = np.einsum("wab,wb->wa", np.linalg.cholesky(cov), rng.standard_normal((12, 3)))
        y = b + F @ K.T + e
        fit = fit_static(F, y, V)
        ta = type_a_without_type_b(F, y, V, fit.K, [])
        err.append(fit.params - np.concatenate([b, K.ravel()]))
        u.append(np.sqrt(np.diag(ta.cov)))
        comp.append(ta.components)
        fit_sigma.append(fit.sigma)
        k.append(student_t.ppf(0.97725, np.floor(ta.dof)))
    out = (("err", err), ("u", u), ("comp", comp), ("fit", fit_sigma), ("k", k))
    return {name: np.array(v) for name, v in out}


@pytest.mark.slow
@pytest.mark.parametrize(
    ("seed", "own", "pose", "high"),
    [
        (2102, 0.0, 0.0, 1 + BAND),
        (2103, SIGMA**2, 0.0, MISREAD_HIGH),
        (2104, 0.0, (SIGMA / 0.0177) ** 2, 1 + BAND),
    ],
    ids=["no excess", "own excess", "pose error"],
)
def test_type_a_is_unbiased_with_and_without_an_excess(
    seed: int, own: float, pose: float, high: float
) -> None:
    s = _sessions(np.random.default_rng(seed), own, pose)
    spread = s["err"].std(axis=0, ddof=1)
    ratio = spread / np.sqrt(np.mean(s["u"] ** 2, axis=0))
    assert np.all((ratio > 1 - BAND) & (ratio < high)), ratio.round(3)
    z = float(np.sqrt(np.mean((s["err"] / s["u"]) ** 2)))
    assert 0.8 < z < 1.25, z
    cover = float(np.mean(np.abs(s["err"]) <= s["k"] * s["u"]))
    assert (COVER_FLOOR if high == 1 + BAND else MISREAD_COVER) < cover < 0.99, cover
    if own == pose == 0.0:  # nothing invented; the fit's σ states more than the spread (3 SE on most)
        mean, se = s["comp"].mean(axis=0), s["comp"].std(axis=0, ddof=1) / np.sqrt(RUNS)
        assert np.all(np.abs(mean) < 4 * se), (mean, se)
        fit_ratio = spread / np.sqrt(np.mean(s["fit"] ** 2, axis=0))
        assert np.sum(fit_ratio < 1 - 3 * SE) >= 6, fit_ratio.round(3)


def test_own_excess_under_large_pose_errors_is_estimated_near_the_reml_bound() -> None:
    """Pose errors 50x the window noise across gravity (3' on 198 s windows, docs/noise-model.md)
    and each channel's own excess equal to the noise: with the fit's Paule-Mandel weights as
    the MINQUE prior the own components' standard deviations were 10-20x (median of 10 draws)
    the restricted-likelihood information bound √(2 (F⁻¹)_ll), F_kl = tr(P G_k P G_l), P the
    residual operator at the true covariance (Rao & Kleffe 1988), and swung the Type A line of
    the biases and the diagonal of K from the floor to 7x the fit's σ. Iterated towards REML
    (``excess_moments.PRIOR_STEPS``) the stated values lie within 2x the bound (0.7-1.2 when
    written)."""
    rng = np.random.default_rng(2105)
    m = F.shape[0]
    H = design_rows(F).reshape(3 * m, 12)
    ratios = []
    for _ in range(10):
        K = np.diag(0.0177 * (1 + 0.01 * rng.standard_normal(3))) + 2e-5 * rng.standard_normal((3, 3))
        blocks = [pose_scatter(K, F)] + [np.tile(np.outer(e, e), (m, 1, 1)) for e in np.eye(3)]
        cov = V + (50 * SIGMA / 0.0177) ** 2 * blocks[0] + SIGMA**2 * sum(blocks[1:])
        y = 1.5 + F @ K.T + np.einsum("wab,wb->wa", np.linalg.cholesky(cov), rng.standard_normal((m, 3)))
        fit = fit_static(F, y, V)
        E, _, _ = between_window_excess(F, y, V, fit.K)
        W = em._block_diag(np.asarray(np.linalg.inv(V + E), dtype=np.float64))
        HtW = H.T @ W
        R = W - HtW.T @ np.linalg.solve(HtW @ H, HtW)
        G = [em._block_diag(g) for g in blocks]
        no_input = np.zeros((0, 3 * m))
        _, cov_phi = em._iterated(
            H, R, y.reshape(-1), em._block_diag(V), V, G, blocks, no_input, (0, 1, 2, 3)
        )
        Wt = em._block_diag(np.asarray(np.linalg.inv(cov), dtype=np.float64))
        HtWt = H.T @ Wt
        P = Wt - HtWt.T @ np.linalg.solve(HtWt @ H, HtWt)
        info = np.array([[np.trace(P @ a @ P @ b) for b in G] for a in G])
        ratios.append(np.sqrt(np.diag(cov_phi) / np.diag(2 * np.linalg.inv(info))))
    median = np.median(np.array(ratios), axis=0)
    assert np.all(median < 2.0), median.round(2)
