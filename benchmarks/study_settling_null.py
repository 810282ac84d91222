"""False alarms of ``calbench diagnose`` on clean simulated static-12 recordings (docs/diagnose.md).

``python -m benchmarks.study_settling_null [N] [--full]``: N clean recordings (seeds 1000…,
``tests.support.diagnose_cases.static_recording``). For each, the settling test's p value
(``settling_test``: T_j/(2n) judged as F(2n, 3 d_ref)) and, from the same periodograms, the
p value the test had when the reference spectrum was treated as exact (T_j ~ χ²_2n); prints
the share of recordings below several nominal levels for both. ``--full`` also runs the
whole diagnosis on each recording and prints the recordings with any finding.

Also checks the F approximation by Monte Carlo: the mean over three channels of
F(2n/3, d_ref) ratios with independent references, against F(2n, 3 d_ref), at the tail
probabilities the Bonferroni-corrected test uses.
"""

from __future__ import annotations

import sys
import time

import numpy as np
from scipy.stats import chi2 as chi2_dist
from scipy.stats import f as f_dist

from bench.calibration.diagnose import diagnose_recording, recording_evidence
from bench.diagnosis.effects.settling import frequency_p_values, settling_test
from tests.support.diagnose_cases import static_recording

LEVELS = (0.001, 0.01, 0.05, 0.1)


def chi2_p_value(window_samples: tuple[np.ndarray, ...], sample_rate_hz: float) -> float:
    """The p value with the reference treated as exact: min_j χ²_2n tail of T_j × number of f_j."""
    _, T, p, n, _ = frequency_p_values(window_samples, sample_rate_hz)
    return min(1.0, float(chi2_dist.sf(T.max(), 2 * n)) * p.size)


def monte_carlo_tail(n_per_channel: int, d_ref: int, n_bins: int, draws: int = 2_000_000) -> str:
    """Actual / nominal tail of the mean of three F(2a, d_ref) against the F(6a, 3 d_ref) quantile."""
    rng = np.random.default_rng(7)
    a = n_per_channel
    x = sum(rng.chisquare(2 * a, draws) / (2 * a) / (rng.chisquare(d_ref, draws) / d_ref) for _ in range(3))
    x = x / 3.0
    out = []
    for level in LEVELS:
        p = level / n_bins
        out.append(f"{level:g}: {np.mean(x > f_dist.isf(p, 6 * a, 3 * d_ref)) / p:.2f}")
    return "actual/nominal tail at the per-frequency level of " + ", ".join(out)


def main(argv: list[str] | None = None) -> None:
    """Print the false-alarm table (module docstring)."""
    args = sys.argv[1:] if argv is None else argv
    n = int(args[0]) if args and args[0].isdigit() else 200
    full = "--full" in args
    t0 = time.perf_counter()
    p_f, p_chi2, findings = [], [], {}
    for seed in range(1000, 1000 + n):
        rec = static_recording({}, seed=seed)
        ev = recording_evidence(rec)
        assert ev.window_samples is not None and ev.sample_rate_hz is not None
        st = settling_test(ev.window_samples, ev.sample_rate_hz)
        p_f.append(st.p_value)
        p_chi2.append(chi2_p_value(ev.window_samples, ev.sample_rate_hz))
        if full:
            found = [f.effect for f in diagnose_recording(rec).findings]
            if found:
                findings[seed] = found
    pf, pc = np.array(p_f), np.array(p_chi2)
    print(
        f"{n} clean static-12 recordings (seeds 1000-{999 + n}); settling test dof 2n = {st.dof}, "
        f"3 d_ref = {st.ref_dof} at its frequency"
    )
    print("| nominal level | F(2n, 3 d_ref) (now) | χ²_2n, reference exact (before) |")
    print("|---|---|---|")
    for level in LEVELS:
        print(
            f"| {level:g} | {np.sum(pf < level)} ({np.mean(pf < level):.1%}) | "
            f"{np.sum(pc < level)} ({np.mean(pc < level):.1%}) |"
        )
    print(monte_carlo_tail(st.dof // 6, st.ref_dof // 3, 88))
    if full:
        print(f"full diagnosis: {len(findings)} of {n} with a finding ({len(findings) / n:.1%}): {findings}")
    print(f"({time.perf_counter() - t0:.0f} s)")


if __name__ == "__main__":
    main()
