"""Calibrate the static windows of a recording: the known-orientation fit or the
orientation-free one.

* a table in the sidecar: the known-orientation 12-parameter fit (``static_fit``), with
  f_w = Rᵀ [0, 0, g] at each window's mean encoder angles (``windows.known_specific_force``);
* no table, every window labelled with ``nominal_up`` (a hand-placed six-position
  calibration): the same fit with f_w = ±g along the named axis;
* otherwise the orientation-free fit of |f| = g (``scalar_fit``), K reported as the
  lower-triangular L with L Lᵀ = K Kᵀ (K up to a rotation of the sensor frame).

Windows come from ``windows.choose_windows``; the "before" |g| check uses the nominal
scale (:func:`nominal_force`). Nothing is dropped without a word: a declared segment (or
detected window) that is not used is named with the reason in ``unused_windows``, and a fit
with as many parameters as observations (no redundancy: the residuals are zero by
construction, χ² and the |g| scatter test nothing, the sigmas rest on the within-window
noise alone) says so in ``warnings`` and ``zero_redundancy``.
"""

from __future__ import annotations

import numpy as np
import numpy.typing as npt

from bench.calibration.kind import FitKind
from bench.calibration.result import CalibrationResult, WindowResult, zero_redundancy_warning
from bench.calibration.windows import choose_windows, known_specific_force, unused_warning, window_means
from bench.estimation.dynamic_batch import BiasReference
from bench.estimation.g_check import correct, g_check
from bench.estimation.scalar_fit import fit_scalar, floor_by_sandwich
from bench.estimation.scalar_wander import scalar_wander
from bench.estimation.static_fit import fit_static
from bench.recording import G0_M_S2, Recording

FloatArray = npt.NDArray[np.float64]

NATURAL_ZERO_UNITS = ("m/s2", "g")
"""Channel units whose nominal zero-g output is 0 (a nominal scale may come without a bias)."""


def nominal_force(
    rec: Recording, y: FloatArray, scale: float | None, bias: FloatArray | None
) -> FloatArray | None:
    """Specific force with the nominal scale only (the 'before' of the g check), or ``None``."""
    if scale is not None:
        if not (np.isfinite(scale) and scale != 0):
            raise ValueError(f"nominal scale must be finite and non-zero, got {scale}")
        b0 = np.zeros(3) if bias is None else np.asarray(bias, dtype=float)
        return (y - b0) / scale
    unit = rec.sidecar.channel_unit
    if unit == "m/s2":
        return y
    if unit == "g":
        return y * G0_M_S2
    return None


def calibrate_static(
    rec: Recording, nominal_scale: float | None, nominal_bias: FloatArray | None
) -> CalibrationResult:
    """The static or orientation-free calibration of ``rec`` (module docstring).

    :param nominal_scale: nominal sensitivity (channel unit per m/s²) for the "before" check.
    :param nominal_bias: (3,) nominal zero-g output (channel units) with ``nominal_scale``.
    :raises ValueError: no usable windows, a degenerate orientation set, too few windows for
        the scalar fit, or non-finite data.
    """
    chosen = choose_windows(rec)
    wins = list(chosen.used)
    y, V = window_means(rec, wins)
    g = rec.sidecar.g_local_m_s2
    f = known_specific_force(rec, wins)
    mid_s = np.array([(rec.t_s[w.start] + rec.t_s[w.stop - 1]) / 2 for w in wins])
    reference: BiasReference
    run_mean_sigma = None
    if f is not None:
        fit = fit_static(f, y, V, mid_s=mid_s)
        bias, K, cov = fit.bias, fit.K, fit.cov
        bias_sigma, K_sigma = fit.bias_sigma, fit.K_sigma
        resid, norm_resid = fit.residuals, fit.normalized_residuals
        chi2, dof, model, kind = fit.chi2, fit.dof, fit.noise_model, FitKind.STATIC
        reference, run_mean_sigma = fit.bias_reference, fit.bias_sigma_run_mean
        n_obs, n_params, what = 3 * len(wins), 12, "window-mean components (3 per window)"
    else:
        sf = fit_scalar(y, V, g)
        bias, K, cov = sf.bias, sf.L, sf.cov
        wander = scalar_wander(sf, y, g, mid_s)
        if wander is not None:  # windows sharing a slow wander: their errors are not independent
            cov = floor_by_sandwich(wander.cov, sf.sandwich_cov)
        reference = "long_run" if wander is not None else "run_mean"
        sig = np.sqrt(np.diag(cov))
        bias_sigma, K_sigma = sig[:3], np.zeros((3, 3))
        K_sigma[np.tril_indices(3)] = sig[3:]
        fh = correct(y, bias, K)
        dirs = fh / np.linalg.norm(fh, axis=1, keepdims=True)
        resid = (sf.residuals_m_s2[:, None] * dirs) @ K.T
        norm_resid = np.repeat((sf.residuals_m_s2 / sf.residual_sigma_m_s2)[:, None], 3, axis=1)
        chi2, dof, kind = sf.chi2, sf.dof, FitKind.ORIENTATION_FREE
        n_obs, n_params, what = len(wins), 9, "window magnitudes (|f| = g, one per window)"
        model = (
            "window means: batch-means covariance from each window's samples; "
            f"between windows: additive |g| scatter sigma = {np.sqrt(sf.excess_var_m_s2):.3g} m/s²"
        )
        if wander is not None:
            model += (
                f"; a slow wander shared by the windows, sigma = {wander.omega_m_s2:.3g} m/s² per axis, "
                f"correlation time {wander.corr_time_s:.0f} s (REML, 2 delta loglik {wander.lr:.1f})"
            )
    after = g_check(correct(y, bias, K), g)
    f_nominal = nominal_force(rec, y, nominal_scale, nominal_bias)
    before = None if f_nominal is None else g_check(f_nominal, g)
    sigma_mean = np.sqrt(np.diagonal(V, axis1=1, axis2=2))
    windows = tuple(
        WindowResult(
            label=w.label,
            start_s=w.start_s,
            end_s=w.end_s,
            n_samples=w.stop - w.start,
            mean_raw=y[k],
            mean_sigma=sigma_mean[k],
            f_m_s2=None if f is None else f[k],
            residual=resid[k],
            normalized_residual=norm_resid[k],
            g_error_after_m_s2=float(after.error_m_s2[k]),
            g_error_before_m_s2=None if before is None else float(before.error_m_s2[k]),
        )
        for k, w in enumerate(wins)
    )
    warnings = [zero_redundancy_warning(n_obs, n_params, what)] if dof <= 0 else []
    unused_text = unused_warning(chosen.unused)
    if unused_text is not None:
        warnings.append(unused_text)
    return CalibrationResult(
        unit_serial=rec.sidecar.unit_serial,
        channel_unit=rec.sidecar.channel_unit,
        procedure=rec.sidecar.procedure or ("static" if kind is FitKind.STATIC else "hand-held"),
        kind=kind,
        g_local_m_s2=g,
        bias=bias,
        K=K,
        cov=cov,
        bias_sigma=bias_sigma,
        K_sigma=K_sigma,
        residual_rms=float(np.sqrt(np.mean(resid**2))),
        chi2=chi2,
        dof=dof,
        noise_model=model,
        g_after=after,
        g_before=before,
        windows=windows,
        source=rec.source,
        unused_windows=chosen.unused,
        warnings=tuple(warnings),
        bias_reference=reference,
        bias_sigma_run_mean=run_mean_sigma,
    )
