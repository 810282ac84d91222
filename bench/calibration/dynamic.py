"""Calibrate a recording in which the table moves (``rate-1axis``, ``oscillation-2axis``).

Recording -> motion regressors (``motion_data.prepare_motion`` on the unwrapped encoder
angles and the sidecar geometry) -> choice of terms (below) -> batch fit over every usable
sample (``dynamic_batch``) -> extended Kalman filter over the same samples as a cross-check
(``dynamic_kalman``) -> the contract of ``calbench calibrate`` with the terms beyond bias
and K under ``extra`` (``docs/cli-contract.md``: ``lever_arm.r_m``, ``proof_mass_offsets.rho_m``,
``nonlinearity_quadratic.k2_per_g``, ``table_tilt.tilt_rad``, ``time_skew.delay_s``).

Terms: the model the evidence supports. By default the terms are those the diagnosis of
the same recording claims (``bench.diagnosis.dynamic.claim_moving``: each term the motion
determines is tried, and enters only if its departure from the believed geometry passes a
Wald test at the diagnosis's false-alarm rate and lowers the BIC; steps that a term of the
moving library explains better are left out, as the diagnosis leaves them; claims that only
imitated a bench family, an angle harmonic or a growing delay, are withdrawn by the families'
head to head, as the diagnosis withdraws them); the believed geometry of
the sidecar is kept for every term left out. Fitting a term that the data do not need only
spreads the same information over more parameters: on a clean oscillation run the z-bias
sigma of the all-terms fit is 3.7× the first-order fit's. ``terms=`` (``calbench calibrate
--terms``) fits a declared set instead (a unit model's terms), and ``model_selection``
says which rule chose the model; ``not_fitted`` says why each candidate was left out. With
``proof_mass_offsets`` the three proof-mass positions q_i are fitted; the contract's
``r_m`` is their centroid and row i of ``rho_m`` is q_i − r_m (a split of the q_i that the
data cannot make otherwise). :func:`choose_spec` (every term the motion determines to a
useful Cramér–Rao sigma) is the identifiability rule the evidence rule replaced; it
remains for studies of what a motion can determine.

|g| check: each sample corrected, f̂ = K⁻¹(raw − b − nonlinear term) minus the fitted
centripetal and tangential acceleration, |f̂| − g averaged over blocks of 1 s.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Any

import numpy as np
import numpy.typing as npt

from bench.calibration.kind import CANDIDATE_TERMS, FitKind
from bench.calibration.result import CalibrationResult, WindowResult
from bench.calibration.windows import moving_samples, select_windows
from bench.diagnosis.dynamic import claim_moving
from bench.estimation.dynamic_batch import DynamicFit, fit_dynamic_batch, linear_start, white_sigma
from bench.estimation.dynamic_kalman import run_dynamic_kalman
from bench.estimation.dynamic_model import G0_M_S2, ModelSpec, initial_theta, positions, predict
from bench.estimation.g_check import GCheck
from bench.estimation.motion_data import MotionData, sample_chunks
from bench.estimation.observability import USEFUL_SIGMA, fisher_information, information_report
from bench.estimation.window_noise import pooled_mean_covariances, window_noise
from bench.fitted_model import DYNAMIC_BATCH, FittedModel
from bench.recording import Recording

FloatArray = npt.NDArray[np.float64]

DROP_ORDER = ("proof_mass_offsets", "nonlinearity_quadratic", "time_skew", "table_tilt", "lever_arm")
"""Which undetermined term goes first when the information is singular."""
KALMAN_AGREEMENT_Z = 3.0
"""The filter and the batch fit agree when every |difference| / batch sigma is below this."""
G_BLOCK_S = 1.0
_FMT: Any = {"float_kind": lambda x: f"{x:.5g}"}
MIN_BATCH_WINDOW = 40
"""Samples a still window needs for its batch-means noise (``window_noise``)."""


@dataclass(frozen=True)
class DynamicCalibrationResult(CalibrationResult):
    """A :class:`CalibrationResult` of a moving-table recording, with the extra terms.

    :param fit: the batch fit (θ, sandwich covariance, names).
    :param extra: contract ``extra`` (effect id -> parameter -> value).
    :param extra_sigma: one-sigma of the same shape.
    :param not_fitted: candidate term -> why it was left out.
    :param kalman: cross-check summary (``max_abs_z``, ``agree``, ``sigma_ratio``), or empty.
    :param model_selection: which rule chose the terms (``rule``: ``evidence`` or
        ``declared``), with the admitted steps (term, Wald W, ΔBIC) for ``evidence``.
    """

    fit: DynamicFit | None = None
    extra: dict[str, dict[str, Any]] = field(default_factory=dict)
    extra_sigma: dict[str, dict[str, Any]] = field(default_factory=dict)
    not_fitted: dict[str, str] = field(default_factory=dict)
    kalman: dict[str, Any] = field(default_factory=dict)
    model_selection: dict[str, Any] = field(default_factory=dict)

    @property
    def terms(self) -> list[str]:
        """bias, scale_matrix and the fitted extra terms (contract effect ids)."""
        return ["bias", "scale_matrix", *self.extra]

    @property
    def model_terms(self) -> tuple[str, ...]:
        """The dynamic model's terms beyond bias and K (``ModelSpec.terms``), in fit order."""
        assert self.fit is not None
        return tuple(self.fit.spec.terms)

    @property
    def parameter_names(self) -> tuple[str, ...]:
        """The batch fit's parameter names (bias and K first, then the extra terms)."""
        assert self.fit is not None
        return tuple(self.fit.names)

    def model_lines(self) -> list[str]:
        """The extra terms with their sigmas, the rule that chose the model and why each other
        candidate was left out, as ``calbench calibrate`` prints them."""
        lines = []
        for effect, params in self.extra.items():
            for name, value in params.items():
                sigma = self.extra_sigma.get(effect, {}).get(name, np.nan)
                v, sg = (
                    np.array2string(np.asarray(x), formatter=_FMT, separator=", ") for x in (value, sigma)
                )
                lines.append(f"{effect}.{name} = {v} ± {sg}".replace("\n", ""))
        if self.model_selection:
            sel = self.model_selection
            lines.append(f"model: {' + '.join(self.terms)}, chosen by {sel['rule']}: {sel['text']}")
        lines += [f"  not fitted {term}: {why}" for term, why in self.not_fitted.items()]
        return lines

    def fitted_model(self) -> FittedModel:
        """The fitted model with the extra terms and the method (``dynamic-batch``)."""
        return replace(super().fitted_model(), extra=self.extra, method=DYNAMIC_BATCH)

    def to_contract(self) -> dict[str, Any]:
        """The contract object; adds ``extra_sigma``, ``not_fitted``, ``method``, ``kalman_check``
        and ``model_selection``."""
        out = super().to_contract()
        out["extra"] = self.extra
        out["extra_sigma"] = self.extra_sigma
        out["not_fitted"] = self.not_fitted
        out["method"] = DYNAMIC_BATCH
        out["kalman_check"] = self.kalman
        out["model_selection"] = self.model_selection
        return out


