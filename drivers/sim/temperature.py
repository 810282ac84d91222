"""Sensor temperature during a run: self-heating warm-up plus the lab's air-conditioning cycle.

    T(t) = ambient_c + warmup_rise_c·(1 − exp(−t/warmup_tau_s))
           + cycle_amplitude_c·sin(2π·t/cycle_period_s + cycle_phase_rad)

t in seconds since the run's start. The reading adds white noise of ``reading_noise_c``
(°C) from a generator owned by the model, so consecutive blocks continue one stream.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True)
class TemperatureModel:
    """Deterministic temperature course of the sensor (°C).

    Defaults: a 23 °C lab, 2 °C of self-heating with a 10-minute time constant, a ±0.3 °C
    air-conditioning cycle of 30 minutes.
    """

    ambient_c: float = 23.0
    warmup_rise_c: float = 2.0
    warmup_tau_s: float = 600.0
    cycle_amplitude_c: float = 0.3
    cycle_period_s: float = 1800.0
    cycle_phase_rad: float = 0.0
    reading_noise_c: float = 0.0

    def __post_init__(self) -> None:
        for name, value in vars(self).items():
            if not math.isfinite(value):
                raise ValueError(f"TemperatureModel: {name} must be finite, got {value!r}")
        if self.warmup_tau_s <= 0 or self.cycle_period_s <= 0 or self.reading_noise_c < 0:
            raise ValueError(
                "TemperatureModel: warmup_tau_s and cycle_period_s must be > 0, reading_noise_c >= 0"
            )

    @classmethod
    def constant(cls, temp_c: float) -> TemperatureModel:
        """A sensor held at ``temp_c``."""
        return cls(ambient_c=temp_c, warmup_rise_c=0.0, cycle_amplitude_c=0.0)

    def true_c(self, t_s: FloatArray) -> FloatArray:
        """True sensor temperature (°C) at times ``t_s`` (n,) (s since the run's start)."""
        t = np.asarray(t_s, dtype=float)
        warm = self.warmup_rise_c * -np.expm1(-t / self.warmup_tau_s)
        cycle = self.cycle_amplitude_c * np.sin(
            2.0 * math.pi * t / self.cycle_period_s + self.cycle_phase_rad
        )
        return self.ambient_c + warm + cycle

    def reading_c(self, t_s: FloatArray, rng: np.random.Generator) -> FloatArray:
        """What the temperature channel reads: the true value plus reading noise."""
        t = np.asarray(t_s, dtype=float)
        true = self.true_c(t)
        if self.reading_noise_c == 0:
            return true
        return true + self.reading_noise_c * rng.standard_normal(t.shape)
