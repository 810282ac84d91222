"""What a simulated unit truly is: bias, scale/misalignment K, catalogue effects, noise, ageing.

First-order model (``docs/cli-contract.md``): raw = bias + K·f, bias in channel units, K in
channel units per m/s². Effects beyond it are keyed by the catalogue's ids with the
catalogue's parameter names and units; they are validated here, applied in
``drivers/sim/physics.py``, and their equations are collected in ``docs/physics-model.md``.

Ageing (:meth:`SensorTruth.aged`) is a random walk per channel, deterministic per seed
and consistent across calls (the same seed gives one path through the days):

    bias_i(d)  = bias_i + K_ii·σ_b·W_i(d),      σ_b = 30 µg/√day
    K_ij(d)    = K_ij·(1 + σ_s·V_i(d)),          σ_s = 10 ppm/√day

W, V standard Wiener processes sampled on whole days, linear in between.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from drivers.sim.bench_effects import BENCH_EFFECT_PARAMETERS
from drivers.sim.noise import NoiseSpec

FloatArray = npt.NDArray[np.float64]
G0_M_S2 = 9.80665
"""Standard gravity (m/s²): the unit ``g`` and the g0 of the catalogue's formulas."""

BIAS_AGEING_M_S2_PER_RT_DAY = 30e-6 * G0_M_S2
"""Bias random walk of an ageing unit (m/s² per √day)."""
SCALE_AGEING_PER_RT_DAY = 10e-6
"""Relative scale random walk of an ageing unit (per √day)."""
_AGEING_STREAM = 0xA6E

EFFECT_PARAMETERS: dict[str, dict[str, tuple[int, ...]]] = {
    "lever_arm": {"r_m": (3,)},
    "proof_mass_offsets": {"rho_m": (3, 3)},
    "nonlinearity_quadratic": {"k2_per_g": (3,)},
    "scale_asymmetry": {"delta": (3,)},
    "cross_coupling": {"c_per_g": (3, 3)},
    "temperature_bias": {"tc_m_s2_per_c": (3,)},
    "bias_drift": {"drift_m_s2_per_s": (3,)},
    "time_skew": {"delay_s": ()},
    "table_tilt": {"tilt_rad": (2,)},
    "pose_error": {"angles_rad": (-1, 2)},
    "encoder_offset": {"offset_deg": (-1,)},
    "sensor_lowpass": {"tau_s": ()},
    "settling": {"duration_s": ()},
    **BENCH_EFFECT_PARAMETERS,
}
"""Catalogue of ``docs/cli-contract.md`` and the bench physics beyond it (``bench_effects``):
effect id -> parameter name -> shape (−1: any length)."""

_NOMINAL = {
    # channel unit: (nominal scale per m/s², nominal zero-g output, converter step)
    "V": (0.174 / G0_M_S2, 1.5, 3.0 / 65536),
    "count": (0.174 / G0_M_S2 * 65536 / 3.0, 32768.0, 1.0),
    "m/s2": (1.0, 0.0, 0.0),
    "g": (1.0 / G0_M_S2, 0.0, 0.0),
}


def check_effects(effects: dict[str, dict[str, Any]]) -> dict[str, dict[str, FloatArray]]:
    """Validate catalogue effects and return them as float arrays.

    :raises ValueError: unknown effect or parameter, wrong shape, non-finite value.
    """
    out: dict[str, dict[str, FloatArray]] = {}
    for effect, params in effects.items():
        if effect not in EFFECT_PARAMETERS:
            raise ValueError(f"unknown effect {effect!r}; known: {', '.join(EFFECT_PARAMETERS)}")
        expected = EFFECT_PARAMETERS[effect]
        if set(params) != set(expected):
            raise ValueError(
                f"effect {effect!r}: parameters {sorted(params)} given, expected exactly {sorted(expected)}"
            )
        out[effect] = {}
        for name, shape in expected.items():
            try:
                value = np.array(params[name], dtype=float)
            except (TypeError, ValueError) as exc:
                raise ValueError(f"effect {effect!r}: {name} is not numeric: {params[name]!r}") from exc
            ok = value.ndim == len(shape) and all(
                e in (-1, s) for e, s in zip(shape, value.shape, strict=True)
            )
            if not ok:
                raise ValueError(f"effect {effect!r}: {name} has shape {value.shape}, expected {shape}")
            if not np.all(np.isfinite(value)):
                raise ValueError(f"effect {effect!r}: {name} must be finite, got {params[name]!r}")
            out[effect][name] = value
    for effect, name in (
        ("sensor_lowpass", "tau_s"),
        ("settling", "duration_s"),
        ("thermal_lag", "tau_s"),
        ("encoder_hold", "step_deg"),
    ):
        if effect in out and out[effect][name] <= 0:
            raise ValueError(f"effect {effect!r}: {name} must be > 0, got {float(out[effect][name])}")
    return out