def choose_spec(
    m: MotionData, y: FloatArray, g: float, lever: FloatArray, candidates: tuple[str, ...] = CANDIDATE_TERMS
) -> tuple[ModelSpec, dict[str, str]]:
    """The candidate terms this motion determines (module docstring) and the reasons for the others."""
    b0, K0 = linear_start(m, y, g, lever)
    sig = np.maximum(white_sigma(y[m.valid]), 1e-12)
    terms = list(candidates)
    dropped: dict[str, str] = {}
    while True:
        spec = ModelSpec(tuple(terms))
        rep = information_report(
            fisher_information(m, initial_theta(spec, b0, K0, lever), spec, g, lever, sig), spec.names
        )
        worst: tuple[float, str, str] | None = None
        if not rep.ok:  # drop the most dispensable term the undetermined directions involve
            text = "; ".join(rep.unobservable)
            involved = [
                t for t in DROP_ORDER if t in spec.terms and any(n in text for n in spec.names[spec.index(t)])
            ]
            if involved:
                worst = (np.inf, involved[0], "not determined by this motion: " + text)
        else:
            for t in spec.terms:
                s = float(np.max(rep.crb_sigma[spec.index(t)]))
                ratio = s / USEFUL_SIGMA[t]
                if ratio > 1.0 and (worst is None or ratio > worst[0]):
                    worst = (ratio, t, f"Cramér–Rao sigma {s:.3g} exceeds {USEFUL_SIGMA[t]:g}")
        if worst is None:
            return spec, dropped
        terms.remove(worst[1])
        dropped[worst[1]] = worst[2]


