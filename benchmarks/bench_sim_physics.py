"""Simulating runs with the truth model, against the cost of just drawing their noise.

Baseline: drawing the same number of (n, 3) standard normals and one matrix product, the
least any simulation of those samples could cost. Read the ratios, not the absolute times.
Also: the same static run streamed in 100-sample blocks (as the simulated DAQ does) against
one call, which must give the same samples.
"""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np

from drivers.sim.offline import (
    DEFAULT_AXES,
    simulate_oscillation,
    simulate_rate_steps,
    simulate_static,
    static12_poses_deg,
)
from drivers.sim.physics import SensorPhysics, SensorTruth

FS_HZ = 100.0
G = 9.81535


def _best_of(fn: Callable[[], object], repeat: int = 3) -> float:
    best = float("inf")
    for _ in range(repeat):
        t0 = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t0)
    return best


def _physics(effects: dict | None = None) -> SensorPhysics:
    truth = SensorTruth.typical("V", seed=1).with_effects(effects or {})
    return SensorPhysics(truth, DEFAULT_AXES, None, G, seed=2, sample_rate_hz=FS_HZ)


def _baseline(n: int) -> float:
    rng = np.random.default_rng(0)
    K = np.eye(3)
    return _best_of(lambda: rng.standard_normal((n, 3)) @ K.T)


def main() -> None:
    """Print times per procedure and their ratio to the noise-drawing baseline."""
    rich = {
        "lever_arm": {"r_m": [0.05, 0.0, 0.01]},
        "sensor_lowpass": {"tau_s": 0.02},
        "settling": {"duration_s": 1.5},
        "nonlinearity_quadratic": {"k2_per_g": [0.0, 0.0, 1.5e-3]},
    }
    cases: list[tuple[str, Callable[[], object]]] = [
        ("static-12, 30 s dwell", lambda: simulate_static(static12_poses_deg(), 30.0, _physics(), FS_HZ)),
        ("static-12 + 4 effects", lambda: simulate_static(static12_poses_deg(), 30.0, _physics(rich), FS_HZ)),
        ("rate-1axis", lambda: simulate_rate_steps(_physics(), FS_HZ)),
        ("oscillation-2axis, 90 s", lambda: simulate_oscillation(_physics(), FS_HZ)),
    ]
    print(f"{'run':28s} {'samples':>8s} {'time s':>8s} {'x baseline':>10s}")
    for label, fn in cases:
        run = fn()
        n = run.t_s.shape[0]  # type: ignore[attr-defined]
        t = _best_of(fn)
        print(f"{label:28s} {n:8d} {t:8.3f} {t / _baseline(n):10.1f}")

    one = simulate_static(static12_poses_deg(), 30.0, _physics(rich), FS_HZ)

    def stream() -> np.ndarray:
        phys = _physics(rich)
        return np.vstack(
            [phys.sample(one.t_s[i : i + 100], one.profile).raw for i in range(0, one.t_s.size, 100)]
        )

    t_one = _best_of(lambda: _physics(rich).sample(one.t_s, one.profile))
    t_stream = _best_of(stream)
    blocks = stream()
    same = np.allclose(blocks, one.raw, rtol=0, atol=1e-12)
    print(
        f"streamed in 100-sample blocks: {t_stream:.3f} s vs one call {t_one:.3f} s (x{t_stream / t_one:.1f})"
    )
    print(f"  identical samples: {same}")
    if not same:
        raise AssertionError("streamed samples differ from the one-call run")
