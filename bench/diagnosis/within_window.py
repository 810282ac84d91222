"""The window noise of a model whose library terms vary within a window, and its refit.

A window mean's covariance V_w comes from the window's own samples (batch means with one
correlation factor per channel pooled over the run: ``bench.estimation.window_noise``).
Everything that moves the samples within a window counts there as noise. A library term
in temperature or time (``temp``, ``t`` or a product with them, e.g. f_z·temp) is not
constant within a window: the temperature moves up to 1.3 °C in a 30 s window on a ±1.5 °C
cycle. Once such a term is in the data its deterministic within-window change inflates the
batch-means variance of its channel, and through the pooled correlation factor every
window's, including those where the term is nil: the term's sigma came out five to six
times its estimate's scatter (docs/diagnose.md, "Sigmas against the scatter of the
estimates").

The noise the model leaves is that of the samples with the model's own within-window terms
removed. For window w and channel i with terms k = 1..K of coefficients c_k on i,

    u_s = y_s,i − Σ_k c_k (x_k(s) − x̄_k,w),     x̄_k,w = mean of x_k over the window's samples,

x_k(s) the term evaluated at sample s (f and |f| from the window's pose, temperature and
time per sample); the window mean is unchanged (the subtracted part has mean 0 over the
window). The window noise is then the same estimator applied to u instead of y_i. Both of
its ingredients, the samples' covariance Σ_w and the batch means' covariance, are sample
covariances Q(a, b) = Σ_j (a_j − ā)(b_j − b̄)/(N − 1), over the samples or over the batch
means, so by their bilinearity (one term)

    Q(u, u)   = Q(y_i, y_i) − 2 c Q(y_i, x) + c² Q(x, x),
    Q(u, y_j) = Q(y_i, y_j) − c Q(x, y_j)      (j ≠ i),

and so V_w (``pooled_mean_covariances``: φ_c = max(1, Σ_w Vbm_w,cc / Σ_w Σ_w,cc/n_w),
V_w = D Σ_w D / n_w) is computed from the corrected samples exactly as the moments of the
samples, the term and their cross moments would give it. Batch means: Flegal & Jones,
Ann. Stat. 38 (2010); removing a fitted regression's mean function before batching is
what batch means of regression residuals do (the estimator assumes a stationary process).

The coefficients come from the fit, which depends on the noise: the model is refitted
(REML noise and GLS, ``model_state.fit_model``) under the corrected evidence and the
correction redone with the refit's coefficients, ``Thresholds.within_window_passes`` times in all.
Only a model with such a library term is refitted; every other model, the selection's
statistics, the catalogue's effects (bias_drift and temperature_bias keep their window
noise, which their own within-window change is part of) and ``calibrate`` are unchanged.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.diagnosis.effects import Candidate
from bench.diagnosis.effects.base import FloatArray
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.library import LibraryTerm, quantity
from bench.diagnosis.likelihood import GlsFit
from bench.diagnosis.model_state import ModelState, fit_model, scale_matrix
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.window_noise import pooled_mean_covariances, window_noise

WITHIN_KINDS = ("temp", "t")
"""Base quantities that change within a static window (the pose's f and |f| do not)."""


def varies_within(t: LibraryTerm) -> bool:
    """The term has a factor in temperature or time, so it changes within a window."""
    return any(b.kind in WITHIN_KINDS for b in t.factors)


def can_correct(ev: StaticEvidence, t: LibraryTerm) -> bool:
    """The evidence carries the per-sample series the term needs (samples, temperature, time)."""
    if ev.window_samples is None:
        return False
    kinds = {b.kind for b in t.factors}
    has_temp = "temp" not in kinds or ev.window_temp_c is not None
    return has_temp and ("t" not in kinds or ev.window_t_s is not None)


def sample_values(ev: StaticEvidence, t: LibraryTerm, w: int) -> FloatArray:
    """(n_w,) the term's monomial at every sample of window ``w`` (its own unit; NaN where the
    temperature was not measured): f and abs(f) from the window's pose (g), temp − 25 °C and
    t (s) per sample (``library.quantity``, as the library's per-window values)."""
    assert ev.window_samples is not None
    temp = None if ev.window_temp_c is None else ev.window_temp_c[w]
    t_s = None if ev.window_t_s is None else ev.window_t_s[w]
    x = np.ones(ev.window_samples[w].shape[0])
    for b in t.factors:
        x = x * quantity(b, ev.f_m_s2[w], temp, t_s)
    return x


def deviations(x: FloatArray) -> FloatArray:
    """x − its mean over the finite samples; 0 where x is not finite (nothing to remove)."""
    ok = np.isfinite(x)
    if not np.any(ok):
        return np.zeros_like(x)
    return np.where(ok, x - float(np.mean(x[ok])), 0.0)


def coefficients(
    fit: GlsFit, cands: list[Candidate], terms: dict[str, LibraryTerm]
) -> list[tuple[LibraryTerm, float]]:
    """(term, coefficient in channel units per unit of the term) of every candidate of the
    model that is one of ``terms``, from the fit's θ (columns after the first-order 12)."""
    out = []
    col = 12
    for c in cands:
        if c.effect in terms:
            t = terms[c.effect]
            out.append((t, float(fit.theta[col]) / t.scale))
        col += len(c.names)
    return out


def corrected_evidence(ev: StaticEvidence, terms: list[tuple[LibraryTerm, float]]) -> StaticEvidence:
    """The evidence with each window's samples less the terms' within-window change (module
    docstring) and the window-mean covariances V recomputed from them (``window_noise``,
    pooled as the calibration's ``window_means``). Window means, poses and times unchanged."""
    assert ev.window_samples is not None
    samples = []
    for w, s in enumerate(ev.window_samples):
        u = np.array(s, dtype=float, copy=True)
        for t, c in terms:
            u[:, t.channel] -= c * deviations(sample_values(ev, t, w))
        samples.append(u)
    V = pooled_mean_covariances([window_noise(u) for u in samples])
    return replace(ev, V=V, window_samples=tuple(samples))


def refit_within_window(
    ev: StaticEvidence,
    state: ModelState,
    lib_terms: dict[str, LibraryTerm],
    fixed: FloatArray | None,
    th: Thresholds = THRESHOLDS,
) -> tuple[StaticEvidence, ModelState]:
    """The evidence and model state the final model is reported from.

    When the model holds library terms that vary within a window (:func:`varies_within`)
    and the evidence has their per-sample series: the window noise without them and the
    model refitted under it (module docstring). Otherwise ``ev`` and ``state`` unchanged.
    """
    within = {k: t for k, t in lib_terms.items() if varies_within(t) and can_correct(ev, t)}
    if not any(c.effect in within for c in state.candidates):
        return ev, state
    assert state.fit is not None and state.noise is not None
    fit, noise = state.fit, state.noise
    out = ev
    for _ in range(th.within_window_passes):
        out = corrected_evidence(ev, coefficients(fit, state.candidates, within))
        noise, fit, _ = fit_model(out, state.candidates, state.pose, scale_matrix(fit), fixed, noise, th=th)
    return out, replace(state, noise=noise, fit=fit)
