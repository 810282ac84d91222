"""Parameter sigma against test duration: static 12-position tumble vs two-axis oscillation.

Reproduces, in simulation, the oscillation paper's claim (docs/methods.md §2: the accuracy of a
40-minute static test in 1.5 minutes) for an ADXL325-like unit: 15 mg bias spread, 1 %
scale spread, 15′ misalignment, 250 µg/√Hz white noise, 40 µg Gauss-Markov bias wander
(200 s), a 16-bit converter over 3 V, 100 Hz. Both methods are simulated by the same truth
model (drivers/sim) and fitted by the same estimator (the dynamic batch fit with bias and
K only; the unit has no other effect); the static recordings are also fitted by the
project's static window-means fit for reference. Durations are whole recordings: moves,
settling and reference windows included.

Run: ``.venv/bin/python -m benchmarks.study_dynamic_duration [n_seeds]``; docs/dynamic.md
quotes its output.
"""

from __future__ import annotations

import math
import sys

import numpy as np

from api.simulated_recording import to_recording
from bench.calibration import calibrate_recording
from bench.calibration.dynamic import calibrate_dynamic
from drivers.sim.offline import DEFAULT_AXES, simulate_oscillation, simulate_static, static12_poses_deg
from drivers.sim.physics import SensorPhysics, SensorTruth

G0 = 9.80665
ARCMIN = math.pi / 180.0 / 60.0
STATIC_DWELLS_S = (2.0, 5.0, 15.0, 40.0, 100.0, 192.0)
OSC_DURATIONS_S = (30.0, 60.0, 90.0, 180.0, 300.0, 600.0, 1200.0, 1800.0)


def unit(seed: int) -> SensorTruth:
    """An ADXL325-like unit drawn with the paper's spreads."""
    typ = SensorTruth.typical("V", seed=seed)
    rng = np.random.default_rng([seed, 325])
    scale = 0.174 / G0 * (1.0 + 0.01 * rng.standard_normal(3))
    K = np.diag(scale) @ (np.eye(3) + 15.0 * ARCMIN * rng.standard_normal((3, 3)) * (1 - np.eye(3)))
    bias = 1.5 + scale * 15e-3 * G0 * rng.standard_normal(3)
    return SensorTruth(bias=bias, K=K, channel_unit="V", noise=typ.noise)


def metrics(b: np.ndarray, K: np.ndarray, b_ref: np.ndarray, K_ref: np.ndarray) -> np.ndarray:
    """[bias µg, scale ppm, misalignment µrad] RMS over the three axes / six off-diagonals."""
    d = np.diag(K_ref)
    eb = (b - b_ref) / d / G0 * 1e6
    eK = (K - K_ref) / d[:, None]
    off = eK[~np.eye(3, dtype=bool)]
    rms = lambda x: float(np.sqrt(np.mean(np.square(x))))  # noqa: E731
    return np.array([rms(eb), rms(np.diag(eK)) * 1e6, rms(off) * 1e6])


def one(kind: str, x: float, seed: int) -> tuple[float, np.ndarray, np.ndarray, np.ndarray | None]:
    """(duration_s, sigma metrics, error metrics, static-fit error metrics or None)."""
    tr = unit(seed)
    ph = SensorPhysics(tr, DEFAULT_AXES, seed=1000 + seed)
    if kind == "static":
        run = simulate_static(static12_poses_deg(), x, ph, 100.0)
    else:
        run = simulate_oscillation(ph, 100.0, duration_s=x)
    rec = to_recording(run, serial="SN-STUDY")
    res = calibrate_dynamic(rec, terms=(), cross_check=False)
    b_ref = run.bias_seen()
    sig = metrics(res.bias + res.bias_sigma, res.K + res.K_sigma, res.bias, res.K)
    err = metrics(res.bias, res.K, b_ref, tr.K)
    st = None
    if kind == "static":
        s = calibrate_recording(rec)
        st = metrics(s.bias, s.K, b_ref, tr.K)
    return float(run.t_s[-1]), sig, err, st


def main(n_seeds: int = 4) -> None:
    rows = []
    for kind, xs in (("static", STATIC_DWELLS_S), ("oscillation", OSC_DURATIONS_S)):
        for x in xs:
            out = [one(kind, x, s) for s in range(n_seeds)]
            dur = out[0][0]
            sig = np.mean([o[1] for o in out], axis=0)
            err = np.sqrt(np.mean([o[2] ** 2 for o in out], axis=0))
            st = np.sqrt(np.mean([o[3] ** 2 for o in out], axis=0)) if kind == "static" else None
            rows.append((kind, x, dur, sig, err, st))
            extra = "" if st is None else "   window fit err " + " ".join(f"{v:8.1f}" for v in st)
            print(
                f"{kind:12s} {x:6.0f} s -> {dur / 60:6.2f} min  sigma "
                + " ".join(f"{v:8.1f}" for v in sig)
                + "   err "
                + " ".join(f"{v:8.1f}" for v in err)
                + extra,
                flush=True,
            )
    st_rows = [r for r in rows if r[0] == "static"]
    ref = st_rows[-1]
    osc = [r for r in rows if r[0] == "oscillation"]
    print(f"\nstatic reference: {ref[2] / 60:.1f} min; oscillation duration with the same sigma:")
    for j, name in enumerate(("bias", "scale", "misalignment")):
        d = np.log([r[2] for r in osc])
        s = np.log([r[3][j] for r in osc])
        target = math.log(ref[3][j])
        slope, icpt = np.polyfit(d, s, 1)
        if target < s.min():
            when = (
                f"beyond {math.exp(d[-1]) / 60:.1f} min; power law sigma ∝ T^{slope:.2f} "
                f"extrapolates to {math.exp((target - icpt) / slope) / 60:.0f} min"
            )
        elif target > s.max():
            when = f"below {math.exp(d[0]) / 60:.1f} min"
        else:
            when = f"{math.exp(np.interp(target, s[::-1], d[::-1])) / 60:.2f} min"
        print(f"  {name:13s} static sigma {ref[3][j]:8.1f}  -> oscillation {when}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 4)
