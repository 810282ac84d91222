"""Allan deviation of one hour of 1 kHz three-channel data: ours against allantools.oadev.

Same data, same octave τ grid; allantools runs once per channel (it takes 1-D data). The
two run alternately ``ROUNDS`` times and the fastest of each is kept, so a busy machine
slows both alike. The ratio (allantools time / ours) is what to read, not the absolute
times. Ours also identifies the noise type and computes the χ² interval at every τ, which
allantools.oadev does not. The results must agree to 1e-10 relative, else this fails.
"""

from __future__ import annotations

import os
import time

import allantools
import numpy as np

from bench.estimation.allan import overlapping_allan

FS_HZ = 1000.0
DURATION_S = 3600.0
ROUNDS = 3


def _data() -> np.ndarray:
    rng = np.random.default_rng(2024)
    n = int(FS_HZ * DURATION_S)
    y = rng.normal(scale=2e-3, size=(n, 3))
    y += np.cumsum(rng.normal(scale=2e-6, size=(n, 3)), axis=0)
    y[:, 2] += 9.81
    return y


def main() -> None:
    """Time both on the same data; print times, ratio and the largest relative difference."""
    y = _data()
    n, c = y.shape
    print(f"data: {n} samples x {c} channels at {FS_HZ:g} Hz ({DURATION_S / 3600:g} h), octave taus")

    t_ours = t_ref = float("inf")
    for _ in range(ROUNDS):
        t0 = time.perf_counter()
        ours = overlapping_allan(y, FS_HZ, "octave")
        t_ours = min(t_ours, time.perf_counter() - t0)
        t0 = time.perf_counter()
        ref = [allantools.oadev(y[:, c], rate=FS_HZ, data_type="freq", taus="octave") for c in range(3)]
        t_ref = min(t_ref, time.perf_counter() - t0)

    worst = 0.0
    for c, (taus, dev, _, n) in enumerate(ref):
        if not (np.array_equal(taus, ours.taus_s) and np.array_equal(n, ours.n_pairs)):
            raise AssertionError(f"channel {c}: τ grid or pair counts differ from allantools")
        worst = max(worst, float(np.max(np.abs(ours.adev[:, c] / dev - 1.0))))
    if worst > 1e-10:
        raise AssertionError(f"results differ from allantools by {worst:.3g} relative")

    print(f"allantools.oadev x3 (baseline): {t_ref:8.3f} s   (load average {os.getloadavg()[0]:.1f})")
    print(f"overlapping_allan (with CIs)  : {t_ours:8.3f} s   ratio baseline/ours = {t_ref / t_ours:.2f}")
    span = f"{ours.taus_s[0]:g} to {ours.taus_s[-1]:g} s"
    print(f"{ours.taus_s.size} taus, {span}; fastest of {ROUNDS} rounds; max relative difference {worst:.2e}")


if __name__ == "__main__":
    main()
