"""Honest sigmas of the static calibration on long recordings: split halves and z-scores against truth.

A long hand-placed session (a day's worth of static windows) is simulated at the level of
the window means, which is what ``static_fit`` sees: a triad with bias b and scale K, m
windows at random orientations spread over ``hours``, each window's mean

    y_w = b + K R(δ_w) f_w + K (s(t_w) + c (T(t_w) − T̄)) + e_w,

with R(δ_w) a hand-placement error (a rotation by two random angles about axes perpendicular
to f_w, ``pose_rad`` rms), s(t) a first-order
Gauss-Markov wander of every channel (``wander_m_s2`` rms, correlation time ``wander_tau_s``),
T(t) a daily temperature swing (±``temp_amp_c`` over 24 h) reaching the bias through a
temperature coefficient ``tc_m_s2_per_c``, and e_w the window's own noise with its known
covariance V_w. The truth the calibration is scored against is b (the bias at the session's
mean temperature T̄) and K (1 − σ_δ²): a tilt shortens the reading along gravity by cos|δ|,
which no calibration without the angles can tell from the scale (with 0.01 rad placement
errors that is 1e-4 of K, several sigmas of a long session; the default is 0.003 rad).

For each recording the calibration is run on all windows and on the two halves of the
session in time (disjoint windows, different temperatures and wander). Reported: the spread
(standard deviation) of z = (estimate − truth) / sigma over all 12 parameters and all
recordings, for the fit with the window times (``mid_s``: correlated wander) and without them
(independent between-window errors); and the largest |difference of the halves| / sigma.

Run: ``python -m benchmarks.study_long_recording [n_recordings]``.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from bench.estimation.static_fit import StaticFit, fit_static

G = 9.80665


@dataclass(frozen=True)
class LongSession:
    """Simulation settings (module docstring)."""

    m: int = 400
    hours: float = 20.0
    window_s: float = 10.0
    rate_hz: float = 30.0
    white_m_s2_rt_hz: float = 250e-6 * G
    wander_m_s2: float = 4e-4
    wander_tau_s: float = 3600.0
    temp_amp_c: float = 5.0
    tc_m_s2_per_c: float = 1e-4
    pose_rad: float = 0.003


def simulate(cfg: LongSession, seed: int) -> dict[str, np.ndarray]:
    """One session: f (m, 3), y (m, 3), V (m, 3, 3), mid_s (m,), truth b (3,) and K (3, 3)."""
    rng = np.random.default_rng(seed)
    m = cfg.m
    K = np.diag(1.0 + 0.01 * rng.standard_normal(3)) + 1e-3 * rng.standard_normal((3, 3)) * (1 - np.eye(3))
    b = 0.2 * rng.standard_normal(3)
    d = rng.standard_normal((m, 3))
    fh = d / np.linalg.norm(d, axis=1, keepdims=True)
    f = G * fh
    t = np.sort(rng.uniform(0.0, cfg.hours * 3600.0, m))
    # hand placement: small rotation about two axes perpendicular to f̂
    e = np.eye(3)[np.argmin(np.abs(fh), axis=1)]
    u1 = np.cross(e, fh)
    u1 /= np.linalg.norm(u1, axis=1, keepdims=True)
    u2 = np.cross(fh, u1)
    a = cfg.pose_rad * rng.standard_normal((m, 2))
    tilted = fh + a[:, :1] * u1 + a[:, 1:] * u2
    f_true = G * tilted / np.linalg.norm(tilted, axis=1, keepdims=True)  # a rotation: |f| stays g
    # Gauss-Markov wander at the window times (exact discretisation)
    s = np.empty((m, 3))
    s[0] = cfg.wander_m_s2 * rng.standard_normal(3)
    for w in range(1, m):
        rho = np.exp(-(t[w] - t[w - 1]) / cfg.wander_tau_s)
        s[w] = rho * s[w - 1] + cfg.wander_m_s2 * np.sqrt(1 - rho**2) * rng.standard_normal(3)
    temp = cfg.temp_amp_c * np.sin(2 * np.pi * t / 86400.0 + rng.uniform(0, 2 * np.pi))
    thermal = cfg.tc_m_s2_per_c * (temp - temp.mean())[:, None] * np.ones(3)
    n = cfg.window_s * cfg.rate_hz
    sig = cfg.white_m_s2_rt_hz * np.sqrt(cfg.rate_hz / 2.0) / np.sqrt(n)  # σ of a window mean (m/s²)
    Vd = (sig * np.diag(K)) ** 2 * (1.0 + 0.1 * rng.uniform(size=(m, 3)))
    V = np.zeros((m, 3, 3))
    V[:, np.arange(3), np.arange(3)] = Vd
    y = b + (f_true + s + thermal) @ K.T + np.sqrt(Vd) * rng.standard_normal((m, 3))
    # a random tilt shortens the reading along f by cos|δ| (E = 1 − pose_rad², two angles):
    # no calibration without the angles can tell that from K, so the truth scored is K (1 − σ²)
    K_seen = K * (1.0 - cfg.pose_rad**2)
    return {"f": f, "y": y, "V": V, "mid_s": t, "b": b, "K": K_seen}


def _z(fit: StaticFit, b: np.ndarray, K: np.ndarray) -> np.ndarray:
    return (fit.params - np.concatenate([b, K.ravel()])) / fit.sigma


def study(n: int, cfg: LongSession = LongSession()) -> dict[str, float]:
    """z spreads (with and without window times) and the worst halves disagreement, in sigmas."""
    z_corr, z_ind, split = [], [], []
    for seed in range(n):
        r = simulate(cfg, seed)
        z_corr.append(_z(fit_static(r["f"], r["y"], r["V"], mid_s=r["mid_s"]), r["b"], r["K"]))
        z_ind.append(_z(fit_static(r["f"], r["y"], r["V"]), r["b"], r["K"]))
        h = cfg.m // 2
        parts = [
            fit_static(r["f"][sl], r["y"][sl], r["V"][sl], mid_s=r["mid_s"][sl])
            for sl in (slice(0, h), slice(h, cfg.m))
        ]
        diff = (parts[0].params - parts[1].params) / np.hypot(parts[0].sigma, parts[1].sigma)
        split.append(diff)
    zc, zi, sp = np.array(z_corr), np.array(z_ind), np.array(split)
    return {
        "z_spread_correlated": float(np.std(zc)),
        "z_spread_independent": float(np.std(zi)),
        "z_max_correlated": float(np.max(np.abs(zc))),
        "z_max_independent": float(np.max(np.abs(zi))),
        "halves_spread": float(np.std(sp)),
        "halves_max": float(np.max(np.abs(sp))),
    }


def main() -> None:
    """Print the study (module docstring)."""
    n = int(sys.argv[1]) if len(sys.argv) > 1 else 20
    cfg = LongSession()
    print(
        f"{n} sessions of {cfg.m} windows over {cfg.hours:.0f} h: wander {cfg.wander_m_s2:.1e} m/s² "
        f"({cfg.wander_tau_s:.0f} s), temperature ±{cfg.temp_amp_c} °C daily at {cfg.tc_m_s2_per_c:.0e} "
        f"m/s²/°C, placement {cfg.pose_rad} rad rms"
    )
    for k, v in study(n, cfg).items():
        print(f"  {k:24s} {v:.2f}")


if __name__ == "__main__":
    main()
