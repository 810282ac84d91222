"""How tight the slow-noise cap is, and how tight any within-window statistic could make it.

``python -m benchmarks.study_wander_cap [N]``:

1. Coverage and tightness on simulated static-12 recordings where the wander is known
   (``tests.support.diagnose_cases.static_recording``: 40 µg Gauss-Markov wander, T_c = 200 s,
   250 µg/√Hz white, 30 s windows; seeds 100…): per channel, the cap τ²_max(T_c = 200 s) of
   ``wander_cap`` over the true τ² (K_ii · 40 µg · g0)², its median and range, and how often
   it falls below the truth (nominal ``cap_alpha`` = 0.001).
2. The information about τ² that a window's samples hold (at τ² → 0, the window's mean taken
   out, white noise σ² per sample): I = ½ tr((M P M)²) / σ⁴ (M = I − 11ᵀ/n, P the Gauss-Markov
   correlation of the samples; Fisher information of a Gaussian covariance parameter, e.g.
   Harville, JASA 72 (1977) 320), against the half-window difference's ½ (g / w)² and the
   leading eigenmodes of M P M (a trend, then a curve). The ratio says how much tighter any
   within-window statistic could make the bound.
"""

from __future__ import annotations

import sys

import numpy as np

from bench.calibration.diagnose import recording_evidence
from bench.diagnosis.evidence import G0_M_S2
from bench.diagnosis.wander_cap import SlowNoiseCap, half_difference_factor
from drivers.sim.physics import SensorTruth
from tests.support.diagnose_cases import static_recording

WANDER_G = 40e-6
CORR_TIME_S = 200.0


def coverage(n: int) -> None:
    """Part 1 of the module docstring."""
    ratios = []
    for seed in range(100, 100 + n):
        ev = recording_evidence(static_recording({}, seed))
        truth = SensorTruth.typical("V", seed=seed)
        tau2 = (np.diag(truth.K) * WANDER_G * G0_M_S2) ** 2
        cap = SlowNoiseCap(ev, 1e-3)(CORR_TIME_S)
        assert cap is not None
        ratios.append(cap / tau2)
    r = np.array(ratios).ravel()
    print(
        f"static-12, {n} seeds x 3 channels: cap / true tau^2 median {np.median(r):.1f}, "
        f"range {r.min():.2f}-{r.max():.1f}, below the truth {int(np.sum(r < 1))} of {r.size}"
    )


def information(fs_hz: float = 100.0, window_s: float = 30.0) -> None:
    """Part 2 of the module docstring."""
    n = int(fs_hz * window_s)
    t = np.arange(n) / fs_hz
    M = np.eye(n) - 1.0 / n
    for tc in (CORR_TIME_S, 600.0):
        MPM = M @ np.exp(-np.abs(t[:, None] - t[None, :]) / tc) @ M
        full = 0.5 * float(np.sum(MPM * MPM))
        g = float(half_difference_factor(np.array([window_s / 2]), tc)[0])
        half = 0.5 * (g / (4.0 / n)) ** 2
        lam = np.sort(np.linalg.eigvalsh(MPM))[::-1]
        share = np.cumsum(lam[:2] ** 2) / np.sum(lam**2)
        print(
            f"{window_s:.0f} s window at {fs_hz:.0f} Hz, T_c = {tc:.0f} s: half-window difference "
            f"holds {half / full:.3f} of the within-window information; the leading mode "
            f"{share[0]:.3f}, two modes {share[1]:.3f}"
        )


if __name__ == "__main__":
    information()
    coverage(int(sys.argv[1]) if len(sys.argv) > 1 else 10)