def _extra(fit: DynamicFit) -> tuple[dict[str, dict[str, Any]], dict[str, dict[str, Any]]]:
    spec, th, cov = fit.spec, fit.theta, fit.cov
    val: dict[str, dict[str, Any]] = {}
    sig: dict[str, dict[str, Any]] = {}

    def lin(T: FloatArray, s: slice) -> tuple[FloatArray, FloatArray]:
        c = cov[s, s]
        return T @ th[s], np.sqrt(np.diag(T @ c @ T.T))

    for t in spec.terms:
        s = spec.index(t)
        if t == "lever_arm":
            val[t], sig[t] = {"r_m": th[s].tolist()}, {"r_m": np.sqrt(np.diag(cov[s, s])).tolist()}
        elif t == "proof_mass_offsets":
            Tr = np.tile(np.eye(3) / 3.0, (1, 3))  # centroid of q_x, q_y, q_z
            r, rs = lin(Tr, s)
            Trho = np.eye(9) - np.tile(Tr, (3, 1))
            rho, rhos = lin(Trho, s)
            val["lever_arm"], sig["lever_arm"] = {"r_m": r.tolist()}, {"r_m": rs.tolist()}
            val[t], sig[t] = {"rho_m": rho.reshape(3, 3).tolist()}, {"rho_m": rhos.reshape(3, 3).tolist()}
        else:
            name = {"nonlinearity_quadratic": "k2_per_g", "table_tilt": "tilt_rad", "time_skew": "delay_s"}[t]
            v, e = th[s], np.sqrt(np.diag(cov[s, s]))
            val[t] = {name: float(v[0]) if t == "time_skew" else v.tolist()}
            sig[t] = {name: float(e[0]) if t == "time_skew" else e.tolist()}
    order = ["lever_arm", *[t for t in val if t != "lever_arm"]]
    return {k: val[k] for k in order if k in val}, {k: sig[k] for k in order if k in sig}


def _corrected_gravity(fit: DynamicFit, m: MotionData, y: FloatArray, lever: FloatArray) -> FloatArray:
    """(n, 3) K⁻¹(raw − b − nonlinear term) − fitted motion acceleration, per sample (m/s²)."""
    spec, th = fit.spec, fit.theta
    b, K = th[:3], th[3:12].reshape(3, 3)
    Q = positions(th, spec, lever)
    f_motion = np.empty((m.n, 3))
    for s in sample_chunks(m.n):  # B_δ per sample: chunks bound the (chunk, 3, 3) temporaries
        ms = m.take(s, rates=spec.needs_rates)
        Be = ms.B
        if "time_skew" in spec.terms:
            d = th[spec.index("time_skew")][0]
            Be = ms.B - d * ms.B_dot + 0.5 * d * d * ms.B_ddot
        f_motion[s] = np.einsum("nic,ic->ni", Be, Q)
    fhat = np.linalg.solve(K, (y - b).T).T
    if "nonlinearity_quadratic" in spec.terms:  # one fixed-point step removes the k2 f² term
        k2 = th[spec.index("nonlinearity_quadratic")]
        fhat = np.linalg.solve(K, (y - b - np.diag(K) * k2 * fhat**2 / G0_M_S2).T).T
    return np.asarray(fhat - f_motion, dtype=float)


def _block_means(t: FloatArray, v: FloatArray) -> FloatArray:
    blk = np.floor((t - t[0]) / G_BLOCK_S).astype(np.int64)
    counts = np.bincount(blk)
    return np.asarray(np.bincount(blk, weights=v)[counts > 0] / counts[counts > 0], dtype=float)


