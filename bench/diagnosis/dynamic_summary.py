"""Residuals of a moving-table diagnosis: 1 s block means, per-channel mismatch, regressor correlations.

Regressors per sample (``motion_regressors``): with B = Mᵀ R_inᵀ (Ω̇ + Ω²) R_in
(``dynamic_model``; Ω = [ω]×), the symmetric part of B is the rotated Ω², whose trace is
−2|ω|², and the antisymmetric part the rotated Ω̇, so ω² = −tr(B)/2 and |ω̇| = |axial(B − Bᵀ)/2|;
f_i² and |f_i| (quadratic nonlinearity, scale asymmetry) from the final model's specific
force; its time derivative fdot_i (g/s: a delay of one channel shows there); time;
temperature. Correlation of each
channel's block-mean residual with each regressor's block mean after both are made
orthogonal to [1, f̄_x, f̄_y, f̄_z] (what bias and K absorb), significant when
|ρ|√(n_b − 5)/√(1 − ρ²) exceeds Student's t at 0.01 / (2 · 3 · number of regressors).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.stats import t as t_dist

from bench.diagnosis.dynamic_coherence import Coherence, block_coherence
from bench.diagnosis.regressors import Correlation
from bench.diagnosis.result import ModelSummary, Unexplained
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.dynamic_batch import DynamicFit
from bench.estimation.dynamic_model import predict, specific_force
from bench.estimation.motion_data import MotionData, sample_chunks

FloatArray = np.ndarray
CHANNELS = ("ax", "ay", "az")


@dataclass(frozen=True)
class BlockSummary:
    """What the report shows of a dynamic diagnosis."""

    baseline: ModelSummary
    final: ModelSummary
    channel_ratio: FloatArray
    where: str
    """The strongest block of the first-order mismatch (``residuals.where_text`` words it)."""
    where_beyond: bool
    """Whether that block lies beyond ``Thresholds.where_z`` sigma."""
    correlations: tuple[Correlation, ...]
    labels: tuple[str, ...]
    mid_s: FloatArray
    final_ratio: FloatArray | None = None
    """(3,) the final model's per-channel Σ (r/σ_w)² / (n_used − 4)."""
    final_correlations: tuple[Correlation, ...] = ()
    """Regressor correlations of the final model's block residuals."""
    coherence: Coherence | None = None
    """The final model's block means against their own noise (``dynamic_coherence``)."""


def motion_regressors(
    m: MotionData, y: FloatArray, fit: DynamicFit, g: float, lever: FloatArray, temp_c: FloatArray | None
) -> dict[str, FloatArray]:
    """Name -> (n,) regressor per sample (module docstring)."""
    out = {"omega^2": np.empty(m.n), "|omega_dot|": np.empty(m.n)}
    for s in sample_chunks(m.n):  # B per sample: chunks bound the (chunk, 3, 3) regressors
        B = m.take(s, rates=False).B
        out["omega^2"][s] = -0.5 * np.trace(B, axis1=1, axis2=2)
        a_zy, a_xz, a_yx = (0.5 * (B[:, i, j] - B[:, j, i]) for i, j in ((2, 1), (0, 2), (1, 0)))
        out["|omega_dot|"][s] = np.sqrt(a_zy**2 + a_xz**2 + a_yx**2)  # the antisymmetric part of B is [ω̇]×
    f = specific_force(fit.theta, m, fit.spec, g, lever)
    for i, a in enumerate("xyz"):
        out[f"f_{a}^2"] = f[:, i] ** 2
    for i, a in enumerate("xyz"):
        out[f"|f_{a}|"] = np.abs(f[:, i])
    for i, a in enumerate("xyz"):
        out[f"f_{a}"] = f[:, i]
    fdot = np.gradient(f, m.t_s, axis=0) / 9.80665
    for i, a in enumerate("xyz"):
        out[f"fdot_{a}"] = fdot[:, i]
    out["time"] = m.t_s - m.t_s[0]
    if temp_c is not None and np.all(np.isfinite(temp_c)):
        out["temperature"] = np.asarray(temp_c, dtype=float)
    return out


