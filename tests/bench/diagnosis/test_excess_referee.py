"""The head to head of a claim against one channel's own excess (``excess_referee``).

The log score against an independent formulation (GLS without the window, then the Gaussian
conditional of its means given the others); sampled draws from the one-channel test's
synthetic windows (``test_channel_excess._draw``: 18 directions, window noise σ = 1.5e-5 V, a
shared wander): a nonlinearity claim on ax beside a random per-window excess of 4 σ on ax
(the loose connector) loses, and beside a true ax nonlinearity of 1e-3 /g (about 11 σ at ±g)
and no excess it wins. Margin: on 8 draws of each (seeds 1 and 2) the score differences were
−16 to −30 and +20 to +26 nats, spread about 3 nats, so a wrong sign on any draw is not
noise; the rates over simulated recordings are in ``benchmarks.study_diagnose_one_channel``.
The pose error (a variance component) is not a column and meets no head to head: a model
holding it and no column claim has none (its rival, a carried excess, meets it in the noise
model; the real hand-held session in ``test_diagnose_real`` and the loose connector in
``test_diagnosis_library`` hold both sides of that).
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import binom

from bench.diagnosis.effects import pose_response
from bench.diagnosis.effects.sensor import NONLINEARITY
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.excess_referee import HeadToHead, head_to_heads, loo_log_score
from bench.diagnosis.model_state import ModelState, fit_model
from bench.estimation.window_covariance import WindowCovariance
from tests.bench.diagnosis.test_channel_excess import K_TRUE, SIGMA_V, _draw


def _brute_score(X: np.ndarray, z: np.ndarray, C: np.ndarray) -> float:
    """Σ_w ln p(y_w | y₋w): θ̂ by GLS without window w, then y_w's Gaussian conditional given
    y₋w at θ̂, its covariance widened by θ̂'s own (the flat prior's predictive)."""
    m = z.size // 3
    total = 0.0
    for w in range(m):
        i = np.arange(3 * w, 3 * w + 3)
        o = np.setdiff1d(np.arange(3 * m), i)
        Coo_inv = np.linalg.inv(C[np.ix_(o, o)])
        Xo, zo = X[o], z[o]
        cov_th = np.linalg.inv(Xo.T @ Coo_inv @ Xo)
        th = cov_th @ Xo.T @ Coo_inv @ zo
        G = C[np.ix_(i, o)] @ Coo_inv
        mean = X[i] @ th + G @ (zo - Xo @ th)
        D = X[i] - G @ Xo
        S = C[np.ix_(i, i)] - G @ C[np.ix_(o, i)] + D @ cov_th @ D.T
        r = z[i] - mean
        total += -0.5 * (r @ np.linalg.solve(S, r) + np.linalg.slogdet(S)[1] + 3 * np.log(2 * np.pi))
    return float(total)


def test_log_score_matches_the_conditional_predictive() -> None:
    rng = np.random.default_rng(5)
    m, p = 9, 7
    A = rng.standard_normal((m, 3, 3))
    blocks = np.einsum("wij,wkj->wik", A, A) + 0.5 * np.eye(3)
    C = WindowCovariance(blocks, np.array([0.3, 0.5, 0.2]), 40.0, 25.0 * np.arange(m, dtype=np.float64))
    X = rng.standard_normal((3 * m, p))
    z = rng.standard_normal(3 * m)
    assert loo_log_score(X, z, C) == pytest.approx(_brute_score(X, z, C.dense()), rel=1e-9)


def _with_claim(ev: StaticEvidence) -> ModelState:
    cand = NONLINEARITY.candidates(ev)[0]
    noise, fit, _ = fit_model(ev, [cand], False, K_TRUE, None)
    return ModelState(candidates=[cand], noise=noise, fit=fit)


def _quadratic_ax(ev: StaticEvidence, k2_per_g: float) -> StaticEvidence:
    y = ev.y.copy()
    y[:, 0] += K_TRUE[0, 0] * k2_per_g * ev.f_m_s2[:, 0] ** 2 / 9.80665
    return replace(ev, y=y)


def _head_to_heads(n: int, seed: int, excess_sigmas: float, k2_per_g: float) -> list[HeadToHead]:
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        ev = _quadratic_ax(_draw(rng, 18, (excess_sigmas * SIGMA_V, 0.0, 0.0)), k2_per_g)
        (h,) = head_to_heads(ev, _with_claim(ev), None)
        assert h.effect == NONLINEARITY.id
        out.append(h)
    return out


def test_a_claim_beside_a_loose_connector_loses_to_the_channels_excess() -> None:
    assert all(h.withdrawn and h.channel == 0 for h in _head_to_heads(3, 1, 4.0, 0.0))


def test_a_true_claim_beats_the_channels_excess() -> None:
    assert not any(h.withdrawn for h in _head_to_heads(3, 2, 0.0, 1e-3))


def test_the_pose_error_alone_meets_no_head_to_head() -> None:
    """A true random pose error of 5e-4 rad per angle beside a 4 σ ax excess: the model with the
    pose variance and no column claim has no head to head (a variance is weighed in REML)."""
    rng = np.random.default_rng(3)
    ev = _draw(rng, 18, (4.0 * SIGMA_V, 0.0, 0.0))
    J = pose_response(ev, K_TRUE)
    ev = replace(ev, y=ev.y + np.einsum("wiq,wq->wi", J, 5e-4 * rng.standard_normal((ev.m, 2))))
    noise, fit, _ = fit_model(ev, [], True, K_TRUE, None)
    assert head_to_heads(ev, ModelState(pose=True, noise=noise, fit=fit), None) == []


@pytest.mark.slow
def test_the_head_to_head_rates_over_draws() -> None:
    """40 draws each; a rate of 95 % or more fails with probability below 1e-3."""
    need = binom.ppf(1e-3, 40, 0.95)
    assert sum(h.withdrawn and h.channel == 0 for h in _head_to_heads(40, 11, 4.0, 0.0)) >= need
    assert sum(not h.withdrawn for h in _head_to_heads(40, 12, 0.0, 1e-3)) >= need
