"""Cost of calibrating and diagnosing a long free-living recording, against its length.

A free-living recording is what a wrist- or body-worn logger writes over a day: no table, no
segments, so the orientation of every still period is unknown (``docs/recording-format.md``,
``table`` absent) and the reader finds the still periods itself; ``calibrate`` then runs the
orientation-free (scalar) fit and ``diagnose`` the orientation-free pipeline.

The recording (:func:`free_living_recording`), in g at :data:`RATE_HZ` with a temperature
column: still periods of log-normal length (median :data:`STILL_MEDIAN_S`) in orientations
uniform on the sphere, separated by movement of log-normal length (median
:data:`MOVE_MEDIAN_S`) in which gravity's direction turns smoothly from one still orientation to
the next while a walking-like 1.8 Hz acceleration of 0.1–0.4 g and broadband jerks are added;
white noise :data:`NOISE_G` g rms per channel; an offset that wanders as a random walk
(:data:`WANDER_G_PER_SQRT_H` g/√h) and follows the temperature (:data:`TEMPCO_G_PER_C` g/°C
per channel), the temperature a day's cycle of ±3 °C about 30 °C plus slow noise; values
written to 1e-5 g (and 0.01 °C), as loggers write them.

Each length is written to a temporary directory in calbench-recording/1, then
``calbench calibrate REC.csv --json`` and ``calbench diagnose REC.csv --json`` run in fresh
processes; printed per command: hours, n (samples), windows (the still periods found, ``choose_windows``),
wall s, CPU s (user + system) and peak RSS MB of the child alone (``os.wait4``, as in
``bench_recording_size``), then the growth exponent a of CPU ∝ n^a over the lengths.

Run: ``python -m benchmarks free_living`` (5, 10 and 20 h); other lengths in hours as
arguments (``python -m benchmarks.bench_free_living 1 2``).
"""

from __future__ import annotations

import json
import math
import os
import sys
import tempfile
from pathlib import Path

import numpy as np

from bench.calibration.windows import choose_windows
from bench.recording import Recording, Sidecar
from bench.recording.writer import write_recording
from benchmarks.bench_recording_size import ChildCost, command_argv, growth_exponent, run_child

RATE_HZ = 35.0
"""Sample rate of the logger (Hz): 20 h are 2.52 M samples."""
LENGTHS_H = (5.0, 10.0, 20.0)
STILL_MEDIAN_S = 8.0
"""Median length of a still period (s); log-normal with σ_ln = 0.8."""
MOVE_MEDIAN_S = 7.0
"""Median length of the movement between two still periods (s); log-normal with σ_ln = 0.9."""
NOISE_G = 2.5e-3
"""White noise per channel (g rms at 35 Hz)."""
WANDER_G_PER_SQRT_H = 2e-4
"""Random-walk offset per channel (g/√h)."""
TEMPCO_G_PER_C = (3e-4, -2e-4, 5e-4)
"""Offset temperature coefficient per channel (g/°C)."""
K_TRUE = np.array([[1.012, 0.004, -0.003], [0.0, 0.991, 0.006], [0.0, 0.0, 1.004]])
"""Scale and misalignment (g per g), upper triangular."""
B_TRUE = np.array([0.021, -0.013, 0.008])
"""Offset at 30 °C (g)."""
G_LOCAL_M_S2 = 9.81


def _unit(v: np.ndarray) -> np.ndarray:
    return np.asarray(v / np.linalg.norm(v, axis=-1, keepdims=True), dtype=float)


