"""Sensor noise: its specification and a streaming, seeded generator.

All noise is input-referred (m/s², added to the specific force before saturation and
conversion); quantisation and saturation are listed here because they are part of the
same data-sheet description of a channel.

Processes, per axis (IEEE Std 952 / 1293 terms; Allan-deviation signatures from
El-Sheimy et al., *IEEE Trans. Instrum. Meas.* 57(1), 2008):

- white noise (velocity random walk) of density N = ``white_m_s2_rt_hz`` (m/s²/√Hz):
  per-sample standard deviation N·√f_s; σ_A(τ) = N/√τ.
- bias instability modelled as first-order Gauss-Markov with standard deviation
  B = ``bias_instability_m_s2`` and correlation time T_c = ``bias_instability_tau_s``:
  x_k = φ·x_{k−1} + B·√(1 − φ²)·w_k, φ = exp(−Δt/T_c), x_0 ~ N(0, B²) (exact discretisation).
- random walk of the bias (rate random walk) K = ``random_walk_m_s2_s_rt_hz`` in
  m/s² per √s (= m/s³/√Hz): b_k = b_{k−1} + K·√Δt·w_k, b_0 = 0 at the stream's first
  sample; σ_A(τ) = K·√(τ/3).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.signal import lfilter

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class NoiseSpec:
    """Noise of one triad, identical on the three axes.

    :param white_m_s2_rt_hz: white-noise density N (m/s²/√Hz).
    :param bias_instability_m_s2: Gauss-Markov standard deviation B (m/s²).
    :param bias_instability_tau_s: Gauss-Markov correlation time T_c (s).
    :param random_walk_m_s2_s_rt_hz: bias random-walk coefficient K (m/s² per √s).
    :param quantization_lsb: converter step in channel units; 0 = not quantised.
    :param saturation_m_s2: full-scale specific force (m/s²); 0 = no clipping.
    """

    white_m_s2_rt_hz: float = 1e-3
    bias_instability_m_s2: float = 0.0
    bias_instability_tau_s: float = 100.0
    random_walk_m_s2_s_rt_hz: float = 0.0
    quantization_lsb: float = 0.0
    saturation_m_s2: float = 0.0

    def __post_init__(self) -> None:
        for name in (
            "white_m_s2_rt_hz",
            "bias_instability_m_s2",
            "random_walk_m_s2_s_rt_hz",
            "quantization_lsb",
            "saturation_m_s2",
        ):
            value = getattr(self, name)
            if not math.isfinite(value) or value < 0:
                raise ValueError(f"NoiseSpec: {name} must be finite and >= 0, got {value!r}")
        if not math.isfinite(self.bias_instability_tau_s) or self.bias_instability_tau_s <= 0:
            raise ValueError(
                f"NoiseSpec: bias_instability_tau_s must be > 0, got {self.bias_instability_tau_s!r}"
            )

    @classmethod
    def silent(cls) -> NoiseSpec:
        """No noise, no quantisation, no saturation."""
        return cls(white_m_s2_rt_hz=0.0)


class NoiseStream:
    """Continues the noise processes across consecutive blocks of samples.

    :param spec: the noise specification.
    :param rng: generator owned by this stream (one normal draw per sample and process).
    :param sample_rate_hz: rate that sets the white-noise bandwidth; ``None`` takes it from
        the first block's median sample spacing.
    """

    def __init__(self, spec: NoiseSpec, rng: np.random.Generator, sample_rate_hz: float | None) -> None:
        self.spec = spec
        self._rng_white, self._rng_gm, self._rng_rw = rng.spawn(3)
        self._rate_hz = sample_rate_hz
        self._t_last: float | None = None
        self._gm_last = np.zeros(3)
        self._rw_last = np.zeros(3)

    def next(self, t_s: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Noise for the next block of time stamps ``t_s`` (n,), m/s².

        :returns: (white, wander), each (n, 3): the white part and the slow bias wander
            (Gauss-Markov + random walk); the sensor sees their sum.
        """
        t = np.asarray(t_s, dtype=float)
        n = t.shape[0]
        white = np.zeros((n, 3))
        out = np.zeros((n, 3))
        if n == 0:
            return white, out
        first = self._t_last is None
        dt = np.diff(t, prepend=t[0] if self._t_last is None else self._t_last)
        spec = self.spec
        if spec.white_m_s2_rt_hz > 0:
            if self._rate_hz is None:
                if n < 2:
                    raise ValueError("NoiseStream: sample_rate_hz unknown and the first block has one sample")
                self._rate_hz = 1.0 / float(np.median(np.diff(t)))
            white += (
                spec.white_m_s2_rt_hz * math.sqrt(self._rate_hz) * self._rng_white.standard_normal((n, 3))
            )
        if spec.bias_instability_m_s2 > 0:
            out += self._gauss_markov(dt, first)
        if spec.random_walk_m_s2_s_rt_hz > 0:
            steps = (
                spec.random_walk_m_s2_s_rt_hz * np.sqrt(dt)[:, None] * self._rng_rw.standard_normal((n, 3))
            )
            walk = self._rw_last + np.cumsum(steps, axis=0)
            self._rw_last = walk[-1].copy()
            out += walk
        self._t_last = float(t[-1])
        return white, out

    def _gauss_markov(self, dt: FloatArray, first: bool) -> FloatArray:
        b, tau = self.spec.bias_instability_m_s2, self.spec.bias_instability_tau_s
        w = self._rng_gm.standard_normal((dt.shape[0], 3))
        phi = np.exp(-dt / tau)
        if first and phi.shape[0] > 1:
            phi[0] = phi[1]  # the first sample has no predecessor: its φ is never used
        drive = b * np.sqrt(1.0 - phi * phi)[:, None] * w
        if first:
            drive[0] = b * w[0]  # stationary start
            prev = np.zeros(3)
        else:
            prev = self._gm_last
        if np.allclose(phi, phi[-1], rtol=0, atol=1e-15):
            x, _ = lfilter([1.0], [1.0, -phi[-1]], drive, axis=0, zi=(phi[-1] * prev)[None, :])
        else:
            x = np.empty_like(drive)
            for i in range(dt.shape[0]):
                prev = phi[i] * prev + drive[i]
                x[i] = prev
        self._gm_last = np.asarray(x[-1], dtype=float).copy()
        return np.asarray(x, dtype=float)
