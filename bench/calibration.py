"""Calibrate a recording: windows -> window noise -> fit -> result -> contract dict.

The one place where a :class:`~bench.recording.Recording` becomes a calibration; the CLI
(``calbench calibrate``), the service and ``diagnose`` all call
:func:`calibrate_recording`. Which fit applies:

* a table in the sidecar: the known-orientation 12-parameter fit (``static_fit``), with
  f_w = Rᵀ [0, 0, g] at each window's circular-mean encoder angles;
* no table, every window labelled with ``nominal_up`` (a hand-placed six-position
  calibration): the same fit with f_w = ±g along the named axis;
* otherwise the orientation-free fit of |f| = g (``scalar_fit``), K reported as the
  lower-triangular L with L Lᵀ = K Kᵀ (K up to a rotation of the sensor frame);
* a moving-table recording (``calibration_dynamic.is_dynamic``: a ``rate-1axis`` or
  ``oscillation-2axis`` procedure, or no procedure and a segment in which the table turns):
  none of the above, but the sample-by-sample dynamic fit of
  :func:`bench.calibration_dynamic.calibrate_dynamic` (method ``"dynamic"``).

For the static and scalar fits, windows come from the sidecar's segments (those in which
the table did not move; without a table, those with ``nominal_up`` when any segment has
one), or are detected when the sidecar has none.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import numpy as np
import numpy.typing as npt

from bench.estimation.g_check import GCheck, correct, g_check
from bench.estimation.scalar_fit import fit_scalar
from bench.estimation.scalar_wander import scalar_wander
from bench.estimation.static_fit import fit_static
from bench.estimation.window_noise import WindowNoise, pooled_mean_covariances, window_noise
from bench.estimation.windows import StaticWindow, detect_static_windows, windows_from_segments
from bench.kinematics import attitude, static_specific_force
from bench.recording import G0_M_S2, Recording

FloatArray = npt.NDArray[np.float64]

MAX_TABLE_MOTION_RAD = 1e-3
"""A segment whose encoder angles span more than this is a motion, not a static window."""
MIN_WINDOW_SAMPLES = 8
_AXES = {"+x": (0, 1.0), "-x": (0, -1.0), "+y": (1, 1.0), "-y": (1, -1.0), "+z": (2, 1.0), "-z": (2, -1.0)}


@dataclass(frozen=True)
class WindowResult:
    """One static window of a calibration.

    :param label: segment label or detected-window name.
    :param start_s: first sample time (s).
    :param end_s: last sample time (s).
    :param n_samples: samples averaged.
    :param mean_raw: (3,) window mean (channel units).
    :param mean_sigma: (3,) standard deviation of that mean (channel units).
    :param f_m_s2: (3,) specific force the fit assumed (m/s²), ``None`` for the scalar fit.
    :param residual: (3,) mean − model (channel units) for the known-orientation fit;
        for the scalar fit the |g| residual mapped to channel units along f̂.
    :param normalized_residual: (3,) residual over its standard deviation (known-orientation
        fit), or (|f̂| − g) / σ repeated (scalar fit).
    :param g_error_after_m_s2: |K⁻¹(mean − b)| − g.
    :param g_error_before_m_s2: the same with the nominal scale, or ``None``.
    """

    label: str
    start_s: float
    end_s: float
    n_samples: int
    mean_raw: FloatArray
    mean_sigma: FloatArray
    f_m_s2: FloatArray | None
    residual: FloatArray
    normalized_residual: FloatArray
    g_error_after_m_s2: float
    g_error_before_m_s2: float | None


@dataclass(frozen=True)
class CalibrationResult:
    """A fitted first-order model of one recording, with its evidence.

    :param method: ``"static"`` (known orientations), ``"scalar"`` (|f| = g only) or
        ``"dynamic"`` (moving table; the instance is then a
        :class:`bench.calibration_dynamic.DynamicCalibrationResult`).
    :param bias: (3,) channel units.
    :param K: (3, 3) channel unit per m/s² (lower-triangular L for ``"scalar"``).
    :param cov: (12, 12) for ``"static"`` in ``static_fit.PARAMETER_NAMES`` order,
        (9, 9) for ``"scalar"`` in ``scalar_fit.PARAMETER_NAMES`` order, or (p, p) for
        ``"dynamic"`` in ``fit.names`` order (bias and K first, then the extra terms).
    :param bias_sigma: (3,); :param K_sigma: (3, 3) one-sigma (Type A) uncertainties.
    :param residual_rms: RMS of the window residuals (channel units); for ``"dynamic"`` the
        RMS of the per-sample residuals.
    :param chi2: residual χ² against the within-window noise; :param dof: its degrees of
        freedom. For ``"dynamic"``, whose residuals are scaled by their own fitted sigma,
        ``chi2`` is 3·n_samples by construction and carries no goodness-of-fit information.
    """

    unit_serial: str
    channel_unit: str
    procedure: str
    method: str
    g_local_m_s2: float
    bias: FloatArray
    K: FloatArray
    cov: FloatArray
    bias_sigma: FloatArray
    K_sigma: FloatArray
    residual_rms: float
    chi2: float
    dof: int
    noise_model: str
    g_after: GCheck
    g_before: GCheck | None
    windows: tuple[WindowResult, ...]
    source: str = ""

    @property
    def terms(self) -> list[str]:
        """Model terms fitted, as listed in the contract."""
        if self.method == "scalar":
            return ["bias", "scale_matrix_lower_triangular"]
        return ["bias", "scale_matrix"]

    def to_contract(self) -> dict[str, Any]:
        """The ``calbench calibrate --json`` object (shared/cli-contract.md)."""
        g_check_out: dict[str, Any] = {}
        if self.g_before is not None:
            g_check_out["before"] = _g_dict(self.g_before)
        g_check_out["after"] = _g_dict(self.g_after)
        return {
            "unit": self.unit_serial,
            "channel_unit": self.channel_unit,
            "procedure": self.procedure,
            "bias": self.bias.tolist(),
            "bias_sigma": self.bias_sigma.tolist(),
            "scale_matrix": self.K.tolist(),
            "scale_matrix_sigma": self.K_sigma.tolist(),
            "terms": self.terms,
            "extra": {},
            "residual_rms": self.residual_rms,
            "g_check": g_check_out,
        }


def _g_dict(g: GCheck) -> dict[str, float]:
    return {"mean_error_m_s2": g.mean_error_m_s2, "std_m_s2": g.std_m_s2}


def _where(rec: Recording) -> str:
    return rec.source or "recording"


def _window_angles(table_deg: FloatArray, w: StaticWindow) -> tuple[FloatArray, FloatArray]:
    """Mean encoder angles (rad) of a window and their span (rad), robust to wrapping.

    Angles are taken relative to the window's first sample and wrapped to (−180°, 180°]
    before averaging, so a window at the ±180° wrap averages correctly.
    """
    q = np.ascontiguousarray(table_deg[w.start : w.stop].T)  # (k, n): fast reductions along time
    d = (q - q[:, :1] + 180.0) % 360.0 - 180.0
    return np.deg2rad(q[:, 0] + d.mean(axis=1)), np.deg2rad(d.max(axis=1) - d.min(axis=1))


def select_windows(rec: Recording) -> list[StaticWindow]:
    """Static windows of a recording: its still segments, or detected ones without segments.

    :raises ValueError: no usable static window.
    """
    if rec.sidecar.segments:
        wins = windows_from_segments(rec.t_s, rec.sidecar.segments)
        if rec.table_deg is not None:
            wins = [w for w in wins if np.all(_window_angles(rec.table_deg, w)[1] <= MAX_TABLE_MOTION_RAD)]
        elif any(w.nominal_up is not None for w in wins):
            # a hand-held session names the pose of each static window; the others are motions
            wins = [w for w in wins if w.nominal_up is not None]
    else:
        wins = detect_static_windows(rec.t_s, rec.accel_raw, rec.table_rad_unwrapped())
    wins = [w for w in wins if w.stop - w.start >= MIN_WINDOW_SAMPLES]
    if not wins:
        raise ValueError(f"{_where(rec)}: no static window with at least {MIN_WINDOW_SAMPLES} samples")
    return wins


def _specific_force(rec: Recording, wins: list[StaticWindow]) -> FloatArray | None:
    """(m, 3) specific force per window from the table or ``nominal_up``; ``None`` if unknown."""
    g = rec.sidecar.g_local_m_s2
    table = rec.sidecar.table
    if table is not None and rec.table_deg is not None:
        qm = np.array([_window_angles(rec.table_deg, w)[0] for w in wins])
        return static_specific_force(attitude(table.axis_vectors, qm, table.mount_matrix), g)
    if all(w.nominal_up in _AXES for w in wins):
        f = np.zeros((len(wins), 3))
        for k, w in enumerate(wins):
            axis, sign = _AXES[str(w.nominal_up)]
            f[k, axis] = sign * g
        return f
    bad = [w.label for w in wins if w.nominal_up is not None and w.nominal_up not in _AXES]
    if bad:
        raise ValueError(f"{_where(rec)}: segment(s) {bad} have a nominal_up outside {sorted(_AXES)}")
    return None


NATURAL_ZERO_UNITS = ("m/s2", "g")
"""Channel units whose nominal zero-g output is 0 (a nominal scale may come without a bias)."""


def _nominal_force(
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


def calibrate_recording(
    rec: Recording,
    *,
    nominal_scale: float | None = None,
    nominal_bias: FloatArray | None = None,
) -> CalibrationResult:
    """Fit bias and scale/misalignment to a recording (see the module docstring).

    :param rec: the recording.
    :param nominal_scale: nominal sensitivity (channel unit per m/s²) for the "before"
        g check of a channel unit without a natural scale (V, count).
    :param nominal_bias: (3,) nominal zero-g output (channel units) with ``nominal_scale``;
        required with it unless the channel unit is in :data:`NATURAL_ZERO_UNITS`.
    :returns: :class:`CalibrationResult`.
    :raises ValueError: a nominal scale without a zero-g output for a V or count channel, no
        usable windows, a degenerate orientation set (the message names the undeterminable
        parameters), too few windows for the scalar fit, or non-finite data; every message
        starts with the recording's path.
    """
    try:
        unit = rec.sidecar.channel_unit
        if nominal_scale is not None and nominal_bias is None and unit not in NATURAL_ZERO_UNITS:
            raise ValueError(
                f"a nominal scale for a {unit} channel needs the nominal zero-g output (nominal_bias): "
                f"a {unit} output is not 0 at zero g"
            )
        # moving-table recordings (rate-1axis, oscillation-2axis): the dynamic model
        from bench.calibration_dynamic import calibrate_dynamic, is_dynamic

        if is_dynamic(rec):
            return calibrate_dynamic(rec, nominal_scale=nominal_scale, nominal_bias=nominal_bias)
        return _calibrate(rec, nominal_scale, nominal_bias)
    except ValueError as exc:
        msg = str(exc)
        where = _where(rec)
        raise ValueError(msg if msg.startswith(where) else f"{where}: {msg}") from exc


def window_means(rec: Recording, wins: list[StaticWindow]) -> tuple[FloatArray, FloatArray]:
    """(m, 3) window means of the raw outputs and (m, 3, 3) honest covariances of those means
    (batch means per window, correlation factor pooled over the run: ``window_noise``).

    :raises ValueError: a window whose noise cannot be estimated (named with its times).
    """
    noises: list[WindowNoise] = []
    for w in wins:
        try:
            noises.append(window_noise(rec.accel_raw[w.start : w.stop]))
        except ValueError as exc:
            raise ValueError(f"window {w.label!r} ({w.start_s:.3f}-{w.end_s:.3f} s): {exc}") from exc
    return np.array([q.mean for q in noises]), pooled_mean_covariances(noises)


def _calibrate(
    rec: Recording, nominal_scale: float | None, nominal_bias: FloatArray | None
) -> CalibrationResult:
    wins = select_windows(rec)
    y, V = window_means(rec, wins)
    g = rec.sidecar.g_local_m_s2
    f = _specific_force(rec, wins)
    if f is not None:
        mid_s = np.array([(rec.t_s[w.start] + rec.t_s[w.stop - 1]) / 2 for w in wins])
        fit = fit_static(f, y, V, mid_s=mid_s)
        bias, K, cov = fit.bias, fit.K, fit.cov
        bias_sigma, K_sigma = fit.bias_sigma, fit.K_sigma
        resid, norm_resid = fit.residuals, fit.normalized_residuals
        chi2, dof, model, method = fit.chi2, fit.dof, fit.noise_model, "static"
    else:
        sf = fit_scalar(y, V, g)
        bias, K, cov = sf.bias, sf.L, sf.cov
        mid_s = np.array([(rec.t_s[w.start] + rec.t_s[w.stop - 1]) / 2 for w in wins])
        wander = scalar_wander(sf, y, g, mid_s)
        if wander is not None:  # windows sharing a slow wander: their errors are not independent
            cov = wander.cov
        sig = np.sqrt(np.diag(cov))
        bias_sigma, K_sigma = sig[:3], np.zeros((3, 3))
        K_sigma[np.tril_indices(3)] = sig[3:]
        fh = correct(y, bias, K)
        dirs = fh / np.linalg.norm(fh, axis=1, keepdims=True)
        resid = (sf.residuals_m_s2[:, None] * dirs) @ K.T
        norm_resid = np.repeat((sf.residuals_m_s2 / sf.residual_sigma_m_s2)[:, None], 3, axis=1)
        chi2, dof, method = sf.chi2, sf.dof, "scalar"
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
    f_nominal = _nominal_force(rec, y, nominal_scale, nominal_bias)
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
    return CalibrationResult(
        unit_serial=rec.sidecar.unit_serial,
        channel_unit=rec.sidecar.channel_unit,
        procedure=rec.sidecar.procedure or ("static" if method == "static" else "hand-held"),
        method=method,
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
    )