def _static_windows(
    rec: Recording, fit: DynamicFit, m: MotionData, y: FloatArray, fg: FloatArray, lever: FloatArray
) -> tuple[WindowResult, ...]:
    """The recording's still segments (reference windows, zero-rate windows) against the fitted model.

    residual = window mean − mean model prediction; its sigma from batch means pooled over
    the windows (``window_noise``), as in the static calibration.
    """
    try:
        wins = [w for w in select_windows(rec) if w.stop - w.start >= MIN_BATCH_WINDOW]
    except ValueError:
        return ()
    if not wins:
        return ()
    V = pooled_mean_covariances([window_noise(y[w.start : w.stop]) for w in wins])
    out = []
    g = rec.sidecar.g_local_m_s2
    for k, w in enumerate(wins):
        sl = slice(w.start, w.stop)
        model, _ = predict(fit.theta, m.take(sl, rates=fit.spec.needs_rates), fit.spec, g, lever)
        mean = y[sl].mean(axis=0)
        sig = np.sqrt(np.diag(V[k]))
        resid = mean - model.mean(axis=0)
        f_mean = np.linalg.solve(fit.theta[3:12].reshape(3, 3), model.mean(axis=0) - fit.theta[:3])
        out.append(
            WindowResult(
                label=w.label,
                start_s=w.start_s,
                end_s=w.end_s,
                n_samples=w.stop - w.start,
                mean_raw=mean,
                mean_sigma=sig,
                f_m_s2=f_mean,
                residual=resid,
                normalized_residual=resid / sig,
                g_error_after_m_s2=float(np.linalg.norm(fg[sl].mean(axis=0)) - g),
                g_error_before_m_s2=None,
            )
        )
    return tuple(out)


def _g_from_magnitudes(mag: FloatArray, g: float) -> GCheck:
    """:class:`GCheck` of block-mean magnitudes |f̂| (m/s²) against g."""
    err = mag - g
    return GCheck(
        magnitude_m_s2=mag,
        error_m_s2=err,
        mean_error_m_s2=float(err.mean()),
        std_m_s2=float(err.std(ddof=1)) if err.size > 1 else 0.0,
        rms_m_s2=float(np.sqrt(np.mean(err**2))),
    )


def nominal_g_check(
    rec: Recording, y: FloatArray, nominal_scale: float | None, nominal_bias: FloatArray | None
) -> GCheck | None:
    """The |g| check before adjustment: |(y − b₀)/s| − g over blocks of :data:`G_BLOCK_S`, with
    the nominal scale s (channel unit per m/s²) and zero-g output b₀ (3,), or the channel unit's
    natural scale (m/s2, g) when no nominal is given; ``None`` without either.

    :param y: (n, 3) raw samples (channel units), those of ``moving_samples``.
    """
    scale = nominal_scale
    if scale is None:
        scale = {"m/s2": 1.0, "g": 1.0 / G0_M_S2}.get(rec.sidecar.channel_unit)
    if scale is None:
        return None
    b0n = np.zeros(3) if nominal_bias is None else np.asarray(nominal_bias, dtype=float)
    norms = np.linalg.norm((y - b0n) / scale, axis=1)
    return _g_from_magnitudes(_block_means(rec.t_s, norms), rec.sidecar.g_local_m_s2)


