"""Overlapping Allan deviation of rate-type data, with chi-squared confidence intervals.

Input is *rate-type* data y (acceleration samples, angular rate, fractional frequency),
sampled at ``sample_rate_hz`` = 1/τ0. With M samples and averaging factor m (τ = m·τ0),
NIST SP1065 eqn (10) gives the overlapping Allan variance

    σ²_y(τ) = 1 / (2 m² (M − 2m + 1)) · Σ_{j=1}^{M−2m+1} [ Σ_{i=j}^{j+m−1} (y_{i+m} − y_i) ]²

Written with the "phase" x_k = τ0 · Σ_{i<k} y_i (k = 0 … M, x_0 = 0) this is SP1065 eqn (11),

    σ²_y(τ) = 1 / (2 τ² (N − 2m)) · Σ_{k=0}^{N−2m−1} (x_{k+2m} − 2 x_{k+m} + x_k)²,   N = M + 1,

which is what is evaluated here: one cumulative sum, then O(M) per τ. The result equals
``allantools.oadev(y, rate=sample_rate_hz, data_type="freq", taus=...)``. Units: σ_y has
the unit of y; τ in seconds.

Confidence intervals (SP1065 §5.3, eqn (45)): σ²·edf/σ̂² is χ²-distributed with edf
equivalent degrees of freedom, so the two-sided interval at level p is

    σ̂·√(edf / χ²_{(1+p)/2}(edf))  ≤  σ  ≤  σ̂·√(edf / χ²_{(1−p)/2}(edf)).

edf comes from the *simple* formulas of SP1065 Table 5 (Howe, Allan & Barnes), which need
the power-law noise type α (S_y(f) ∝ f^α) at each τ. α is identified per τ and channel by
the lag-1 autocorrelation method of Riley & Greenhall (2004), applied to the non-overlapping
τ-averages of y (needs ≥ 30 averages; at most 8 runs of 16384 of them, spread over the
record); at longer τ the last identified α is carried over. The edf is then made
non-increasing in τ (running minimum from short τ to long): a longer τ averages the same
record into fewer independent differences whatever the noise, while a change of identified α
between neighbouring τ can make the Table 5 value jump up (…185, 580, 36…); the smaller,
earlier value is kept.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Literal

import numpy as np
import numpy.typing as npt
from scipy import stats

FloatArray = npt.NDArray[np.float64]
IntArray = npt.NDArray[np.int64]

ONE_SIGMA_LEVEL = 0.682689492137086
"""Probability content of ±1σ of a normal distribution, the default interval level."""

MIN_BLOCKS_FOR_NOISE_ID = 30
"""Riley & Greenhall: the lag-1 ACF noise identification needs at least ~30 averages."""

ID_PIECES = 8
ID_PIECE_LEN = 1 << 14

_CHUNK_ROWS = 1 << 20


@dataclass(frozen=True)
class AllanResult:
    """Overlapping Allan deviation of c channels at m averaging times.

    :param taus_s: (m,) averaging times τ = m_k / sample_rate_hz (s).
    :param adev: (m, c) overlapping Allan deviation, unit of the input.
    :param adev_lo: (m, c) lower end of the confidence interval.
    :param adev_hi: (m, c) upper end of the confidence interval.
    :param n_pairs: (m,) number of overlapping differences N − 2m in the sum.
    :param edf: (m, c) equivalent degrees of freedom used for the interval, non-increasing in τ.
    :param alpha: (m, c) power-law exponent α identified at each τ (2 … −2).
    :param sample_rate_hz: sampling rate of the input (Hz).
    :param n_samples: number of input samples M.
    :param ci_level: probability content of [adev_lo, adev_hi].
    """

    taus_s: FloatArray
    adev: FloatArray
    adev_lo: FloatArray
    adev_hi: FloatArray
    n_pairs: IntArray
    edf: FloatArray
    alpha: IntArray
    sample_rate_hz: float
    n_samples: int
    ci_level: float

    @property
    def n_channels(self) -> int:
        """Number of channels c."""
        return int(self.adev.shape[1])

    @property
    def avar(self) -> FloatArray:
        """(m, c) Allan variance σ²."""
        return self.adev**2


TauSpec = None | Literal["octave", "decade", "all"] | npt.ArrayLike


def averaging_factors(n_samples: int, sample_rate_hz: float, taus_s: TauSpec = None) -> IntArray:
    """Averaging factors m (τ = m/sample_rate_hz) that an M-sample record supports.

    ``None``/``"octave"``: 1, 2, 4, …; ``"decade"``: 1, 2, 4, 10, 20, 40, …; ``"all"``: every m;
    an array of τ (s) is rounded to the nearest m. Only m with at least two overlapping
    differences (M − 2m + 1 ≥ 2) are kept for the keywords; an explicit τ outside that range
    is a ValueError naming it.
    """
    m_max = (n_samples - 1) // 2
    if m_max < 1:
        raise ValueError(f"Allan deviation needs at least 3 samples, got {n_samples}")
    if taus_s is None or (isinstance(taus_s, str) and taus_s == "octave"):
        m = 2 ** np.arange(int(np.floor(np.log2(m_max))) + 1)
    elif isinstance(taus_s, str) and taus_s == "decade":
        decades = 10 ** np.arange(int(np.floor(np.log10(m_max))) + 1)
        m = np.outer(decades, [1, 2, 4]).ravel()
    elif isinstance(taus_s, str) and taus_s == "all":
        m = np.arange(1, m_max + 1)
    elif isinstance(taus_s, str):
        raise ValueError(f"taus_s must be 'octave', 'decade', 'all' or an array of seconds, got {taus_s!r}")
    else:
        tau = np.atleast_1d(np.asarray(taus_s, dtype=float))
        if tau.ndim != 1 or tau.size == 0 or not np.all(np.isfinite(tau)):
            raise ValueError(f"taus_s must be a non-empty 1-D array of finite seconds, got {taus_s!r}")
        m = np.rint(tau * sample_rate_hz)
        bad = (m < 1) | (m > m_max)
        if np.any(bad):
            t_bad = float(tau[np.argmax(bad)])
            raise ValueError(
                f"tau {t_bad:g} s is outside what {n_samples} samples at {sample_rate_hz:g} Hz support "
                f"({1 / sample_rate_hz:g} s to {m_max / sample_rate_hz:g} s)"
            )
    m = np.unique(np.asarray(m, dtype=np.int64))
    return m[(m >= 1) & (m <= m_max)]


def _as_channels(y: npt.ArrayLike) -> FloatArray:
    """(n,) or (n, c) input as a finite (n, c) float array, or a ValueError naming the bad sample."""
    arr = np.asarray(y, dtype=float)
    if arr.ndim == 1:
        arr = arr[:, None]
    if arr.ndim != 2 or arr.shape[1] == 0:
        raise ValueError(f"y must have shape (n,) or (n, c), got {np.shape(y)}")
    finite = np.isfinite(arr)
    if not np.all(finite):
        row, col = np.argwhere(~finite)[0]
        raise ValueError(f"y has a non-finite value ({arr[row, col]}) at sample {row}, channel {col}")
    return arr


def _phase(y: FloatArray) -> FloatArray:
    """(c, n+1) running sums x_k = Σ_{i<k} (y_i − ȳ) per channel, in units of y·τ0.

    Channel-major and contiguous, so every later pass runs over contiguous memory; the mean
    is removed first for precision.
    """
    yc = np.ascontiguousarray(y.T)
    x = np.empty((yc.shape[0], yc.shape[1] + 1))
    x[:, 0] = 0.0
    for c in range(yc.shape[0]):
        np.cumsum(yc[c] - yc[c].mean(), out=x[c, 1:])
    return x


def _sum_sq_second_difference(x: FloatArray, m: int) -> FloatArray:
    """(c,) Σ_k (x_{k+2m} − 2 x_{k+m} + x_k)² over k = 0 … N−2m−1, in chunks of one channel."""
    n_terms = x.shape[1] - 2 * m
    total = np.zeros(x.shape[0])
    buf = np.empty(min(_CHUNK_ROWS, n_terms))
    for c in range(x.shape[0]):
        xc = x[c]
        for start in range(0, n_terms, _CHUNK_ROWS):
            stop = min(start + _CHUNK_ROWS, n_terms)
            d = buf[: stop - start]
            np.subtract(xc[start + 2 * m : stop + 2 * m], xc[start + m : stop + m], out=d)
            d -= xc[start + m : stop + m]
            d += xc[start:stop]
            total[c] += float(np.einsum("i,i->", d, d))
    return total


def _block_means(x: FloatArray, m: int) -> FloatArray:
    """(c, P, L) non-overlapping m-sample means of y, from the running sums x (c, n+1).

    All n // m of them as one piece (P = 1) when there are at most ``ID_PIECES × ID_PIECE_LEN``;
    otherwise ``ID_PIECES`` runs of ``ID_PIECE_LEN`` consecutive means spread evenly over the
    record: the lag-1 ACF of 10⁵ means is known to ±0.003, far inside the δ < 0.25 decision,
    and spreading the runs keeps the whole record represented.
    """
    n_blocks = (x.shape[1] - 1) // m
    if n_blocks <= ID_PIECES * ID_PIECE_LEN:
        starts, length = np.array([0]), n_blocks
    else:
        starts, length = np.linspace(0, n_blocks - ID_PIECE_LEN, ID_PIECES).astype(np.int64), ID_PIECE_LEN
    idx = (starts[:, None] + np.arange(length + 1)[None, :]) * m  # (P, L+1) sample indices
    sums = x[:, idx]
    return np.diff(sums, axis=-1) / m


def _lag1_alpha(z: FloatArray, d_max: int = 2) -> IntArray:
    """(c,) power-law α of (c, P, L) frequency-type series (P pieces) by the lag-1 ACF method.

    Riley & Greenhall, "Power law noise identification using the lag 1 autocorrelation",
    EFTF 2004: difference until δ = r1/(1 + r1) < 0.25 (at most d_max times), then
    α = round(−2(δ + d)); r1 pools the lag products of all pieces.
    """
    alpha = np.zeros(z.shape[0], dtype=np.int64)
    for c in range(z.shape[0]):
        s = z[c]
        for d in range(d_max + 1):
            s0 = s - s.mean(axis=-1, keepdims=True)
            denom = float(np.einsum("pi,pi->", s0, s0))
            r1 = float(np.einsum("pi,pi->", s0[:, :-1], s0[:, 1:])) / denom if denom > 0 else 0.0
            delta = r1 / (1.0 + r1) if r1 > -1.0 else -np.inf
            if delta < 0.25 or d == d_max:
                alpha[c] = int(np.clip(np.rint(-2.0 * (delta + d)), -2, 2))
                break
            s = np.diff(s, axis=-1)
    return alpha


def edf_simple(n_phase: int, m: int, alpha: npt.ArrayLike) -> FloatArray:
    """Equivalent degrees of freedom of the overlapping Allan variance, SP1065 Table 5.

    :param n_phase: number of phase points N (= samples of rate data + 1).
    :param m: averaging factor.
    :param alpha: power-law exponent(s) α ∈ {2, 1, 0, −1, −2}.
    :returns: edf, same shape as alpha, at least 1.
    """
    N, mf = float(n_phase), float(m)
    a = np.asarray(alpha)
    white_pm = (N + 1) * (N - 2 * mf) / (2 * (N - mf))
    la = np.log(max((N - 1) / (2 * mf), 1.0 + 1e-12))
    lb = np.log(max((2 * mf + 1) * (N - 1) / 4, 1.0 + 1e-12))
    flicker_pm = np.exp(np.sqrt(la * lb))
    white_fm = (3 * (N - 1) / (2 * mf) - 2 * (N - 2) / N) * (4 * mf**2 / (4 * mf**2 + 5))
    flicker_fm = 2 * (N - 2) / (2.3 * N - 4.9) if m == 1 else 5 * N**2 / (4 * mf * (N + 3 * mf))
    rw_fm = (N - 2) / (mf * (N - 3) ** 2) * ((N - 1) ** 2 - 3 * mf * (N - 1) + 4 * mf**2)
    table = {2: white_pm, 1: flicker_pm, 0: white_fm, -1: flicker_fm, -2: rw_fm}
    edf = np.vectorize(lambda al: table[int(al)], otypes=[float])(a)
    return np.asarray(np.maximum(edf, 1.0), dtype=float)


def chi2_interval(dev: FloatArray, edf: FloatArray, level: float) -> tuple[FloatArray, FloatArray]:
    """(lo, hi) of a deviation with edf degrees of freedom at probability ``level`` (SP1065 eqn (45))."""
    p_lo = (1.0 - level) / 2.0
    lo = dev * np.sqrt(edf / stats.chi2.ppf(1.0 - p_lo, edf))
    hi = dev * np.sqrt(edf / stats.chi2.ppf(p_lo, edf))
    return lo, hi


def overlapping_allan(
    y: npt.ArrayLike,
    sample_rate_hz: float,
    taus_s: TauSpec = None,
    ci_level: float = ONE_SIGMA_LEVEL,
) -> AllanResult:
    """Overlapping Allan deviation (SP1065 eqn (10)/(11)) of each column of y, with intervals.

    :param y: (n,) or (n, c) rate-type samples, evenly spaced, finite.
    :param sample_rate_hz: 1/τ0 (Hz), finite and > 0.
    :param taus_s: ``None``/``"octave"``, ``"decade"``, ``"all"`` or an array of τ (s); see
        :func:`averaging_factors`.
    :param ci_level: probability content of the interval (default ±1σ, 68.27 %).
    :returns: :class:`AllanResult`; ``adev`` is (m, c) even for 1-D input.
    """
    if not (np.isfinite(sample_rate_hz) and sample_rate_hz > 0):
        raise ValueError(f"sample_rate_hz must be finite and > 0, got {sample_rate_hz}")
    if not 0.0 < ci_level < 1.0:
        raise ValueError(f"ci_level must be in (0, 1), got {ci_level}")
    data = _as_channels(y)
    n = data.shape[0]
    ms = averaging_factors(n, sample_rate_hz, taus_s)
    x = _phase(data)
    n_phase = n + 1
    c = data.shape[1]
    adev = np.empty((ms.size, c))
    edf = np.empty((ms.size, c))
    alpha = np.empty((ms.size, c), dtype=np.int64)
    last_alpha = np.zeros(c, dtype=np.int64)
    for k, m in enumerate(ms):
        s = _sum_sq_second_difference(x, int(m))
        adev[k] = np.sqrt(s / (2.0 * (n_phase - 2 * m))) / m
        n_blocks = n // m
        if n_blocks >= MIN_BLOCKS_FOR_NOISE_ID:
            last_alpha = _lag1_alpha(_block_means(x, int(m)))
        alpha[k] = last_alpha
        edf[k] = edf_simple(n_phase, int(m), last_alpha)
    edf = np.minimum.accumulate(edf, axis=0)
    lo, hi = chi2_interval(adev, edf, ci_level)
    return AllanResult(
        taus_s=ms / float(sample_rate_hz),
        adev=adev,
        adev_lo=lo,
        adev_hi=hi,
        n_pairs=(n_phase - 2 * ms).astype(np.int64),
        edf=edf,
        alpha=alpha,
        sample_rate_hz=float(sample_rate_hz),
        n_samples=n,
        ci_level=ci_level,
    )
