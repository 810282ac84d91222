"""The closed-form floors the planner passes designs over with, and the closest design it
reports when no design meets the targets."""

from __future__ import annotations

import numpy as np
import pytest

from bench.planning.evaluation import Fit, Targets, evaluate
from bench.planning.information import wander_bound_bias
from bench.planning.noise import UnitNoise
from bench.planning.search import DWELL_GRID_S, FAMILY, Designs, plan
from bench.procedures.planned import MAX_WINDOWS
from bench.procedures.preview import DEFAULT_TABLE_LIMITS, preview

G = 9.80665
UG = 1e-6 * G
ADXL = UnitNoise.from_ug(250, 40, 200)


@pytest.mark.parametrize("step_s", [10.0, 1.0, 0.5])
def test_the_wander_bound_is_below_the_ar1_mean_and_its_limit(step_s: float) -> None:
    """Var of the best linear unbiased mean of n AR(1) samples, 1/(1ᵀΣ⁻¹1) by a matrix inverse,
    is at least B²·2T_c/(T + 2T_c) with T = n·Δ, and tends to it as Δ → 0."""
    B, tau, T = 40 * UG, 200.0, 600.0
    n = round(T / step_s)
    lag = np.abs(np.subtract.outer(np.arange(n), np.arange(n))) * step_s
    cov = B**2 * np.exp(-lag / tau)
    var = 1.0 / float(np.ones(n) @ np.linalg.solve(cov, np.ones(n)))
    bound = wander_bound_bias(B, tau, T)
    assert var >= bound**2
    assert var <= bound**2 * (1.0 + 0.5 * step_s / tau + 1e-9)  # the gap closes as Δ → 0
    assert wander_bound_bias(0.0, tau, T) == 0.0


NOISES = [
    ADXL,
    UnitNoise(250 * UG, 40 * UG, 200.0, random_walk_m_s2_rt_s=1 * UG),
    UnitNoise.from_ug(20, 1, 100),
]


@pytest.mark.parametrize("fit", ["window", "every-sample"])
@pytest.mark.parametrize("dwell_s, reps", [(2.0, 1), (2.0, 3), (10.0, 2), (60.0, 1)])
def test_no_prediction_is_below_its_floor(fit: Fit, dwell_s: float, reps: int) -> None:
    for noise in NOISES:
        designs = Designs(noise, DEFAULT_TABLE_LIMITS, 2.0, G, True, fit)
        e, f = designs.evaluate(dwell_s, reps), designs.floor(dwell_s, reps)
        u = e.predicted
        assert min(u.k_rms, u.scale, u.misalignment) >= f.k and u.bias >= f.bias_m_s2
        # and not far below: the white bound of the record the fit weighs (the every-sample fit
        # weighs all of it, the window fit its dwells; the wander adds the rest)
        assert u.k_rms < (1.5 if fit == "every-sample" else 3.0) * f.k
        # fewer passes, a higher floor
        if reps > 1:
            fewer = designs.floor(dwell_s, reps - 1)
            assert fewer.k > f.k and fewer.bias_m_s2 >= f.bias_m_s2


def _closest_of_all(noise: UnitNoise, fit: Fit, max_duration_s: float) -> tuple[dict[str, object], float]:
    """Every dwell's longest design within the cap evaluated: the parameters and RMS σ(K_ij) of
    the least, the first on a tie."""
    found: tuple[float, dict[str, object]] | None = None
    for dwell in DWELL_GRID_S:
        reps = min(MAX_WINDOWS // 12, int(max_duration_s // 60))  # a pass takes over 60 s
        while reps >= 1:
            proc = FAMILY[fit](dwell_s=dwell, repeats=reps)
            if preview(proc, DEFAULT_TABLE_LIMITS).duration_s <= max_duration_s:
                break
            reps -= 1
        if reps < 1:
            continue
        e = evaluate(proc, noise, fit=fit)
        if found is None or e.predicted.k_rms < found[0]:
            found = (e.predicted.k_rms, dict(e.procedure.parameters))
    assert found is not None
    return found[1], found[0]


@pytest.mark.parametrize(
    "fit, targets, minutes",
    [
        ("window", Targets(scale=1e-6), 10.0),  # the white-noise bound rules it out
        ("window", Targets(misalignment_rad=0.5e-6, scale=30e-6), 20.0),
        # 2·N/√T = 14 ug: only the wander's bound (2·25 ug over 20 min) rules it out
        ("window", Targets(bias_m_s2=20 * UG), 20.0),
        ("every-sample", Targets(scale=1e-6), 3.0),
        ("every-sample", Targets(bias_m_s2=20 * UG), 3.0),
    ],
)
def test_a_target_no_design_meets_names_the_closest_of_every_dwells_longest_design(
    fit: Fit, targets: Targets, minutes: float
) -> None:
    got = plan(ADXL, targets, max_duration_s=minutes * 60, fits=(fit,))
    assert got.best is None and got.closest is not None
    params, k_rms = _closest_of_all(ADXL, fit, minutes * 60)
    assert got.closest.procedure.parameters == params
    assert got.closest.predicted.k_rms == pytest.approx(k_rms, rel=1e-12)
    assert f"within {minutes:.0f} min meets" in got.problems[0]


def test_no_plan_is_longer_than_its_cap() -> None:
    """The design chosen, or the closest when none meets, lasts at most ``max_duration_s``
    (a 120-s dwell's one pass takes 25 min: it is no candidate within 3 min)."""
    for minutes in (3.0, 10.0):
        for scale_ppm in (60.0, 40.0, 20.0, 1.0):
            got = plan(ADXL, Targets(scale=scale_ppm * 1e-6), max_duration_s=minutes * 60)
            e = got.best if got.best is not None else got.closest
            assert e is not None and e.duration_s <= minutes * 60, (minutes, scale_ppm, e and e.duration_s)
    none = plan(ADXL, Targets(scale=60e-6), max_duration_s=30.0)  # shorter than any one pass
    assert none.best is None and none.closest is None
    assert none.problems == ("no planned design fits within 0.5 min (one pass of the shortest dwell)",)
