"""Why the Allan fit admits a Gauss–Markov term on curves without a wander: each route measured.

On the ``whiterw`` (white N and rate random walk K) or ``powerlaw`` (also flicker B) records
of ``benchmarks.study_sigmas_allan``, per curve (``seeds`` records × 3 channels):

* the covariance the GLS uses, at the truth: χ² of σ̂² about the true model under
  C = D·R·D (edf and the overlapping estimates' correlation, ``allan_correlation``), against
  χ² of m points; and per τ the variance, mean and skew of (σ̂² − σ²)/(σ²·√(2/edf)) over the
  curves (1, 0, 0 if the covariance is right and σ̂² Gaussian);
* the term's likelihood ratio against the power-law model chosen without it (Q and R by
  ``select_terms``): Δχ²(T_c) on the profile grid, the share above 5.41 at each fixed T_c
  (the ½χ²₀ + ½χ²₁ law's 1 %) and of its maximum over T_c;
* the route by which the former selection (backward elimination from the full model, every
  term kept where χ² fails its 95 % point) admitted the term: ``gate`` (χ² failed, the term
  > 0), ``beside Q/R`` (χ² held, the maximum Δχ² against the power-law model below 5.41,
  but the term stayed with Q or R), ``test`` (maximum ≥ 5.41);
* the share the selection as built admits (``noise_gls.select_with_gauss_markov``).

    python -m benchmarks.study_gm_admission [seeds] [seconds] [whiterw|powerlaw]
"""

from __future__ import annotations

import math
import sys

import numpy as np
from scipy import stats

from bench.estimation import noise_gls as gls
from bench.estimation.allan import overlapping_allan
from bench.estimation.allan_covariance import allan_correlation, cholesky_ridged, forward_solve
from bench.estimation.noise_terms import first_fit_index, fit_noise_model_curve
from benchmarks.study_sigmas_allan import B_FLICKER, FS_HZ, K_RRW, N_WHITE, record

ALL = [0, 1, 2, 3, 4, gls.GM]
POWER_LAW = [0, 1, 2, 3, 4]


def truth_p(sensor: str) -> np.ndarray:
    """(5,) [Q², N², B², K², R²] of the study's sensor."""
    b2 = B_FLICKER**2 if sensor == "powerlaw" else 0.0
    return np.array([0.0, N_WHITE**2, b2, K_RRW**2, 0.0])


def curve(t: np.ndarray, s2: np.ndarray, nu: np.ndarray, sensor: str) -> dict[str, object]:
    """The measures of the module doc for one curve (τ (m,) s, σ̂² (m,), edf (m,))."""
    tau0 = 1.0 / FS_HZ
    p = truth_p(sensor)
    model = gls.basis(t)[:, :5] @ p
    d = model * np.sqrt(2.0 / nu)
    L = cholesky_ridged(allan_correlation(t, p, tau0) * d[:, None] * d[None, :])
    w = forward_solve(L, (s2 - model)[:, None])[:, 0]
    full_pl = gls.fit_terms(t, s2, nu, POWER_LAW, tau0, 6)
    base = gls.select_terms(t, s2, nu, POWER_LAW, tau0, 6, full_pl, gls.POWER_LAW_OPTIONAL)
    f0 = gls.fit_terms(t, s2, nu, base, tau0, 6)
    act = sorted([*base, gls.GM])
    lo, hi = gls.tc_range_s(t)
    grid = np.exp(np.arange(math.log(lo), math.log(hi) + 1e-9, math.log(2.0) / gls.TC_GRID_PER_OCTAVE))
    delta = []
    for tc in grid:
        g = gls.gls(t, s2, nu, gls.basis(t, tc)[:, act], act, tau0, 0.0, 6, 0.0, tc)
        delta.append((f0.chi2 - g.chi2) / max(1.0, g.chi2 / g.dof))
    full = gls.fit_terms(t, s2, nu, ALL, tau0, 6)
    holds = full.chi2 <= stats.chi2.ppf(gls.MISFIT_LEVEL, full.dof)
    former = gls.select_terms(t, s2, nu, ALL, tau0, 6, full) if holds else ALL
    fit = full if former == ALL else gls.fit_terms(t, s2, nu, former, tau0, 6)
    admitted = gls.GM in former and fit.p[former.index(gls.GM)] > 0.0
    d_max = float(max(delta))
    route = (
        ""
        if not admitted
        else ("gate" if not holds else ("test" if d_max >= gls.SELECT_DELTA_CHI2 else "beside Q/R"))
    )
    return {"chi2_truth": float(w @ w), "z": (s2 - model) / d, "delta": np.array(delta), "grid": grid,
            "d_max": d_max, "route": route}  # fmt: skip


