"""CPU cost of the Allan noise-model fit of one 10⁶-sample three-channel record.

The study's ``gm`` (white, Gauss–Markov 3e-4 / 30 s, rate random walk) and ``whiterw``
records at 10 000 s, 100 Hz (``benchmarks.study_sigmas_allan.record``), octave τ (19 points):
``fit_noise_model`` of the three channels as built, and with the Gauss–Markov term chosen as
before (backward elimination from the full model, every term kept where χ² fails), paired
in one process, process CPU, fastest of ``ROUNDS``.

    python -m benchmarks.bench_allan_fit
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable
from unittest.mock import patch

from bench.estimation import noise_gls, noise_terms
from bench.estimation.allan import AllanResult, overlapping_allan
from bench.estimation.noise_terms import FloatArray, fit_noise_model
from benchmarks.study_sigmas_allan import FS_HZ, record

ROUNDS = 3


def _backward_from_full(
    t: FloatArray,
    s2: FloatArray,
    nu: FloatArray,
    active: list[int],
    tau0_s: float,
    n_it: int,
    full: noise_gls.GlsFit,
    holds: bool,
) -> list[int]:
    """The selection before the term's own test: backward elimination from the full model."""
    return noise_gls.select_terms(t, s2, nu, active, tau0_s, n_it, full) if holds else list(active)


def _cpu(fn: Callable[[AllanResult], object], r: AllanResult) -> float:
    t0 = time.process_time()
    fn(r)
    return time.process_time() - t0


def main() -> None:
    """Print the fit's CPU time per record, as built and with the former selection."""
    built = noise_gls.select_with_gauss_markov
    for sensor in ("gm", "whiterw"):
        r = overlapping_allan(record(0, 1_000_000, False, sensor), FS_HZ)
        best = {"as built": float("inf"), "former selection": float("inf")}
        for _ in range(ROUNDS):
            for name, select in (("as built", built), ("former selection", _backward_from_full)):
                with patch.object(noise_terms, "select_with_gauss_markov", select):
                    best[name] = min(best[name], _cpu(fit_noise_model, r))
        cells = ", ".join(f"{k} {v:.2f} s" for k, v in best.items())
        print(f"{sensor}: {cells} (load average {os.getloadavg()[0]:.1f}, fastest of {ROUNDS})")


if __name__ == "__main__":
    main()
