"""The term library for moving-table recordings: products of what the motion offers.

Base quantities per sample (``docs/cli-contract.md``, "Beyond the catalogue"), from the final
catalogue model θ̂ of the dynamic diagnosis (``dynamic_model``):

    f_x, f_y, f_z          modelled specific force, lever arm, tilt and skew included (g)
    abs(f_x) … abs(f_z)    its magnitudes (g)
    temp                   sensor temperature − 25 °C (only when it varies by ≥ 0.05 °C)
    t                      time since the recording's first sample (s)
    w_x, w_y, w_z          angular rate of the sensor frame, sensor axes (rad/s)
    dw_x, dw_y, dw_z       angular acceleration, sensor axes (rad/s²)
    fdot_x … fdot_z        time derivative of the modelled specific force (g/s)

With G = Mᵀ R_inᵀ (base -> sensor) and Ṙ_in = [ω]× R_in (ω in base coordinates,
Titterton & Weston §3.2), Ġ = −G [ω]×, so the sensor-axis rate is [ω_s]× = −Ġ Gᵀ and,
differentiating once more, [ω̇_s]× = −(G̈ Gᵀ + Ġ Ġᵀ) (ω̇_s = G ω̇: the sensor-axis
components of the angular acceleration). ḟ = Ġ g_base + Ḃ q (``dynamic_model``), from the
Savitzky–Golay derivatives the motion already carries.

Candidates are the monomials of degree 1 to 3 of these bases, each on one output channel
i (raw_i += c·x, c in channel units per unit of x). Left out:

- the first-order model's own columns (f_j alone), powers of abs(·) above one, and the
  static catalogue's regressors on the channel they act on (f_i², abs(f_i), f_j·f_k: the
  quadratic nonlinearity, scale asymmetry and cross-coupling), as in ``library``;
- monomials of t and temp alone (t, t², temp·t, …): a bias wander makes such slow trends
  over one run, and nothing in a moving recording measures the wander at the run's length
  (``moving_report.STATIC_ONLY``, bias_drift);
- what the catalogue's motion effects are (the lever arm's ω²·r and ω̇·r, the proof
  masses, the common time skew K·ḟ, the tilt): not by name but by signature, in the search
  (``library_motion_search``): a term whose signature beyond the fitted model lies within
  |cos| 0.8 of the span of the catalogue terms not in the model is the catalogue's, and one
  with relative leverage < ``Thresholds.relative_leverage_min`` beyond the fitted model is not
  determined; a term identical to a simpler one beyond the model (|cos| > 1 − ``Thresholds.alias_tol``)
  is its alias.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import combinations_with_replacement

import numpy as np

from bench.diagnosis.effects.sensor import REFERENCE_TEMP_C
from bench.diagnosis.library import (
    Base,
    LibraryTerm,
    NamedTerm,
    admissible,
    in_catalogue,
    term_name,
    term_unit,
)
from bench.diagnosis.library import physics as static_physics
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.dynamic_batch import DynamicFit
from bench.estimation.dynamic_model import G0_M_S2, gravity_base, positions, specific_force
from bench.estimation.motion_data import MotionData, sample_chunks

FloatArray = np.ndarray
AXES = "xyz"
CHANNELS = ("ax", "ay", "az")
SLOW_KINDS = frozenset({"t", "temp"})
__all__ = ["MotionTerm", "base_values", "motion_bases", "motion_monomials", "motion_physics"]


def _axial(S: FloatArray) -> FloatArray:
    """(n, 3) axial vector of the antisymmetric part of (n, 3, 3) matrices."""
    A = 0.5 * (S - np.transpose(S, (0, 2, 1)))
    return np.stack([A[:, 2, 1], A[:, 0, 2], A[:, 1, 0]], axis=1)


def sensor_rates(m: MotionData) -> tuple[FloatArray, FloatArray]:
    """(n, 3) ω_s (rad/s) and (n, 3) ω̇_s (rad/s²), sensor axes (module docstring).

    Formed ``sample_chunks`` at a time: each sample's rates depend on that sample alone, so the
    chunks bound the (chunk, 3, 3) products.
    """
    w, dw = np.empty((m.n, 3)), np.empty((m.n, 3))
    for s in sample_chunks(m.n):
        ms = m.take(s)
        G, G_dot = ms.G, ms.G_dot
        Gt = np.transpose(G, (0, 2, 1))
        w[s] = _axial(-G_dot @ Gt)
        dw[s] = _axial(-(ms.G_ddot @ Gt + G_dot @ np.transpose(G_dot, (0, 2, 1))))
    return w, dw


def force_rate(fit: DynamicFit, m: MotionData, g_m_s2: float, lever: FloatArray) -> FloatArray:
    """(n, 3) ḟ = Ġ g_base + Ḃ q of the fitted model (m/s²/s), ``sample_chunks`` at a time."""
    gb, _ = gravity_base(fit.theta, fit.spec, g_m_s2)
    Q = positions(fit.theta, fit.spec, lever)
    out = np.empty((m.n, 3))
    for s in sample_chunks(m.n):
        ms = m.take(s)
        out[s] = ms.G_dot @ gb + np.einsum("nic,ic->ni", ms.B_dot, Q)
    return out


def motion_bases(
    m: MotionData,
    fit: DynamicFit,
    g_m_s2: float,
    lever: FloatArray,
    temp_c: FloatArray | None,
    th: Thresholds = THRESHOLDS,
) -> tuple[tuple[Base, ...], dict[str, FloatArray]]:
    """The base quantities this moving recording offers and their (n,) values (module docstring).

    :param m: the motion; :param fit: the final catalogue model; :param lever: (3,) believed lever arm (m).
    :param temp_c: (n,) temperature (°C) or ``None``.
    """
    f = specific_force(fit.theta, m, fit.spec, g_m_s2, lever) / G0_M_S2
    w, dw = sensor_rates(m)
    fdot = force_rate(fit, m, g_m_s2, lever) / G0_M_S2
    out: list[Base] = []
    vals: dict[str, FloatArray] = {}

    def add(b: Base, v: FloatArray) -> None:
        out.append(b)
        vals[b.name] = np.asarray(v, dtype=float)

    for i, a in enumerate(AXES):
        add(Base(f"f_{a}", "g", i, "f"), f[:, i])
    for i, a in enumerate(AXES):
        add(Base(f"abs(f_{a})", "g", i, "abs"), np.abs(f[:, i]))
    if temp_c is not None:
        tc = np.asarray(temp_c, dtype=float)
        ok = tc[m.valid]
        if np.all(np.isfinite(ok)) and float(np.ptp(ok)) >= th.min_temperature_span_c:
            add(Base("temp", "°C", -1, "temp"), np.where(np.isfinite(tc), tc - REFERENCE_TEMP_C, 0.0))
    add(Base("t", "s", -1, "t"), m.t_s - m.t_s[0])
    for i, a in enumerate(AXES):
        add(Base(f"w_{a}", "rad/s", i, "w"), w[:, i])
    for i, a in enumerate(AXES):
        add(Base(f"dw_{a}", "rad/s^2", i, "dw"), dw[:, i])
    for i, a in enumerate(AXES):
        add(Base(f"fdot_{a}", "g/s", i, "fdot"), fdot[:, i])
    return tuple(out), vals


@dataclass(frozen=True)
class MotionTerm(NamedTerm):
    """A monomial of the moving library on one channel.

    :param term: the contract's grammar, e.g. ``f_x*w_z``; :param channel: output channel 0, 1, 2.
    :param factors: its bases, with repetition, in canonical order; :param unit: e.g. ``g·rad/s``.
    :param aliases: simpler-named twins with the same signature beyond the model on this recording.
    """

    term: str
    channel: int
    factors: tuple[Base, ...]
    unit: str
    aliases: tuple[str, ...] = ()


def _admissible(factors: tuple[Base, ...]) -> bool:
    if {b.kind for b in factors} <= SLOW_KINDS:
        return False  # a slow trend: the bias wander makes those (module docstring)
    return admissible(factors)


def motion_monomials(bases: tuple[Base, ...], th: Thresholds = THRESHOLDS) -> list[tuple[Base, ...]]:
    """Admissible monomials of degree 1..``th.max_degree`` of ``bases``, simplest first."""
    out = []
    for degree in range(1, th.max_degree + 1):
        for combo in combinations_with_replacement(range(len(bases)), degree):
            factors = tuple(bases[k] for k in combo)
            if _admissible(factors):
                out.append(factors)
    return out


def candidate_terms(bases: tuple[Base, ...], th: Thresholds = THRESHOLDS) -> list[MotionTerm]:
    """Every (monomial, channel) pair the library may try, before the recording's own checks."""
    out = []
    for factors in motion_monomials(bases, th):
        name, unit = term_name(factors), term_unit(factors)
        for ch in range(3):
            if not in_catalogue(factors, ch):
                out.append(MotionTerm(name, ch, factors, unit))
    return out