def main(seeds: int, seconds: float, sensor: str) -> None:
    """Print the measures of the module doc over ``seeds`` records × 3 channels."""
    rows, built = [], []
    for seed in range(seeds):
        r = overlapping_allan(record(seed, int(seconds * FS_HZ), False, sensor), FS_HZ)
        for c in range(3):
            start = first_fit_index(r.adev[:, c])
            t, s2, nu = r.taus_s[start:], r.adev[start:, c] ** 2, np.maximum(r.edf[start:, c], 1.0)
            rows.append(curve(t, s2, nu, sensor))
            f = fit_noise_model_curve(r.taus_s, r.adev[:, c], r.edf[:, c], tau0_s=1.0 / FS_HZ)
            built.append(f.gauss_markov_level > 0.0)
    m = min(len(x["z"]) for x in rows)  # type: ignore[arg-type]
    n = len(rows)
    chi2_t = np.array([x["chi2_truth"] for x in rows])
    print(f"{seconds:g} s, {sensor}: {n} curves, the last {m} points of each")
    print(f"covariance at the truth: χ² mean {chi2_t.mean():.1f} on {m} points, "
          f"above its 95 % point on {np.mean(chi2_t > stats.chi2.ppf(0.95, m)):.1%}")  # fmt: skip
    z = np.array([np.asarray(x["z"])[-m:] for x in rows])
    print("per τ (last m), variance of the standardised σ̂²:", np.round(z.var(axis=0), 2).tolist())
    print("per τ, mean:", np.round(z.mean(axis=0), 2).tolist())
    print("per τ, skew:", np.round(stats.skew(z, axis=0), 2).tolist())
    k = min(len(x["delta"]) for x in rows)  # type: ignore[arg-type]
    delta = np.array([np.asarray(x["delta"])[:k] for x in rows])
    grid = np.asarray(rows[0]["grid"])[:k]
    above = np.mean(delta >= gls.SELECT_DELTA_CHI2, axis=0)
    at_max = np.mean(delta.max(axis=1) >= gls.SELECT_DELTA_CHI2)
    worst = f"{above.max():.1%} (T_c {grid[int(np.argmax(above))]:.3g} s)"
    print(f"Δχ² ≥ 5.41 at one T_c: at most {worst}, 0 at {int(np.sum(above == 0))} of {k}; "
          f"at the maximum over T_c {at_max:.1%}")  # fmt: skip
    routes = [str(x["route"]) for x in rows]
    print("former selection: admitted on " + f"{np.mean([bool(r_) for r_ in routes]):.1%}: "
          + ", ".join(f"{name} {routes.count(name)}" for name in ("gate", "beside Q/R", "test")))  # fmt: skip
    print(f"selection as built: admitted on {np.mean(built):.1%} ({int(np.sum(built))} of {n})")


if __name__ == "__main__":
    main(
        int(sys.argv[1]) if len(sys.argv) > 1 else 10,
        float(sys.argv[2]) if len(sys.argv) > 2 else 10_000.0,
        sys.argv[3] if len(sys.argv) > 3 else "whiterw",
    )
