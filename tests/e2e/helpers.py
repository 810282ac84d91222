"""Shared pieces of the end-to-end tests: settings on a temporary directory, z-scores against truth."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.fitted_model import FittedModel
from drivers.sim.physics import SensorTruth
from station.settings import Settings

RATE_HZ = 100.0
SIM_SPEED = 25.0
"""Simulation speed of the end-to-end runs: 2 500 samples/s over Modbus, a simulated ring of
4 800 samples lasting ~2 s of wall time, and a run needing about a fifth of a core, so
two test workers on two loaded cores keep up with margin."""


def wall_budget_s(sim_s: float, speed: float = SIM_SPEED) -> float:
    """A wall-clock deadline for ``sim_s`` simulated seconds of bench work: ten times the
    nominal wall time plus 30 s (start-up, a loaded machine), never a fixed guess."""
    return 30.0 + 10.0 * sim_s / speed


def settings_for(tmp_path: Path, database_url: str | None = None, bench_name: str = "bench-e2e") -> Settings:
    """Settings writing into ``tmp_path`` (SQLite there unless ``database_url``)."""
    return Settings(
        data_dir=tmp_path,
        database_url=database_url or f"sqlite:///{tmp_path / 'calbench.db'}",
        sim_sample_rate_hz=RATE_HZ,
        bench_name=bench_name,
    )


def z_scores(fit: FittedModel, truth: SensorTruth) -> np.ndarray:
    """(12,) (fit − truth) / sigma for bias and K."""
    return np.concatenate(
        [(fit.bias - truth.bias) / fit.bias_sigma, ((fit.K - truth.K) / fit.K_sigma).ravel()]
    )


def difference_z(a: FittedModel, b: FittedModel) -> np.ndarray:
    """(12,) (a − b) / sqrt(σa² + σb²) for bias and K of two fits."""
    db = (a.bias - b.bias) / np.hypot(a.bias_sigma, b.bias_sigma)
    dk = (a.K - b.K) / np.hypot(a.K_sigma, b.K_sigma)
    return np.concatenate([db, dk.ravel()])