def calibrate_dynamic(
    rec: Recording,
    *,
    terms: tuple[str, ...] | None = None,
    nominal_scale: float | None = None,
    nominal_bias: FloatArray | None = None,
    cross_check: bool = True,
) -> DynamicCalibrationResult:
    """Fit the dynamic model to a moving-table recording (module docstring).

    :param terms: the extra terms to fit (declared, e.g. by the unit model); default: those
        the recording's evidence supports and its diagnosis claims (``claim_moving``: the
        catalogue's greedy selection less the steps a library term explains better, and less
        the claims the bench families' head to head withdraws; module docstring), so a
        calibration fits exactly the terms the diagnosis claims.
    :param nominal_scale: nominal sensitivity (channel unit per m/s²) for the 'before' check.
    :param cross_check: run the Kalman filter over the same data and compare.
    :raises ValueError: no table, too few samples, or a motion that cannot determine bias and K.
    """
    geo = rec.sidecar.table
    if geo is None or rec.table_deg is None:
        raise ValueError("a dynamic calibration needs the table (sidecar 'table' and table_i columns)")
    g = rec.sidecar.g_local_m_s2
    lever = np.asarray(geo.lever_arm_m, dtype=float)
    m, y = moving_samples(rec)
    if terms is None:
        whole = claim_moving(
            m, y, g, lever, temp_c=rec.temp_c, unit=rec.sidecar.unit_serial,
            channel_unit=rec.sidecar.channel_unit, source=rec.source, findings=False,
        )  # fmt: skip
        claim, sel = whole.catalogue, whole.catalogue.selection
        spec = ModelSpec(whole.terms)
        fit = claim.fit_of(whole.terms) or fit_dynamic_batch(m, y, g, lever, spec)
        dropped = {**sel.unobservable, **sel.rejected}
        dropped.update(dict.fromkeys(sel.chosen[claim.k :], f"replaced by the library: {claim.note}"))
        if whole.alternative is not None:
            why = f"withdrawn by the bench families' head to head: {whole.withdrawn}"
            dropped.update(dict.fromkeys((t for t in claim.terms if t not in whole.terms), why))
            for t in whole.terms:
                dropped.pop(t, None)
        claimed = (
            [{"term": t, "wald": w, "delta_bic": dbic} for t, dbic, w in sel.steps[: claim.k]]
            if whole.alternative is None
            else [
                {"term": f.effect, "wald": f.lr, "delta_bic": f.delta_bic}
                for f in whole.alternative.findings
                if f.effect in whole.terms
            ]
        )
        selection: dict[str, Any] = {
            "rule": "evidence",
            "text": (
                "terms the recording supports: each term the motion determines enters only if its "
                f"Wald test passes at false alarm {sel.false_alarm:g} per step (over the terms tried) "
                "and it lowers the BIC; the sidecar's geometry is kept for the others"
            ),
            "steps": claimed,
        }
    else:
        spec = ModelSpec(tuple(terms))
        implied = {"lever_arm"} if "proof_mass_offsets" in spec.terms else set()
        dropped = {t: "not declared" for t in CANDIDATE_TERMS if t not in terms and t not in implied}
        selection = {"rule": "declared", "text": "terms declared by the caller (e.g. the unit model)"}
        fit = fit_dynamic_batch(m, y, g, lever, spec)
    kal: dict[str, Any] = {}
    if cross_check:
        b0, K0 = linear_start(m, y, g, lever)
        kr = run_dynamic_kalman(
            m, y, g, lever, spec, initial_theta(spec, b0, K0, lever), fit.noise_sigma, smooth=False
        )
        z = (kr.final.x - fit.theta) / fit.sigma
        kal = {
            "max_abs_z": float(np.max(np.abs(z))),
            "worst": fit.names[int(np.argmax(np.abs(z)))],
            "agree": bool(np.max(np.abs(z)) < KALMAN_AGREEMENT_Z),
            "filter_sigma_over_batch_sigma_median": float(
                np.median(np.sqrt(np.diag(kr.final.P)) / fit.sigma)
            ),
        }
    fg = _corrected_gravity(fit, m, y, lever)
    after = _g_from_magnitudes(_block_means(rec.t_s[m.valid], np.linalg.norm(fg[m.valid], axis=1)), g)
    unit = rec.sidecar.channel_unit
    before = nominal_g_check(rec, y, nominal_scale, nominal_bias)
    extra, extra_sigma = _extra(fit)
    th, sg = fit.theta, fit.sigma
    return DynamicCalibrationResult(
        unit_serial=rec.sidecar.unit_serial,
        channel_unit=unit,
        procedure=rec.sidecar.procedure or "dynamic",
        kind=FitKind.MOVING,
        g_local_m_s2=g,
        bias=th[:3].copy(),
        K=th[3:12].reshape(3, 3).copy(),
        cov=fit.cov,
        bias_sigma=sg[:3].copy(),
        K_sigma=sg[3:12].reshape(3, 3).copy(),
        residual_rms=fit.residual_rms,
        chi2=float(3 * fit.n_used),
        dof=3 * fit.n_used - spec.n_params,
        noise_model=(
            f"per-sample residual sigma {' '.join(f'{v:.3g}' for v in fit.noise_sigma)}; covariance: "
            f"Newey-West sandwich over {fit.n_blocks} blocks, never below the white bound"
        ),
        g_after=after,
        g_before=before,
        windows=_static_windows(rec, fit, m, y, fg, lever),
        source=rec.source,
        fit=fit,
        extra=extra,
        extra_sigma=extra_sigma,
        not_fitted=dropped,
        kalman=kal,
        model_selection=selection,
        bias_reference=fit.bias_reference,
    )
