"""Orientation-free (|f| = g) fit: z-scores of b and L against the truth when windows misfit.

Window means of a sensor b + K f over m random orientations (f = g along a random direction),
each with its own white noise of ``SD`` per axis (the batch-means covariance is given to the
fit), and one kind of misfit the window noise does not show:

- ``clean``: none;
- ``motion``: a fraction ``FRACTION`` of the windows carries a random acceleration inside the
  "still" window (isotropic, ``MOTION_M_S2`` per axis), as on a free-living day;
- ``pose-motion``: motion (``MOTION_M_S2`` per axis) in every window near one pose (within 45°
  of +x) and in no other, so the scatter follows the design's leverage;
- ``pose``: a fixed error in the windows near one pose only (pointing within 45° of +x: ``POSE_M_S2``
  added to the magnitude), so the misfit follows the design's leverage.

Per case: RMS of the z-scores of the 9 parameters (b, L; L Lᵀ = K Kᵀ, the truth's L from its
LQ factor) over the seeds and the largest |z|, for the fit's covariance (``ScalarFit.cov``,
Paule–Mandel excess and the window sandwich floor).

    python -m benchmarks.study_sigmas_scalar CASE WINDOWS SEEDS
"""

from __future__ import annotations

import sys

import numpy as np

from bench.estimation.scalar_fit import _TRIL, fit_scalar

G_M_S2 = 9.81
SD = 2e-4
"""White noise of a window mean per axis (channel units, here m/s²-like with K ≈ 1)."""
FRACTION = 0.1
MOTION_M_S2 = 0.02
POSE_M_S2 = 0.01


def truth(rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """A bias (3,) of ~0.05 and K (3, 3) within 2 % of 1 with 0.5 % cross terms."""
    return rng.normal(0, 0.05, 3), np.eye(3) + np.diag(rng.normal(0, 0.02, 3)) + rng.normal(0, 0.005, (3, 3))


def windows(case: str, m: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(y (m, 3), V (m, 3, 3), θ_true (9,)) of one simulated session."""
    b, K = truth(rng)
    u = rng.normal(size=(m, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    f = G_M_S2 * u
    if case == "motion":
        hit = rng.random(m) < FRACTION
        f = f + hit[:, None] * rng.normal(0, MOTION_M_S2, (m, 3))
    elif case == "pose":
        f = f + (POSE_M_S2 * (u[:, 0] > np.cos(np.pi / 4)))[:, None] * u
    elif case == "pose-motion":
        hit = u[:, 0] > np.cos(np.pi / 4)
        f = f + hit[:, None] * rng.normal(0, MOTION_M_S2, (m, 3))
    elif case != "clean":
        raise ValueError(f"unknown case {case!r}: clean, motion, pose-motion or pose")
    y = b + f @ K.T + rng.normal(0, SD, (m, 3))
    V = np.tile(np.eye(3) * SD**2, (m, 1, 1))
    _, r = np.linalg.qr(K.T)
    L = r.T * np.sign(np.diag(r))[None, :]
    return y, V, np.concatenate([b, L[_TRIL]])


def z_scores(case: str, m: int, seeds: int) -> np.ndarray:
    """(seeds, 9) z-scores of b and L against the truth."""
    out = []
    for seed in range(seeds):
        y, V, th = windows(case, m, np.random.default_rng(seed))
        fit = fit_scalar(y, V, G_M_S2)
        est = np.concatenate([fit.bias, fit.L[_TRIL]])
        out.append((est - th) / fit.sigma)
    return np.array(out)


if __name__ == "__main__":
    case, m, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    z = z_scores(case, m, n)
    print(
        f"{case}: {m} windows, {n} seeds: z RMS {np.sqrt(np.mean(z**2)):.2f}, max |z| {np.abs(z).max():.1f}"
    )
    print("per parameter RMS:", " ".join(f"{v:.2f}" for v in np.sqrt(np.mean(z**2, axis=0))))