def free_living_recording(hours: float, seed: int = 7) -> Recording:
    """A simulated free-living recording of about ``hours`` (module docstring), without a table
    or segments; time, accelerometer in g, temperature in °C."""
    rng = np.random.default_rng(np.random.SeedSequence([seed, 0xF1]))
    n = round(hours * 3600.0 * RATE_HZ)
    dt = 1.0 / RATE_HZ
    t = np.arange(n) * dt
    # alternate still and moving periods until n samples are covered
    lengths: list[int] = []
    total = 0
    while total < n:
        still = max(1, round(math.exp(math.log(STILL_MEDIAN_S) + 0.8 * rng.normal()) * RATE_HZ))
        move = max(2, round(math.exp(math.log(MOVE_MEDIAN_S) + 0.9 * rng.normal()) * RATE_HZ))
        lengths += [still, move]
        total += still + move
    bounds = np.cumsum([0, *lengths])
    m = len(lengths) // 2
    dirs = _unit(rng.normal(size=(m + 1, 3)))  # gravity's direction in the sensor frame, per still period
    up = np.empty((bounds[-1], 3))
    walk = np.zeros(bounds[-1])
    for i in range(m):
        s0, s1, s2 = bounds[2 * i], bounds[2 * i + 1], bounds[2 * i + 2]
        up[s0:s1] = dirs[i]
        k = s2 - s1
        ramp = 0.5 - 0.5 * np.cos(np.pi * np.arange(1, k + 1) / (k + 1))  # smooth turn
        wobble = (
            0.3 * np.sin(2 * np.pi * rng.uniform(0.1, 0.5) * np.arange(k) * dt)[:, None] * rng.normal(size=3)
        )
        up[s1:s2] = _unit((1 - ramp)[:, None] * dirs[i] + ramp[:, None] * dirs[i + 1] + wobble)
        walk[s1:s2] = rng.uniform(0.1, 0.4) * np.sin(np.pi * np.arange(k) / k)
    up, walk = up[:n], walk[:n]
    moving = walk > 0
    f_g = up + (walk * np.sin(2 * np.pi * 1.8 * t))[:, None] * _unit(np.array([1.0, 0.3, 0.5]))
    f_g[moving] += rng.normal(0.0, 0.08, (int(moving.sum()), 3))
    temp = 30.0 + 3.0 * np.sin(2 * np.pi * t / 86400.0) + np.cumsum(rng.normal(0.0, 0.002, n))
    wander = np.cumsum(rng.normal(0.0, WANDER_G_PER_SQRT_H * math.sqrt(dt / 3600.0), (n, 3)), axis=0)
    offset = B_TRUE + wander + (temp - 30.0)[:, None] * np.array(TEMPCO_G_PER_C)
    y = offset + f_g @ K_TRUE.T + rng.normal(0.0, NOISE_G, (n, 3))
    sidecar = Sidecar(
        unit_serial="WRIST-0001",
        channel_unit="g",
        sample_rate_hz=RATE_HZ,
        g_local_m_s2=G_LOCAL_M_S2,
        unit_model="wrist logger (simulated)",
        procedure="free-living",
    )
    return Recording(sidecar, np.round(t, 6), np.round(y, 5), temp_c=np.round(temp, 2))


def main(lengths_h: tuple[float, ...] = LENGTHS_H) -> None:
    """Print the sweep of the module docstring."""
    print(f"load average {os.getloadavg()[0]:.1f}; {RATE_HZ:g} Hz, no table, no segments")
    print(f"{'hours':>6} {'n':>9} {'windows':>8} {'command':>9} {'wall s':>8} {'cpu s':>8} {'peak MB':>8}")
    ns: list[float] = []
    cpu: dict[str, list[float]] = {"calibrate": [], "diagnose": []}
    for hours in lengths_h:
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "free-living.csv"
            rec = free_living_recording(hours)
            n = rec.n_samples
            windows = len(choose_windows(rec).used)
            write_recording(rec, path)
            del rec
            ns.append(float(n))
            for command in cpu:
                cost: ChildCost = run_child(command_argv(command, path))
                json.loads(cost.stdout)  # the answer is a whole JSON document
                cpu[command].append(cost.cpu_s)
                print(
                    f"{hours:6.1f} {n:9d} {windows:>8} {command:>9} {cost.wall_s:8.1f} {cost.cpu_s:8.1f} "
                    f"{cost.peak_rss_bytes / 1e6:8.0f}",
                    flush=True,
                )
    for command, ys in cpu.items():
        print(f"  {command:>9}: cpu ∝ n^{growth_exponent(ns, ys):.2f}")


if __name__ == "__main__":
    main(tuple(float(a) for a in sys.argv[1:]) or LENGTHS_H)