@dataclass(frozen=True)
class SensorTruth:
    """The true parameters of a simulated accelerometer triad.

    :param bias: (3,) zero-input output (channel units).
    :param K: (3, 3) scale/misalignment (channel units per m/s²): raw = bias + K·f.
    :param channel_unit: ``V``, ``count``, ``m/s2`` or ``g``.
    :param effects: catalogue effects, ``{effect id: {parameter: value}}``.
    :param noise: the noise specification.
    """

    bias: FloatArray
    K: FloatArray
    channel_unit: str = "V"
    effects: dict[str, dict[str, Any]] = field(default_factory=dict)
    noise: NoiseSpec = field(default_factory=NoiseSpec)

    def __post_init__(self) -> None:
        bias = np.array(self.bias, dtype=float).reshape(-1)
        K = np.array(self.K, dtype=float)
        if bias.shape != (3,) or K.shape != (3, 3):
            raise ValueError(f"SensorTruth: bias must be (3,) and K (3, 3), got {bias.shape} and {K.shape}")
        if not (np.all(np.isfinite(bias)) and np.all(np.isfinite(K))):
            raise ValueError("SensorTruth: bias and K must be finite")
        if abs(np.linalg.det(K)) < 1e-12 * abs(np.prod(np.diag(K))) or np.any(np.diag(K) == 0):
            raise ValueError(f"SensorTruth: K is singular: {K.tolist()}")
        if self.channel_unit not in _NOMINAL:
            raise ValueError(f"SensorTruth: channel_unit {self.channel_unit!r} not in {list(_NOMINAL)}")
        check_effects(self.effects)
        object.__setattr__(self, "bias", bias)
        object.__setattr__(self, "K", K)

    def effect_arrays(self) -> dict[str, dict[str, FloatArray]]:
        """The effects as validated float arrays."""
        return check_effects(self.effects)

    def with_effects(self, effects: dict[str, dict[str, Any]]) -> SensorTruth:
        """The same unit with ``effects`` in place of its current ones."""
        return replace(self, effects=dict(effects))

    def with_noise(self, noise: NoiseSpec) -> SensorTruth:
        """The same unit with another noise specification."""
        return replace(self, noise=noise)

    @classmethod
    def typical(cls, channel_unit: str = "V", seed: int = 0) -> SensorTruth:
        """A realistic ADXL325-like triad (174 mV/g at 1.5 V zero-g, ±6 g).

        Per seed: scale within ~1 % of nominal, zero-g offset ~25 mg (1 σ), misalignment
        and cross-axis ~1e-3 of the diagonal. Noise: 250 µg/√Hz white (data sheet), a
        40 µg Gauss-Markov bias wander with a 200 s correlation time, the converter step
        of a 16-bit converter over 3 V (``V``, ``count``), clipping at 6 g.
        """
        if channel_unit not in _NOMINAL:
            raise ValueError(f"typical: channel_unit {channel_unit!r} not in {list(_NOMINAL)}")
        scale, zero, lsb = _NOMINAL[channel_unit]
        rng = np.random.default_rng(np.random.SeedSequence([seed, 0x7E1]))
        diag = scale * (1.0 + 0.01 * rng.standard_normal(3))
        K = np.diag(diag) + scale * 1e-3 * rng.standard_normal((3, 3)) * (1 - np.eye(3))
        bias = zero + diag * 25e-3 * G0_M_S2 * rng.standard_normal(3)
        noise = NoiseSpec(
            white_m_s2_rt_hz=250e-6 * G0_M_S2,
            bias_instability_m_s2=40e-6 * G0_M_S2,
            bias_instability_tau_s=200.0,
            quantization_lsb=lsb,
            saturation_m_s2=6.0 * G0_M_S2,
        )
        return cls(bias=bias, K=K, channel_unit=channel_unit, noise=noise)

    def aged(self, days: float, seed: int) -> SensorTruth:
        """The unit ``days`` later: bias and scale moved along a seeded random walk (module docstring)."""
        if not math.isfinite(days) or days < 0:
            raise ValueError(f"aged: days must be finite and >= 0, got {days!r}")
        n_days = math.ceil(days)
        rng = np.random.default_rng(np.random.SeedSequence([seed, _AGEING_STREAM]))
        steps = rng.standard_normal((n_days, 6))
        path = np.vstack([np.zeros((1, 6)), np.cumsum(steps, axis=0)])
        lo = math.floor(days)
        frac = days - lo
        w = path[lo] if frac == 0 else (1 - frac) * path[lo] + frac * path[lo + 1]
        diag = np.diag(self.K)
        bias = self.bias + diag * BIAS_AGEING_M_S2_PER_RT_DAY * w[:3]
        K = self.K * (1.0 + SCALE_AGEING_PER_RT_DAY * w[3:])[:, None]
        return replace(self, bias=bias, K=K)