def _blocks(t: FloatArray, valid: np.ndarray, block_s: float) -> tuple[np.ndarray, np.ndarray]:
    blk = np.floor((t - t[0]) / block_s).astype(np.int64)
    blk = np.where(valid, blk, -1)
    ids, inv, counts = np.unique(blk[valid], return_inverse=True, return_counts=True)
    keep = counts >= 10
    kept_index = np.cumsum(keep) - 1  # a block's index among the kept ones
    return ids[keep], np.where(keep[inv], kept_index[inv], -1)


def _bmean(v: FloatArray, inv: np.ndarray, nb: int) -> FloatArray:
    ok = inv >= 0
    cnt = np.bincount(inv[ok], minlength=nb)
    if v.ndim == 1:
        return np.bincount(inv[ok], weights=v[ok], minlength=nb) / cnt
    return np.column_stack(
        [np.bincount(inv[ok], weights=v[ok, i], minlength=nb) / cnt for i in range(v.shape[1])]
    )


def block_summary(
    m: MotionData,
    y: FloatArray,
    fits: list[DynamicFit],
    g: float,
    lever: FloatArray,
    sig_w: FloatArray,
    regs: dict[str, FloatArray],
    n_obs: int,
    *,
    library: FloatArray | None = None,
    library_terms: tuple[str, ...] = (),
    th: Thresholds = THRESHOLDS,
) -> BlockSummary:
    """Baseline and final model summaries, mismatch and correlates (module docstring).

    :param library: (n, 3) the discovered terms' contribution Σ c_k x_k (channel units), part
        of the final model only; :param library_terms: their labels, ``term[channel]``.
    """
    v = m.valid
    ids, inv = _blocks(m.t_s[v], np.ones(int(v.sum()), dtype=bool), th.block_s)
    nb = ids.size
    cnt = np.bincount(inv[inv >= 0], minlength=nb)
    summaries = []
    resid0 = None
    resid1 = None
    for k, fit in enumerate((fits[0], fits[-1])):
        model, _ = predict(fit.theta, m, fit.spec, g, lever)
        extra = library_terms if k == 1 else ()
        if k == 1 and library is not None:
            model = model + library
        r = (y - model)[v]
        resid1 = r
        if resid0 is None:
            resid0 = r
        br = _bmean(r, inv, nb)
        z = br / (sig_w[None, :] / np.sqrt(cnt)[:, None])
        p = fit.spec.n_params + len(extra)
        summaries.append(
            ModelSummary(
                terms=("bias", "scale_matrix", *fit.spec.terms, *extra),
                residual_rms=float(fit.residual_rms),
                chi2_dof=float(np.sum((r / sig_w) ** 2) / (n_obs - p)),
                bic=float(fit.n_used * np.sum(np.log(fit.noise_sigma**2)) + p * np.log(n_obs)),
                resid=br,
                z=z,
            )
        )
    assert resid0 is not None
    ratio = np.sum((resid0 / sig_w) ** 2, axis=0) / max(resid0.shape[0] - 4, 1)
    base = summaries[0]
    w, i = np.unravel_index(int(np.argmax(np.abs(base.z))), base.z.shape)
    mid = (ids + 0.5) * th.block_s + float(m.t_s[v][0])
    located = (
        f"a{'xyz'[i]}, strongest in the {th.block_s:g} s block at t = {mid[w]:.0f} s "
        f"(block mean {base.z[w, i]:+.1f} sigma)"
    )
    beyond = bool(abs(base.z[w, i]) > th.where_z)
    breg = {k: _bmean(x[v], inv, nb) for k, x in regs.items() if not k.startswith("f_") or k.endswith("^2")}
    F = np.column_stack([np.ones(nb), *(_bmean(regs[f"f_{a}"][v], inv, nb) for a in "xyz")])
    assert resid1 is not None
    return BlockSummary(
        baseline=base,
        final=summaries[1],
        channel_ratio=ratio,
        where=located,
        where_beyond=beyond,
        correlations=tuple(_block_correlations(base.resid, breg, F, th.correlation_significance)),
        labels=tuple(f"t={x:.0f}s" for x in mid),
        mid_s=mid,
        final_ratio=np.sum((resid1 / sig_w) ** 2, axis=0) / max(resid1.shape[0] - 4, 1),
        final_correlations=tuple(
            _block_correlations(summaries[1].resid, breg, F, th.correlation_significance)
        ),
        coherence=block_coherence(summaries[1].resid, cnt, F, th.coherence_trend_degree),
    )


