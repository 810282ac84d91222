"""The one-channel test (``bench.diagnosis.channel_excess``) on synthetic window means drawn from
its own null model (first-order design, window noise, a shared Gauss-Markov wander): its level,
its power against an excess on one channel, and that a misfit common to the channels names none.

Levels are judged against binomial bounds of the nominal rate (a margin over it, not the rate
measured); the rate over clean simulated recordings is in ``benchmarks.study_diagnose_one_channel``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from scipy.stats import binom

from bench.diagnosis.channel_excess import channel_excess
from bench.diagnosis.effects import first_order_design
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.likelihood import NoiseParams, gls, window_covariance
from bench.estimation.window_covariance import invert_blocks

G = 9.81
K_TRUE = np.diag([0.0177, 0.0175, 0.0178])
SIGMA_V = 1.5e-5
"""Window-mean noise per channel (V)."""
TAU_V = 1.0e-5
"""Shared wander (V), correlation time ``TC_S``."""
TC_S = 200.0
_DIRS = np.array(
    [[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1], [0, 0, -1],
     [1, 1, 0], [1, 0, 1], [0, 1, 1], [-1, 1, 0], [-1, 0, -1], [0, -1, 1],
     [1, 1, 1], [-1, -1, 1], [1, -1, -1], [-1, 1, -1], [1, 0, -1], [0, 1, -1]],
    dtype=float,
)  # fmt: skip


def _draw(rng: np.random.Generator, m: int, excess: tuple[float, float, float]) -> StaticEvidence:
    """m windows (the first m directions), white window noise, the shared wander, and an
    independent per-window excess of rms ``excess`` (V) on each channel."""
    d = _DIRS[:m]
    f = G * d / np.linalg.norm(d, axis=1, keepdims=True)
    mid = np.arange(m) * 40.0
    P = np.exp(-np.abs(mid[:, None] - mid[None, :]) / TC_S)
    Lp = np.linalg.cholesky(P)
    wander = TAU_V * (Lp @ rng.standard_normal((m, 3)))
    y = 1.5 + f @ K_TRUE.T + SIGMA_V * rng.standard_normal((m, 3)) + wander
    y += np.array(excess) * rng.standard_normal((m, 3))
    V = np.broadcast_to(np.eye(3) * SIGMA_V**2, (m, 3, 3)).copy()
    return StaticEvidence(
        y=y, V=V, f_m_s2=f, mid_s=mid, labels=tuple(f"w{i}" for i in range(m)), g_local_m_s2=G
    )


def _test(ev: StaticEvidence):  # type: ignore[no-untyped-def]
    noise = NoiseParams(tau2=np.full(3, TAU_V**2), corr_time_s=TC_S, n_tau=1)
    return channel_excess(ev, first_order_design(ev.f_m_s2), noise, None, None, None)


def _false_rate(n: int, alpha: float, seed: int) -> int:
    rng = np.random.default_rng(seed)
    return sum(_test(_draw(rng, 18, (0.0, 0.0, 0.0))).p_value < alpha for _ in range(n))


def test_level_on_its_null_model() -> None:
    """30 null draws at α = 0.1: expected at most 3 (Bonferroni over three channels makes it
    conservative); allowed up to the binomial 99.9 % point of 30 draws at 0.1 (9)."""
    assert _false_rate(30, 0.1, 5) <= binom.ppf(0.999, 30, 0.1)


@pytest.mark.slow
def test_level_on_its_null_model_many_draws() -> None:
    """200 null draws at α = 0.05: allowed up to the binomial 99.9 % point (20, expected ≤ 10)."""
    assert _false_rate(200, 0.05, 6) <= binom.ppf(0.999, 200, 0.05)


def test_an_excess_on_one_channel_is_found_and_named() -> None:
    """An excess of 4 window sigmas on ay, independent per window: the likelihood ratio is
    large (expected about m/2 · ln(1 + 16) ≈ 25 at m = 18 before the fitted parameters), so
    at 0.001 it is found and named in at least 8 of 10 draws."""
    rng = np.random.default_rng(9)
    hits = 0
    for _ in range(10):
        ex = _test(_draw(rng, 18, (0.0, 4.0 * SIGMA_V, 0.0)))
        hits += ex.p_value < 1e-3 and ex.channel == 1
        assert ex.excess_var[1] > 0
    assert hits >= 8


def test_a_misfit_common_to_the_channels_names_none() -> None:
    """The same excess on every channel is a common misfit (H0 holds it): a channel is named
    at 0.001 in at most 1 of 10 draws (nominal ≤ 0.001 each)."""
    rng = np.random.default_rng(10)
    named = sum(_test(_draw(rng, 18, (4.0 * SIGMA_V,) * 3)).p_value < 1e-3 for _ in range(10))
    assert named <= 1


def test_the_search_reaches_the_likelihood_a_grid_reaches() -> None:
    """LR_i from the Powell searches is at least the one a 25 × 25 × 25 grid over
    (log λ, log κ, log ε²) gives, less 0.5 (the grid is coarse: it may be below, not above by much)."""
    rng = np.random.default_rng(12)
    ev = _draw(rng, 12, (0.0, 0.0, 3.0 * SIGMA_V))
    ex = _test(ev)
    X = first_order_design(ev.f_m_s2)
    z = ev.y.reshape(-1)
    base = window_covariance(ev.V, ev.mid_s, NoiseParams(tau2=np.zeros(3), corr_time_s=TC_S))
    scale = SIGMA_V**2
    grid = np.concatenate([[-np.inf], np.linspace(-8.0, 6.0, 24)])

    def neg_reml(lam: float, kap: float, eps: float, i: int) -> float:
        blocks = base.blocks + kap * np.eye(3)
        blocks[:, i, i] += eps
        inv, ld = invert_blocks(blocks)
        wc = replace(base, blocks=blocks, tau2=np.full(3, lam), blocks_inverse=inv, blocks_logdet=ld)
        return -gls(X, z, wc).loglik_reml

    vals = scale * np.exp(grid)
    f0 = min(neg_reml(a, b, 0.0, 0) for a in vals for b in vals)
    f1 = min(neg_reml(a, b, c, 2) for a in vals for b in vals for c in vals)
    assert ex.lr[2] >= 2.0 * (f0 - f1) - 0.5
    assert ex.channel == 2
