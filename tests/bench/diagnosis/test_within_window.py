"""The window noise without a library term's within-window change (``bench.diagnosis.within_window``)."""

from __future__ import annotations

import numpy as np
import pytest

from bench.calibration.diagnose import recording_evidence
from bench.diagnosis.evidence import G0_M_S2, StaticEvidence
from bench.diagnosis.library import Base, LibraryTerm, library_terms
from bench.diagnosis.within_window import corrected_evidence, varies_within


def _batch_moment(a: np.ndarray, b: np.ndarray, n_batches: int) -> float:
    """Sample covariance of the batch means of a and b (B batches over the first B·(n//B) samples)."""
    k = a.size // n_batches
    za = a[: n_batches * k].reshape(n_batches, k).mean(axis=1)
    zb = b[: n_batches * k].reshape(n_batches, k).mean(axis=1)
    return float(np.sum((za - za.mean()) * (zb - zb.mean())) / (n_batches - 1))


def test_noise_without_a_term_follows_the_moment_equation() -> None:
    """Six windows of white noise plus c·f_x·temp on ay with the temperature ramping inside each
    window: V of the corrected evidence equals, on ay, the moment form of the module docstring
    applied to the window's samples and the term, by hand: Q(u,u) = Q(y,y) − 2c Q(y,x) + c² Q(x,x)
    for the samples' and the batch means' covariances, φ pooled over windows, V = φ Q_s(u,u)/n."""
    rng = np.random.default_rng(5)
    m, n, c, B = 6, 400, 3e-3, 10
    f_g = np.array([[1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [0.6, 0, 0.8], [0, 0, 1]], dtype=float)
    temps = tuple(25.0 + w + np.linspace(0.0, 1.2, n) for w in range(m))
    x = [f_g[w, 0] * (temps[w] - 25.0) for w in range(m)]
    samples = []
    for w in range(m):
        y = 1e-3 * rng.standard_normal((n, 3))
        y[:, 1] += c * x[w]
        samples.append(y)
    t_base = Base("temp", "°C", -1, "temp")
    fx = Base("f_x", "g", 0, "f")
    term = LibraryTerm("f_x*temp", 1, (fx, t_base), "g·°C", np.ones(m), 1.0)
    assert varies_within(term)
    ev = StaticEvidence(
        y=np.array([s.mean(axis=0) for s in samples]),
        V=np.tile(np.eye(3) * 1e-8, (m, 1, 1)),
        f_m_s2=f_g * G0_M_S2,
        mid_s=np.arange(m) * 40.0,
        labels=tuple(f"w{w}" for w in range(m)),
        g_local_m_s2=G0_M_S2,
        window_samples=tuple(samples),
        sample_rate_hz=100.0,
        window_temp_c=temps,
    )
    cov = corrected_evidence(ev, [(term, c)]).V
    bm = wh = 0.0
    white = []
    for w in range(m):
        y, xw = samples[w][:, 1], x[w]
        q_s = np.cov(y, y)[0, 1] - 2 * c * np.cov(y, xw)[0, 1] + c * c * np.cov(xw, xw)[0, 1]
        q_b = _batch_moment(y, y, B) - 2 * c * _batch_moment(y, xw, B) + c * c * _batch_moment(xw, xw, B)
        bm += q_b * (n // B) / n
        white.append(q_s / n)
        wh += q_s / n
    phi = max(1.0, bm / wh)
    np.testing.assert_allclose(cov[:, 1, 1], phi * np.array(white), rtol=1e-9)
    # channels without the term keep their noise (the x channel's samples are untouched)
    np.testing.assert_array_equal(cov[:, 0, 0], corrected_evidence(ev, []).V[:, 0, 0])


@pytest.mark.slow
def test_noise_without_the_term_at_its_truth_is_the_clean_recordings() -> None:
    """fixture_temperature (f_x·temp on ay, 6e-4 V per g·°C, ±1.5 °C cycle), seed 200: the
    window-mean covariance is inflated by the term on every window (also where f_x = 0), and
    the corrected one at the true coefficient is that of the same recording without the term
    (same noise draw), which ``calibrate``'s window noise gives."""
    from benchmarks.library_cases import CASES

    case = CASES["fixture_temperature"]
    size = 4.0
    ev = recording_evidence(case.recording(200, size))
    clean = recording_evidence(case.recording(200, 0.0))
    term = next(t for t in library_terms(ev)[0] if t.term == "f_x*temp" and t.channel == 1)
    ratio = ev.V[:, 1, 1] / clean.V[:, 1, 1]
    nil = np.abs(ev.f_m_s2[:, 0]) < 1e-3 * G0_M_S2
    assert nil.any() and np.all(ratio[nil] > 4.0), ratio
    fixed = corrected_evidence(ev, [(term, size * case.coefficient)])
    np.testing.assert_allclose(fixed.V, clean.V, rtol=1e-6, atol=0.0)
    np.testing.assert_array_equal(fixed.y, ev.y)