def _block_correlations(
    resid: FloatArray, breg: dict[str, FloatArray], F: FloatArray, significance: float
) -> list[Correlation]:
    """Correlations of (nb, 3) block residuals with each block regressor, after [1, f̄] (module docstring)."""
    nb = resid.shape[0]
    corr: list[Correlation] = []
    dof = nb - 5
    if dof >= 1:
        crit = float(t_dist.ppf(1.0 - significance / (2.0 * 3 * len(breg)), dof))
        Q, _ = np.linalg.qr(F)
        rr = resid - Q @ (Q.T @ resid)
        for name, x in breg.items():
            xt = x - Q @ (Q.T @ x)
            nx = float(np.linalg.norm(xt))
            if nx <= 1e-9 * max(float(np.linalg.norm(x)), 1e-300):
                continue
            for c in range(3):
                ne = float(np.linalg.norm(rr[:, c]))
                if ne == 0:
                    continue
                rho = float(rr[:, c] @ xt / (nx * ne))
                tval = abs(rho) * np.sqrt(dof) / np.sqrt(max(1.0 - rho * rho, 1e-12))
                corr.append(Correlation(name, c, rho, bool(tval > crit)))
    corr.sort(key=lambda c: -abs(c.rho))
    return corr


def unexplained_blocks(bs: BlockSummary, th: Thresholds) -> Unexplained | None:
    """The final model against the recording's own noise, per channel: the samples' excess over
    the white noise (``th.dynamic_ratio_limit``) and the coherence of the 1 s block means
    (``dynamic_coherence``, lower tail at ``th.unexplained_alpha`` / 3 per channel)."""
    assert bs.final_ratio is not None
    ratio = bs.final_ratio
    coh = bs.coherence
    alpha = th.unexplained_alpha / 3
    p_coh = coh.p_value if coh is not None else np.ones(3)
    excess = ratio > th.dynamic_ratio_limit
    coherent = p_coh < alpha
    if not (excess.any() or coherent.any()):
        return None
    ch = int(np.argmin(p_coh)) if coherent.any() else int(np.argmax(ratio))
    z = bs.final.z
    w = int(np.argmax(np.abs(z[:, ch])))
    names: list[str] = []
    for c in bs.final_correlations:
        if c.significant and f"{c.regressor} on {CHANNELS[c.channel]}" not in names:
            names.append(f"{c.regressor} on {CHANNELS[c.channel]}")
    others = ", ".join(f"{CHANNELS[i]} {ratio[i]:.2f}" for i in range(3) if i != ch)
    coh_text = (
        ""
        if coh is None
        else f"; block means coherent (von Neumann ratio {coh.ratio[ch]:.2f}, "
        f"expected {coh.expected[ch]:.2f} "
        f"for independent blocks, p = {p_coh[ch]:.2g})"
    )
    return Unexplained(
        chi2_dof=float(bs.final.chi2_dof),
        test=(
            f"per channel: the {th.block_s:g} s block means' von Neumann ratio after bias, K and a "
            f"degree-{th.coherence_trend_degree} trend, lower tail at {alpha:.2g}; and the sum of "
            f"(residual / white sigma)^2 over its dof above {th.dynamic_ratio_limit:g} "
            "(clean simulated moving recordings: 0.93-1.10)"
        ),
        p_value=float(min(1.0, 3.0 * float(np.min(p_coh)))),
        where=(
            f"{CHANNELS[ch]}: {ratio[ch]:.2f} times the white noise ({others}){coh_text}, strongest in the "
            f"{th.block_s:g} s block {bs.labels[w]} (block mean {z[w, ch]:+.1f} sigma)"
        ),
        correlates_with=tuple(names),
        channels={CHANNELS[i]: float(ratio[i]) for i in range(3)},
    )
