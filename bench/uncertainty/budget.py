"""Uncertainty budget of a static calibration (GUM, JCGM 100:2008): Type A + Type B, per quantity.

The fitted parameters θ = [b_x, b_y, b_z, K_xx, …, K_zz] (``static_design.PARAMETER_NAMES``) of

    y_w = b + K f_w          (window means y_w, specific force f_w, w = 1…m)

depend on input quantities the fit takes as exact: the table angles, the levelling of the
table base and the local gravity value (through f_w), the DAQ's gain and offset and the unit's
temperature coefficients (through y_w). Each such input X with standard uncertainty u(X) is a
:class:`TypeBInput`: the change of every window's f_w and y_w per unit change of X (the
linearisation of the measurement model, GUM 5.1.3). Its sensitivity c = ∂θ/∂X is found

* by refitting (``method="refit"``): the noise-free means y⁰_w = b + K f_w are refitted with
  the design moved by ±h (f_w ± h ∂f_w/∂X, y⁰_w ± h ∂y_w/∂X), c = (θ₊ − θ₋) / 2h;
* analytically (``method="analytic"``): at zero residual the generalised least-squares
  estimate θ = (Σ Hᵀ W H)⁻¹ Σ Hᵀ W y moves by

      ∂θ/∂X = (Σ_w H_wᵀ W_w H_w)⁻¹ Σ_w H_wᵀ W_w (∂y_w/∂X − K ∂f_w/∂X),

  H_w = [I₃, I₃ ⊗ f_wᵀ], W_w the inverse of the window covariance.

Each quantity's combined standard uncertainty (GUM 5.1.2, uncorrelated inputs) is

    u_c² = u_A² + Σ_X (c_X u(X))²

with u_A the fit's own standard uncertainty (Type A, from its covariance; for the static fit
with each input's expected share of the fit's between-window excess taken out first,
``bench.uncertainty.type_a``, so an input that leaves residuals is counted once). Effective degrees of
freedom (Welch–Satterthwaite, GUM G.4.1): ν_eff = u_c⁴ / Σ_i (u_i⁴ / ν_i). The coverage factor
is k = t_p(ν_eff) with p = 95.45 % and ν_eff rounded down to an integer (GUM G.6.4,
EA-4/02 M:2022 Annex E), which is 2 for ν_eff = ∞; U = k u_c.

The Type A part of a static fit with an independent excess per window is the unbiased estimate
of ``bench.uncertainty.type_a`` with its Satterthwaite degrees of freedom (``type_a_dof``), so
k = t_p(ν_eff) > 2 where the excess between the windows is poorly determined. Otherwise (a
moving fit, a fit with the slow wander) the Type A part is taken with ν = ∞: the fit reports the
standard deviation of the Student-t distribution of its estimated variance components (its
covariance multiplied by ν/(ν − 2), JCGM 101:2008 6.4.9), and k = 2 on that standard deviation
covers at least 95 % for every ν ≥ 3 (2√(ν/(ν − 2)) ≥ t_0.975(ν)). A Type B input is ν = ∞ unless it states
otherwise (GUM G.4.3: a u taken from a calibration certificate or a specification).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
from scipy.stats import t as student_t

from bench.estimation.static_design import PARAMETER_NAMES, design_rows

FloatArray = npt.NDArray[np.float64]

COVERAGE_PROBABILITY = 0.9545
"""p of k = t_p(ν_eff): k = 2 for ν_eff = ∞ (EA-4/02 M:2022 Annex E)."""
TYPE_A_NAME = "Type A: window noise and between-window scatter (fit covariance)"
RULE = (
    "u_c² = u_A² + Σ (c_i u(x_i))² (uncorrelated inputs, sensitivities c_i by linearisation of the "
    "fit); ν_eff by Welch–Satterthwaite (Type A and Type B inputs with ν = ∞ unless stated); "
    "k = t_95.45 %(ν_eff) with ν_eff rounded down (k = 2 for ν_eff = ∞); U = k·u_c"
)


WANDER_GROUP = "bias wander over the run"
"""Budget group of the unit's bias wander averaged over the run (``bench.uncertainty.dynamic``):
what one run's bias differs by from the unit's long-run bias."""


@dataclass(frozen=True)
class TypeBInput:
    """One input quantity X of the measurement model, and how it moves the fit's design.

    :param name: what X is (e.g. ``"DAQ gain, channel x"``).
    :param u: standard uncertainty u(X) (>= 0), in ``unit``.
    :param unit: unit of X.
    :param df_m_s2: (m, 3) ∂f_w/∂X, change of each window's specific force per unit X, or ``None``.
    :param dy: (m, 3) ∂y_w/∂X, change of each window's mean output (channel units) per unit X, or ``None``.
    :param group: row of the budget table X belongs to (e.g. ``"DAQ gain"`` for all channels).
    :param channel: the output channel X belongs to (0, 1, 2), ``None`` for a common input.
    :param dof: degrees of freedom of u(X) (``math.inf``: known reliably).
    :param basis: where u(X) comes from (distribution, divisor, source).
    """

    name: str
    u: float
    unit: str
    df_m_s2: FloatArray | None = None
    dy: FloatArray | None = None
    group: str = ""
    channel: int | None = None
    dof: float = math.inf
    basis: str = ""


@dataclass(frozen=True)
class Contribution:
    """One line of a quantity's budget: |c|·u(X) in the quantity's unit."""

    name: str
    group: str
    channel: int | None
    u: float
    unit: str
    sensitivity: float
    contribution: float
    dof: float


@dataclass(frozen=True)
class QuantityBudget:
    """Budget of one parameter (``b_x`` … ``K_zz``): value, contributions, u_c, ν_eff, k, U."""

    name: str
    value: float
    contributions: tuple[Contribution, ...]
    u_c: float
    nu_eff: float
    k: float
    U: float


@dataclass(frozen=True)
class Budget:
    """Budgets of the 12 parameters in ``PARAMETER_NAMES`` order, and the inputs' sensitivities.

    :param sensitivity: (n_inputs, 12) ∂θ/∂X per input, in the order of ``inputs``.
    """

    quantities: tuple[QuantityBudget, ...]
    inputs: tuple[TypeBInput, ...]
    sensitivity: FloatArray
    method: str

    def by_name(self, name: str) -> QuantityBudget:
        """The budget of parameter ``name`` (``"b_x"``, ``"K_yy"``…)."""
        return self.quantities[PARAMETER_NAMES.index(name)]

    @property
    def u_c(self) -> FloatArray:
        """(12,) combined standard uncertainties."""
        return np.array([q.u_c for q in self.quantities])


def coverage_factor(nu_eff: float) -> float:
    """k = t_p(⌊ν_eff⌋), p = 95.45 % (two-sided); 2 for ν_eff = ∞.

    :raises ValueError: ν_eff < 1.
    """
    if math.isinf(nu_eff):
        return 2.0
    if not nu_eff >= 1.0:
        raise ValueError(f"effective degrees of freedom must be >= 1, got {nu_eff}")
    return float(student_t.ppf(0.5 + COVERAGE_PROBABILITY / 2, float(math.floor(nu_eff))))


def welch_satterthwaite(u: Sequence[float], dof: Sequence[float]) -> float:
    """ν_eff = (Σ u_i²)² / Σ (u_i⁴ / ν_i) (GUM G.4.1); ∞ when every ν_i is ∞ or u_c = 0."""
    ua, na = np.asarray(u, dtype=float), np.asarray(dof, dtype=float)
    finite = np.isfinite(na) & (ua > 0)
    uc2 = float(np.sum(ua**2))
    if uc2 == 0.0 or not np.any(finite):
        return math.inf
    return uc2**2 / float(np.sum(ua[finite] ** 4 / na[finite]))


def _gls(f: FloatArray, y: FloatArray, W: FloatArray) -> FloatArray:
    """θ (12,) of the joint GLS with window weights W (m, 3, 3)."""
    H = design_rows(f)
    HtW = np.einsum("wai,wab->wib", H, W)
    N = np.einsum("wib,wbj->ij", HtW, H)
    return np.asarray(np.linalg.solve(N, np.einsum("wib,wb->i", HtW, y)), dtype=float)


def _weights(m: int, window_cov: FloatArray | None) -> FloatArray:
    if window_cov is None:
        return np.broadcast_to(np.eye(3), (m, 3, 3)).copy()
    S = np.asarray(window_cov, dtype=float)
    if S.shape != (m, 3, 3) or not np.all(np.isfinite(S)):
        raise ValueError(f"window covariances must be finite with shape ({m}, 3, 3), got {S.shape}")
    return np.asarray(np.linalg.inv(0.5 * (S + np.transpose(S, (0, 2, 1)))), dtype=float)


def moves(inp: TypeBInput, m: int) -> tuple[FloatArray, FloatArray]:
    """(∂f_w/∂X, ∂y_w/∂X), each (m, 3), of input ``inp`` (zeros where it moves nothing).

    :raises ValueError: a wrong shape, a non-finite move or a bad u(X) (named with the input).
    """
    zero = np.zeros((m, 3))
    df = zero if inp.df_m_s2 is None else np.asarray(inp.df_m_s2, dtype=float)
    dy = zero if inp.dy is None else np.asarray(inp.dy, dtype=float)
    if df.shape != (m, 3) or dy.shape != (m, 3):
        raise ValueError(f"input {inp.name!r}: moves must have shape ({m}, 3), got {df.shape}, {dy.shape}")
    if not (np.all(np.isfinite(df)) and np.all(np.isfinite(dy))):
        raise ValueError(f"input {inp.name!r}: moves are not finite")
    if not (math.isfinite(inp.u) and inp.u >= 0):
        raise ValueError(f"input {inp.name!r}: standard uncertainty must be finite and >= 0, got {inp.u}")
    return df, dy


def sensitivities(
    f_m_s2: FloatArray,
    bias: FloatArray,
    K: FloatArray,
    inputs: Sequence[TypeBInput],
    *,
    window_cov: FloatArray | None = None,
    method: str = "analytic",
) -> FloatArray:
    """(n_inputs, 12) ∂θ/∂X of each input (see the module docstring for the two methods).

    :param f_m_s2: (m, 3) specific force of the fit's windows (m/s²).
    :param bias: (3,) fitted bias; :param K: (3, 3) fitted scale matrix.
    :param window_cov: (m, 3, 3) covariance of each window mean used by the fit as weights;
        ``None``: equal weights (ordinary least squares).
    :param method: ``"analytic"`` or ``"refit"``.
    :raises ValueError: shapes or values wrong, unknown method.
    """
    f = np.asarray(f_m_s2, dtype=float)
    b, Km = np.asarray(bias, dtype=float).reshape(3), np.asarray(K, dtype=float).reshape(3, 3)
    if f.ndim != 2 or f.shape[1] != 3 or f.shape[0] < 4 or not np.all(np.isfinite(f)):
        raise ValueError(f"specific forces must be finite with shape (m >= 4, 3), got {f.shape}")
    m = f.shape[0]
    W = _weights(m, window_cov)
    y0 = b + f @ Km.T
    out = np.zeros((len(inputs), 12))
    if method == "analytic":
        H = design_rows(f)
        HtW = np.einsum("wai,wab->wib", H, W)
        N = np.einsum("wib,wbj->ij", HtW, H)
        for n, inp in enumerate(inputs):
            df, dy = moves(inp, m)
            out[n] = np.linalg.solve(N, np.einsum("wib,wb->i", HtW, dy - df @ Km.T))
    elif method == "refit":
        for n, inp in enumerate(inputs):
            df, dy = moves(inp, m)
            h = inp.u if inp.u > 0 else 1e-6
            plus = _gls(f + h * df, y0 + h * dy, W)
            minus = _gls(f - h * df, y0 - h * dy, W)
            out[n] = (plus - minus) / (2 * h)
    else:
        raise ValueError(f"unknown sensitivity method {method!r} (analytic or refit)")
    return out


def uncertainty_budget(
    f_m_s2: FloatArray,
    bias: FloatArray,
    K: FloatArray,
    cov_type_a: FloatArray,
    inputs: Sequence[TypeBInput],
    *,
    window_cov: FloatArray | None = None,
    method: str = "analytic",
    type_a_dof: FloatArray | None = None,
    known: tuple[Sequence[TypeBInput], FloatArray] | None = None,
    type_a_name: str = TYPE_A_NAME,
) -> Budget:
    """The budget of the 12 parameters of a static fit.

    :param cov_type_a: (12, 12) the fit's covariance (``StaticFit.cov``), the Type A part.
    :param type_a_dof: (12,) degrees of freedom of each Type A variance (``type_a.TypeA.dof``);
        ``None``: ∞.
    :param known: inputs whose sensitivities (n, 12) are known already, not a move of the design
        (the unit's bias wander over the run, ``bench.uncertainty.wander``); listed after ``inputs``.
    :param type_a_name: the Type A line's name.
    :returns: :class:`Budget`; each quantity lists the Type A line first, then every input.
    :raises ValueError: see :func:`sensitivities`; a non-finite or wrongly shaped covariance.
    """
    C = np.asarray(cov_type_a, dtype=float)
    if C.shape != (12, 12) or not np.all(np.isfinite(C)) or np.any(np.diag(C) < 0):
        raise ValueError(
            f"Type A covariance must be finite (12, 12) with a non-negative diagonal, got {C.shape}"
        )
    sens = sensitivities(f_m_s2, bias, K, inputs, window_cov=window_cov, method=method)
    theta = np.concatenate([np.asarray(bias, dtype=float).reshape(3), np.asarray(K, dtype=float).ravel()])
    all_inputs = list(inputs)
    if known is not None:
        all_inputs += list(known[0])
        sens = np.vstack([sens, np.asarray(known[1], dtype=float).reshape(len(known[0]), 12)])
    return combine(theta, C, all_inputs, sens, method, type_a_name, type_a_dof)


def combine(
    theta: FloatArray,
    cov_type_a: FloatArray,
    inputs: Sequence[TypeBInput],
    sens: FloatArray,
    method: str,
    type_a_name: str = TYPE_A_NAME,
    type_a_dof: FloatArray | None = None,
) -> Budget:
    """The budget from the sensitivities ``sens`` (n_inputs, 12) of θ (12,) to each input, however found.

    :param cov_type_a: (12, 12) the fit's covariance, the Type A part (its diagonal is used).
    :param method: how ``sens`` was found (stored in :class:`Budget`).
    :param type_a_name: the Type A line's name (its group is ``"Type A"``).
    :param type_a_dof: (12,) the Type A line's degrees of freedom; ``None``: ∞.
    """
    C = np.asarray(cov_type_a, dtype=float)
    nu_a = np.full(12, math.inf) if type_a_dof is None else np.asarray(type_a_dof, dtype=float)
    quantities = []
    for j, name in enumerate(PARAMETER_NAMES):
        u_a = math.sqrt(C[j, j])
        lines = [Contribution(type_a_name, "Type A", None, u_a, "", 1.0, u_a, float(nu_a[j]))]
        for n, inp in enumerate(inputs):
            c = float(sens[n, j])
            lines.append(
                Contribution(
                    inp.name, inp.group or inp.name, inp.channel, inp.u, inp.unit, c, abs(c) * inp.u, inp.dof
                )
            )
        u_c = math.sqrt(sum(x.contribution**2 for x in lines))
        nu = welch_satterthwaite([x.contribution for x in lines], [x.dof for x in lines])
        nu = max(nu, min(x.dof for x in lines))  # ν_eff ≥ min ν_i; only rounding breaks it
        k = coverage_factor(nu)
        quantities.append(QuantityBudget(name, float(theta[j]), tuple(lines), u_c, nu, k, k * u_c))
    return Budget(tuple(quantities), tuple(inputs), sens, method)
