"""The referee's leave-one-window-out scores in O(m) against the refit without each window."""

from __future__ import annotations

import numpy as np

from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.likelihood import NoiseParams, gls, window_covariance
from bench.diagnosis.referee import loo_scores


def test_loo_scores_equal_refitting_without_each_window() -> None:
    rng = np.random.default_rng(5)
    m = 15
    A = rng.normal(size=(m, 3, 3)) * 1e-3
    V = np.einsum("wij,wkj->wik", A, A) + 1e-6 * np.eye(3)
    mid_s = rng.uniform(0.0, 900.0, m)
    f = rng.normal(size=(m, 3))
    y = rng.normal(size=(m, 3)) * 1e-3
    ev = StaticEvidence(
        y=y, V=V, f_m_s2=f, mid_s=mid_s, labels=tuple(f"w{i}" for i in range(m)), g_local_m_s2=9.81
    )
    noise = NoiseParams(tau2=np.array([2e-6, 0.0, 1e-6]), corr_time_s=300.0, pose_var_rad2=0.0)
    cov = window_covariance(V, mid_s, noise)
    X = rng.normal(size=(3 * m, 14))
    C, z = cov.dense(), y.reshape(-1)
    want = np.zeros(3)
    for w in range(m):
        keep = np.ones(3 * m, dtype=bool)
        keep[3 * w : 3 * w + 3] = False
        th = gls(X[keep], z[keep], C[np.ix_(keep, keep)]).theta
        r = z[3 * w : 3 * w + 3] - X[3 * w : 3 * w + 3] @ th
        want += r * r / np.diag(C)[3 * w : 3 * w + 3]
    np.testing.assert_allclose(loo_scores(ev, X, cov), want, rtol=1e-7)
