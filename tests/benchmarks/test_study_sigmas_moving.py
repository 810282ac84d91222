"""The moving-table study's rates (``benchmarks/study_sigmas_moving.py``), sampled.

Margins are the issue's acceptance (RMS z 0.8–1.25, no |z| > 5) widened by the sampling
spread of an RMS over the values drawn: about ±1/√(2N) per standard error for N values of a
normal z, doubled for the heavier tails a short run's noise estimate gives.
"""

from __future__ import annotations

import numpy as np
import pytest

from benchmarks.study_sigmas_moving import summary, z_scores


def test_planned_tumble_bias_budget_covers_the_long_run_bias_sampled() -> None:
    """6 seeds of the 3-minute planned tumble (18 bias values, 54 K values): the budget's bias
    lines that need no refit (the fit's sigma against the run's mean and the unit's wander over
    the run) give a long-run bias RMS z of 0.45–1.55; the fit's run-mean sigma against the run's
    mean 0.45–1.55; K 0.6–1.4; no |z| above 5."""
    s = summary([z_scores("tumble", "clean", seed) for seed in range(6)])
    assert 0.45 < s["rms_bias_long_core"] < 1.55, s
    assert 0.45 < s["rms_bias_run_own"] < 1.55, s
    assert 0.6 < s["rms_K"] < 1.4, s
    assert max(s["max_K"], s["max_bias_long_core"]) < 5.0, s


@pytest.mark.slow
@pytest.mark.timeout(3600)
@pytest.mark.parametrize("kind", ["rate", "oscillation", "tumble", "tumble-independent"])
def test_moving_bias_budget_and_k_sigmas_over_seeds(kind: str) -> None:
    """24 seeds per kind, the independent simulator's tumble included (72 bias values, 216 K
    values): long-run bias RMS z with the budget's
    bias lines 0.7–1.35, K 0.75–1.3, no |z| above 5."""
    out = [z_scores(kind, "clean", seed) for seed in range(100, 124)]
    s = summary(out)
    assert 0.7 < s["rms_bias_long_core"] < 1.35, s
    assert 0.75 < s["rms_K"] < 1.3, s
    assert max(s["max_K"], s["max_bias_long_core"]) < 5.0, s
    assert np.isfinite(s["median_worst12"])