def base_values(
    vals: dict[str, FloatArray], factors: tuple[Base, ...], idx: slice | np.ndarray
) -> FloatArray:
    """The monomial's values at the samples ``idx``."""
    x = np.ones_like(vals["t"][idx])
    for b in factors:
        x = x * vals[b.name][idx]
    return x


def motion_physics(t: MotionTerm, coefficient: float, K: FloatArray) -> str:
    """One sentence of physics where the term has a known meaning, else a plain statement.

    ``fdot_i`` on channel i: raw_i = b_i + K_i·f(t − τ_i) ≈ … − K_ii τ_i ḟ_i, so a coefficient
    c (channel units per g/s) is a delay τ_i = −c / (K_ii g0) of that channel alone.
    """
    a = AXES[t.channel]
    kinds = [b.kind for b in t.factors]
    axes = [AXES[b.axis] for b in t.factors]
    if kinds == ["fdot"] and t.factors[0].axis == t.channel:
        tau_ms = -coefficient / (float(K[t.channel, t.channel]) * G0_M_S2) * 1e3
        return (
            f"a delay of the {a} channel alone of {tau_ms:.3g} ms behind the others (its own sampling, "
            "filter or multiplexer lags): the catalogue's time_skew delays all channels together"
        )
    if kinds == ["fdot"]:
        return (
            f"the {a} channel responds to the rate of change of the {axes[0]} input "
            "(a dynamic cross-axis coupling)"
        )
    if kinds in (["w", "w"],):
        what = f"ω_{axes[0]}²" if axes[0] == axes[1] else f"ω_{axes[0]}·ω_{axes[1]}"
        return (
            f"the {a} channel's bias follows {what}: a centripetal load the lever-arm model does not have "
            "(a cable or a flexing mount), or a rate-dependent pick-up"
        )
    if kinds == ["dw"]:
        return (
            f"the {a} channel follows the angular acceleration about {axes[0]}: a tangential force on a mass "
            "the lever-arm model does not place"
        )
    if kinds == ["w"]:
        return (
            f"the {a} channel follows the angular rate about {axes[0]} "
            "(a rate-dependent bias: slip ring, Coriolis pick-up)"
        )
    if set(kinds) <= {"f", "abs", "temp", "t"}:
        lt = LibraryTerm(t.term, t.channel, t.factors, t.unit, np.zeros(0), 1.0)
        return static_physics(lt)
    return f"a term proportional to {t.term} on {CHANNELS[t.channel]} that the model lacks"
