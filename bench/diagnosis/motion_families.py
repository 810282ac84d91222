"""Bench physics in a moving recording's final residual: disturbances locked to a table axis's
angle, a delay that grows along the run (two clocks drifting), periodic lines.

r (n, 3) is what the final model (catalogue and discovered terms) leaves per sample. Each
family is a set of columns X on one channel; it is judged beside the first-order nuisance
N = [1, f_x, f_y, f_z] (f the final model's specific force: whatever bias and K absorb of a
family is estimated again with it, Frisch–Waugh) with the residual's own coloured noise
modelled by an autoregression: per channel an AR(p) fitted by Yule–Walker (p = ``th.ar_order``)
to r less its least-squares fit on N (and, for the drift, the delay's column), and r, N and
X filtered by e_t = x_t − Σ φ_k x_{t−k} (prewhitening, Cochrane & Orcutt 1949). On the
filtered data, ordinary least squares: the coefficients' covariance s²·(XᵀM_N X)⁻¹ with s²
the filtered residual variance, and the F statistic of the columns against F(q, n − p).

- **Angle harmonics** (``angle_harmonic``): X = [sin hθ_j, cos hθ_j] for every axis j that
  turns through more than ``th.min_turn_rad`` and h = 1 … ``th.harmonics`` (a motor's field, a cable's pull, a
  slip ring: locked to the axis's angle, not to time). Greedy forward over (axis, harmonic,
  channel), each step at ``th.bench_false_alarm`` divided over the 3·k·H candidates, at most
  ``th.max_harmonic_terms``. Reported per (axis, harmonic): A·sin(hθ + φ) per channel, A and φ with sigmas.
- **Clock drift** (``clock_drift``): the DAQ clock runs at a rate 1 + ρ against the
  encoders', so the sensor saw the table at t − d(t), d(t) = d₀ + ρ·t, and to first order
  r_i = −(K ḟ)_i·d(t): columns −(K ḟ)_i·(t − t̄) (the growth) and −(K ḟ)_i (the mean delay,
  a nuisance here: ``time_skew`` holds it when the catalogue claimed it) on every channel
  with one ρ shared by the three (one clock). Filtered per channel, combined by their
  normal equations; ρ is claimed when ρ²/σ_ρ² passes χ²₁ at ``th.bench_false_alarm``.
- **Periodic lines** (``periodic_line``, ``periodic_lines.find_periodic_lines``) in r less
  the families above.

``find_families`` runs the harmonics, then the drift on what they leave; ``Families.signal``
is what they put on the samples (the drift's growth only: the mean delay is ``time_skew``'s).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.linalg import solve_toeplitz
from scipy.stats import chi2 as chi2_dist
from scipy.stats import f as f_dist

from bench.diagnosis.thresholds import THRESHOLDS, Thresholds

FloatArray = np.ndarray


@dataclass(frozen=True)
class Harmonic:
    """A disturbance locked to axis ``axis`` (0-based) at harmonic ``harmonic``: A_i sin(hθ + φ_i).

    :param amplitude: (3,) channel units; :param amplitude_sigma: (3,); :param phase_rad: (3,).
    :param channels: channels on which it passed its test; :param f_stat: the largest F.
    """

    axis: int
    harmonic: int
    amplitude: FloatArray
    amplitude_sigma: FloatArray
    phase_rad: FloatArray
    channels: tuple[int, ...]
    f_stat: float


@dataclass(frozen=True)
class ClockDrift:
    """ρ (s per s) and its sigma; ``wald`` = ρ²/σ²."""

    rate_s_per_s: float
    sigma: float
    wald: float


def ar_filter(r: FloatArray, order: int) -> FloatArray:
    """(order + 1,) prewhitening filter [1, −φ₁, …, −φ_p] of a series r (n,) (Yule–Walker)."""
    x = r - r.mean()
    n = x.size
    acf = np.array([x[: n - k] @ x[k:] / n for k in range(order + 1)])
    if acf[0] <= 0:
        return np.array([1.0])
    phi = solve_toeplitz(acf[:order], acf[1 : order + 1])
    return np.concatenate([[1.0], -phi])


def _whiten(a: FloatArray, coef: FloatArray) -> FloatArray:
    from scipy.signal import lfilter  # moving recordings only: a static path stays without it

    p = coef.size - 1
    return np.asarray(lfilter(coef, [1.0], a, axis=0)[p:], dtype=float)


def _project(N: FloatArray, A: FloatArray) -> FloatArray:
    return np.asarray(A - N @ np.linalg.lstsq(N, A, rcond=None)[0], dtype=float)


def harmonic_columns(angles_rad: FloatArray, axis: int, h: int) -> FloatArray:
    """(n, 2) sin hθ, cos hθ of one axis."""
    th = h * angles_rad[:, axis]
    return np.column_stack([np.sin(th), np.cos(th)])


def search_harmonics(
    r: FloatArray, f: FloatArray, angles_rad: FloatArray, th: Thresholds = THRESHOLDS
) -> tuple[Harmonic, ...]:
    """Greedy forward search of angle harmonics (module docstring).

    :param r: (n, 3) residual; :param f: (n, 3) specific force (m/s²); :param angles_rad: (n, k).
    """
    axes = [j for j in range(angles_rad.shape[1]) if np.ptp(angles_rad[:, j]) > th.min_turn_rad]
    if not axes:
        return ()
    cands = [(j, h) for j in axes for h in range(1, th.harmonics + 1)]
    alpha = th.bench_false_alarm / (3 * len(cands))
    white = []
    N0 = np.column_stack([np.ones(r.shape[0]), f])
    for i in range(3):
        coef = ar_filter(_project(N0, r[:, i]), th.ar_order)
        N = _whiten(N0, coef)
        white.append((coef, N, _whiten(r[:, i], coef)))
    chosen: list[tuple[int, int, int]] = []
    stats: dict[tuple[int, int, int], float] = {}
    while len(chosen) < th.max_harmonic_terms:
        best: tuple[float, tuple[int, int, int]] | None = None
        for i in range(3):
            coef, N, y = white[i]
            base = [N] + [_whiten(harmonic_columns(angles_rad, j, h), coef) for (j, h, c) in chosen if c == i]
            N1 = np.column_stack(base)
            y1 = _project(N1, y)
            dof = y1.size - N1.shape[1] - 2
            for j, h in cands:
                if (j, h, i) in chosen:
                    continue
                X = _project(N1, _whiten(harmonic_columns(angles_rad, j, h), coef))
                b = np.linalg.lstsq(X, y1, rcond=None)[0]
                fit = X @ b
                rss = float((y1 - fit) @ (y1 - fit))
                F = float(fit @ fit) / 2.0 / (rss / dof)
                if f_dist.sf(F, 2, dof) < alpha and (best is None or best[0] < F):
                    best = (F, (j, h, i))
        if best is None:
            break
        chosen.append(best[1])
        stats[best[1]] = best[0]
    if not chosen:
        return ()
    out = []
    for j, h in sorted({(j, h) for j, h, _ in chosen}):
        A, sA, ph = np.zeros(3), np.zeros(3), np.zeros(3)
        for i in range(3):
            coef, N, y = white[i]
            others = [
                _whiten(harmonic_columns(angles_rad, jj, hh), coef)
                for jj, hh, c in chosen
                if c == i and (jj, hh) != (j, h)
            ]
            X = _whiten(harmonic_columns(angles_rad, j, h), coef)
            Z = np.column_stack([X, N, *others])
            b, *_ = np.linalg.lstsq(Z, y, rcond=None)
            res = y - Z @ b
            s2 = float(res @ res) / (y.size - Z.shape[1])
            C = s2 * np.linalg.inv(Z.T @ Z)[:2, :2]
            a_, c_ = b[0], b[1]  # A sin(hθ + φ) = A cos φ sin hθ + A sin φ cos hθ
            A[i] = float(np.hypot(a_, c_))
            g = np.array([a_, c_]) / max(A[i], 1e-300)
            sA[i] = float(np.sqrt(max(g @ C @ g, 0.0)))
            ph[i] = float(np.arctan2(c_, a_))
        chans = tuple(sorted(i for jj, hh, i in chosen if (jj, hh) == (j, h)))
        F = max(stats[(j, h, i)] for i in chans)
        out.append(Harmonic(j, h, A, sA, ph, chans, F))
    return tuple(out)


def harmonic_signal(hs: tuple[Harmonic, ...], angles_rad: FloatArray) -> FloatArray:
    """(n, 3) Σ A_i sin(hθ_j + φ_i) of the harmonics found."""
    out = np.zeros((angles_rad.shape[0], 3))
    for h in hs:
        out += h.amplitude * np.sin(h.harmonic * angles_rad[:, h.axis][:, None] + h.phase_rad)
    return out


def clock_drift(
    r: FloatArray, f: FloatArray, Kfdot: FloatArray, t: FloatArray, th: Thresholds = THRESHOLDS
) -> ClockDrift:
    """ρ of a delay growing along the run (module docstring).

    :param Kfdot: (n, 3) K·ḟ, the raw output's rate of change from the model (channel units / s).
    :param t: (n,) time (s).
    """
    tc = t - t.mean()
    num = den = 0.0
    for i in range(3):
        N0 = np.column_stack([np.ones(t.size), f, -Kfdot[:, i]])
        coef = ar_filter(_project(N0, r[:, i]), th.ar_order)
        N = _whiten(N0, coef)
        x = _project(N, _whiten(-Kfdot[:, i] * tc, coef))
        y = _project(N, _whiten(r[:, i], coef))
        b = float(x @ y) / float(x @ x)
        res = y - b * x
        s2 = float(res @ res) / (y.size - N.shape[1] - 1)
        num += float(x @ y) / s2
        den += float(x @ x) / s2
    rho = num / den
    sig = float(np.sqrt(1.0 / den))
    return ClockDrift(rho, sig, rho * rho / (sig * sig))


def drift_passes(cd: ClockDrift, th: Thresholds = THRESHOLDS) -> bool:
    """The growth of the delay passes χ²₁ at ``th.bench_false_alarm``."""
    return bool(chi2_dist.sf(cd.wald, 1) < th.bench_false_alarm)


@dataclass(frozen=True)
class Families:
    """The angle harmonics and the delay's growth found on one residual.

    :param harmonics: as :func:`search_harmonics`; :param drift: the growth when it passes, else ``None``.
    :param t_mean_s: t̄ of the drift's column (s): the mean time of the samples it was fitted on.
    """

    harmonics: tuple[Harmonic, ...]
    drift: ClockDrift | None
    t_mean_s: float

    @property
    def empty(self) -> bool:
        """Nothing found."""
        return not self.harmonics and self.drift is None

    @property
    def n_params(self) -> int:
        """Parameters the families carry: 2 per harmonic and channel, 1 for the growth."""
        return 2 * sum(len(h.channels) for h in self.harmonics) + (self.drift is not None)

    def signal(self, angles_rad: FloatArray, Kfdot: FloatArray, t_s: FloatArray) -> FloatArray:
        """(n, 3) what the families put on the samples: Σ A_i sin(hθ_j + φ_i) − ρ·(t − t̄)·K ḟ.

        :param angles_rad: (n, k); :param Kfdot: (n, 3) K·ḟ (channel units / s); :param t_s: (n,) (s).
        """
        out = harmonic_signal(self.harmonics, angles_rad)
        if self.drift is not None:
            out = out - self.drift.rate_s_per_s * (t_s - self.t_mean_s)[:, None] * Kfdot
        return out


def find_families(
    r: FloatArray,
    f: FloatArray,
    Kfdot: FloatArray,
    angles_rad: FloatArray,
    t: FloatArray,
    th: Thresholds = THRESHOLDS,
) -> Families:
    """Harmonics on r, then the delay's growth on what they leave (module docstring).

    :param r: (n, 3) residual; :param f: (n, 3) specific force (m/s²); :param Kfdot: (n, 3) K·ḟ;
    :param angles_rad: (n, k); :param t: (n,) time (s), all on the samples the fit used.
    """
    hs = search_harmonics(r, f, angles_rad, th)
    cd = clock_drift(r - harmonic_signal(hs, angles_rad), f, Kfdot, t, th)
    return Families(hs, cd if drift_passes(cd, th) else None, float(t.mean()))
