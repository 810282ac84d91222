"""Shared pieces of the end-to-end tests: settings on a temporary directory, z-scores against truth."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from api.settings import Settings
from drivers.sim.physics import SensorTruth

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


def z_scores(calibration: dict[str, object], truth: SensorTruth) -> np.ndarray:
    """(12,) (fit − truth) / sigma for bias and K."""
    b = np.asarray(calibration["bias"], dtype=float)
    sb = np.asarray(calibration["bias_sigma"], dtype=float)
    k = np.asarray(calibration["scale_matrix"], dtype=float)
    sk = np.asarray(calibration["scale_matrix_sigma"], dtype=float)
    return np.concatenate([(b - truth.bias) / sb, ((k - truth.K) / sk).ravel()])


def difference_z(a: dict[str, object], b: dict[str, object]) -> np.ndarray:
    """(12,) (a − b) / sqrt(σa² + σb²) for bias and K of two fits."""
    out = []
    for key in ("bias", "scale_matrix"):
        va, vb = np.asarray(a[key], dtype=float), np.asarray(b[key], dtype=float)
        sa, sb = np.asarray(a[f"{key}_sigma"], dtype=float), np.asarray(b[f"{key}_sigma"], dtype=float)
        out.append(((va - vb) / np.hypot(sa, sb)).ravel())
    return np.concatenate(out)
