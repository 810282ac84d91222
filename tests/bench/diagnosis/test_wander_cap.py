"""The slow-noise cap (``bench.diagnosis.wander_cap``): the white noise's share of the half-window
differences is taken out, per channel, and the bound still covers the true level."""

from __future__ import annotations

from decimal import Decimal, localcontext

import numpy as np
from scipy.stats import binom
from scipy.stats import chi2 as chi2_dist

from bench.diagnosis.wander_cap import half_difference_factor, upper_bound


def _draws(rng: np.random.Generator, tau2: float, g: np.ndarray, w: np.ndarray) -> np.ndarray:
    return (tau2 * g + w) * rng.standard_normal(g.shape) ** 2


def test_bound_solves_its_equation_and_never_exceeds_the_white_blind_bound() -> None:
    rng = np.random.default_rng(3)
    m = 24
    g = half_difference_factor(rng.uniform(5.0, 20.0, m), 600.0)
    w = rng.uniform(0.5, 2.0, m) * 1e-8
    q = float(chi2_dist.ppf(1e-3, m))
    for tau2 in (0.0, 1e-8, 1e-6):
        d2 = _draws(rng, tau2, g, w)
        b = upper_bound(d2, g, w, q)
        blind = float(np.sum(d2 / g)) / q
        assert 0.0 <= b <= blind
        if b > 0:  # independent: the equation of the docstring holds at the root
            assert np.isclose(float(np.sum(d2 / (b * g + w))), q, rtol=1e-5)
    # no white noise: the white-blind closed form
    d2 = _draws(rng, 1e-6, g, np.zeros(m))
    assert np.isclose(upper_bound(d2, g, np.zeros(m), q), float(np.sum(d2 / g)) / q)


def test_bound_covers_the_true_level_at_its_confidence() -> None:
    """Over 400 draws at α = 0.05 the bound falls below the true τ² in about 5 %; 400 · 0.05 = 20
    expected, and the test allows up to the binomial 99.9 % point (a margin over the nominal rate,
    not the measured one). The white-blind bound is looser by the white noise's share."""
    rng = np.random.default_rng(11)
    m, reps, alpha = 24, 400, 0.05
    g = half_difference_factor(rng.uniform(5.0, 20.0, m), 600.0)
    w = rng.uniform(0.5, 2.0, m) * 1e-8
    tau2 = 2e-7  # wander share of d² comparable to the white share
    q = float(chi2_dist.ppf(alpha, m))
    below = 0
    ratios = []
    for _ in range(reps):
        d2 = _draws(rng, tau2, g, w)
        b = upper_bound(d2, g, w, q)
        below += b < tau2
        ratios.append(b / (float(np.sum(d2 / g)) / q))
    assert below <= binom.ppf(0.999, reps, alpha)
    assert below >= binom.ppf(0.001, reps, alpha)  # not trivially loose
    assert np.median(ratios) < 0.95


def test_factor_at_long_correlation_times_matches_exact_arithmetic() -> None:
    """g(h, T) against its closed form evaluated in 80-digit decimal arithmetic, from halves a
    millionth of T (a day's recording with T_c of a few spans: in double precision the closed
    form's cancellation there exceeds g and once made it negative) to halves far longer than T."""

    def exact(x: float) -> float:
        with localcontext() as ctx:
            ctx.prec = 80
            d = Decimal(repr(x))
            return float(2 * (2 * d - 3 + 4 * (-d).exp() - (-2 * d).exp()) / (d * d))

    x = np.array([1e-9, 1e-7, 1e-6, 1e-5, 9.9e-4, 1e-3, 0.01, 0.1, 0.5, 1.0, 3.0, 50.0, 1e4])
    g = half_difference_factor(x * 2.0e5, 2.0e5)
    want = np.array([exact(float(v)) for v in x * 2.0e5 / 2.0e5])
    assert np.all(g > 0)
    np.testing.assert_allclose(g, want, rtol=1e-7)
    np.testing.assert_allclose(g[x < 1e-3], want[x < 1e-3], rtol=1e-13)
