"""A library of terms beyond the catalogue: products of what a static recording offers.

Base quantities of a static window w (``docs/cli-contract.md``, "Beyond the catalogue"):

    f_x, f_y, f_z        specific force from the believed geometry (g = 9.80665 m/s²)
    abs(f_x) … abs(f_z)  its magnitudes (g)
    temp                 sensor temperature − 25 °C (only when it varies over the windows)
    t                    window mid time since the recording's first sample (s)

(ω, ω̇ and ḟ are zero in a static window: their terms need a moving recording.) Candidate
regressors are the monomials of these of degree 1 to 3, each on one output channel i:

    raw_i += c · x(w),  x a monomial (``term`` in the contract's grammar), c in channel units
    per unit of x.

Left out, because they are not new: the first-order model's own columns (1, f_j), powers
of abs(·) above one (abs(f)² = f²), and the catalogue's regressors on the channel they
act on (f_i² and abs(f_i) on channel i, f_j·f_k on any channel, temp and t on any
channel): a catalogue effect is tested first, by the catalogue. A monomial whose
signature on this pose set lies within the first-order model's span (relative leverage
< ``Thresholds.relative_leverage_min``: f_x³ on the six ±g poses is f_x) or coincides with a simpler
monomial's (|cos| > 1 − ``Thresholds.alias_tol`` after projecting out the first-order model: f_x·f_y²
on a pose set where every f_y ≠ 0 has f_x = 0) is not a candidate: the recording cannot
tell it from what is already there. ``LibraryTerm.aliases`` lists the dropped twins.

Columns are scaled to unit RMS over the windows for the fit (t³ reaches 1e8 s³) and the
coefficient is scaled back in ``to_parameters``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import combinations_with_replacement
from typing import Any

import numpy as np

from bench.diagnosis.effects.base import (
    AXES,
    Candidate,
    FloatArray,
    channel_column,
)
from bench.diagnosis.effects.sensor import REFERENCE_TEMP_C
from bench.diagnosis.evidence import G0_M_S2, StaticEvidence
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds

EFFECT = "discovered"
CHANNELS = ("ax", "ay", "az")


@dataclass(frozen=True)
class Base:
    """One base quantity: contract name, unit, the axis it belongs to (−1: none)."""

    name: str
    unit: str
    axis: int
    kind: str  # "f", "abs", "temp", "t"


class NamedTerm:
    """What every library term is named by: its term in the contract's grammar on one channel.

    A mixin of the term dataclasses (their fields ``term``, ``channel``, ``factors``)."""

    term: str
    channel: int
    factors: tuple[Base, ...]

    @property
    def degree(self) -> int:
        """Number of factors."""
        return len(self.factors)

    @property
    def label(self) -> str:
        """``term[channel]``."""
        return f"{self.term}[{CHANNELS[self.channel]}]"


@dataclass(frozen=True)
class LibraryTerm(NamedTerm):
    """A monomial on one channel.

    :param term: the contract's grammar, e.g. ``f_x^2*f_z``.
    :param channel: output channel 0, 1, 2.
    :param factors: the bases, with repetition, in canonical order.
    :param unit: unit of the monomial, e.g. ``g^2·°C``.
    :param values: (m,) the monomial per window (its own unit).
    :param scale: RMS of ``values`` (the column is values / scale).
    :param aliases: simpler-named twins dropped as indistinguishable on this pose set.
    """

    term: str
    channel: int
    factors: tuple[Base, ...]
    unit: str
    values: FloatArray
    scale: float
    aliases: tuple[str, ...] = field(default=())


def bases(ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> tuple[Base, ...]:
    """The base quantities this static recording offers (module docstring)."""
    out = [Base(f"f_{a}", "g", i, "f") for i, a in enumerate(AXES)]
    out += [Base(f"abs(f_{a})", "g", i, "abs") for i, a in enumerate(AXES)]
    if ev.has_temperature:
        assert ev.temp_c is not None
        if float(np.ptp(ev.temp_c)) >= th.min_temperature_span_c:
            out.append(Base("temp", "°C", -1, "temp"))
    out.append(Base("t", "s", -1, "t"))
    return tuple(out)


def quantity(b: Base, f_m_s2: FloatArray, temp_c: FloatArray | None, t_s: FloatArray | None) -> FloatArray:
    """Values of one base quantity in its own unit: f_i or abs(f_i) in g from the specific force
    (…, 3) (m/s²), temp − 25 °C from the temperature (°C), t (s) from the time; a term's
    monomial is the product of its factors' values, broadcast together."""
    if b.kind == "f":
        return f_m_s2[..., b.axis] / G0_M_S2
    if b.kind == "abs":
        return np.abs(f_m_s2[..., b.axis]) / G0_M_S2
    if b.kind == "temp":
        assert temp_c is not None
        return np.asarray(temp_c, dtype=float) - REFERENCE_TEMP_C
    assert t_s is not None
    return np.array(t_s, dtype=float, copy=True)


def base_values(ev: StaticEvidence, b: Base) -> FloatArray:
    """(m,) values of one base quantity per window (:func:`quantity` of the window means)."""
    return quantity(b, ev.f_m_s2, ev.temp_c, ev.mid_s)


def _power_string(items: list[tuple[str, int]], sep: str) -> str:
    return sep.join(n if k == 1 else f"{n}^{k}" for n, k in items)


def _grouped(factors: tuple[Base, ...], attr: str) -> list[tuple[str, int]]:
    out: list[tuple[str, int]] = []
    for b in factors:
        key = getattr(b, attr)
        if out and out[-1][0] == key:
            out[-1] = (key, out[-1][1] + 1)
        else:
            out.append((key, 1))
    return out


def term_name(factors: tuple[Base, ...]) -> str:
    """The contract grammar of a monomial: ``f_x^2*f_z``."""
    return _power_string(_grouped(factors, "name"), "*")


def term_unit(factors: tuple[Base, ...]) -> str:
    """Unit of a monomial: ``g^2·°C``."""
    return _power_string(_grouped(factors, "unit"), "·")


def in_catalogue(factors: tuple[Base, ...], channel: int) -> bool:
    """The catalogue's own regressors on ``channel`` (module docstring): temp, t, abs(f_i) on i, f_j·f_k."""
    kinds = [b.kind for b in factors]
    if len(factors) == 1:
        return kinds[0] in ("temp", "t") or (kinds[0] == "abs" and factors[0].axis == channel)
    if len(factors) == 2 and kinds == ["f", "f"]:
        a, b = factors
        return a.axis != b.axis or a.axis == channel
    return False


def admissible(factors: tuple[Base, ...]) -> bool:
    """Not the first-order model's own column, and no abs(·) of one axis twice (abs(f)² = f²)."""
    if len(factors) == 1 and factors[0].kind == "f":
        return False  # the first-order model's own column
    abs_axes = [b.axis for b in factors if b.kind == "abs"]
    return len(abs_axes) == len(set(abs_axes))


def library_terms(ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> tuple[list[LibraryTerm], int]:
    """The library's candidate terms on this recording, simplest first, and how many
    monomials were dropped as not determined by the pose set (module docstring)."""
    bs = bases(ev, th)
    vals = {b: base_values(ev, b) for b in bs}
    m = ev.m
    F = np.column_stack([np.ones(m), ev.f_m_s2 / G0_M_S2])
    Q, _ = np.linalg.qr(F)
    kept: list[list[tuple[LibraryTerm, FloatArray]]] = [[], [], []]
    aliases: dict[tuple[int, str], list[str]] = {}
    dropped = 0
    for degree in range(1, th.max_degree + 1):
        for combo in combinations_with_replacement(range(len(bs)), degree):
            factors = tuple(bs[k] for k in combo)
            if not admissible(factors):
                continue
            x = np.prod([vals[b] for b in factors], axis=0)
            nrm = float(np.linalg.norm(x))
            resid = x - Q @ (Q.T @ x)
            rn = float(np.linalg.norm(resid))
            name = term_name(factors)
            for ch in range(3):
                if in_catalogue(factors, ch):
                    continue
                if nrm == 0 or rn < th.relative_leverage_min * nrm:
                    dropped += 1
                    continue
                u = resid / rn
                twin = next((t for t, v in kept[ch] if abs(float(u @ v)) > 1.0 - th.alias_tol), None)
                if twin is not None:
                    aliases.setdefault((ch, twin.term), []).append(name)
                    continue
                scale = float(np.sqrt(np.mean(x * x)))
                term = LibraryTerm(name, ch, factors, term_unit(factors), x, scale)
                kept[ch].append((term, u))
    out = []
    for ch in range(3):
        for t, _ in kept[ch]:
            al = tuple(aliases.get((ch, t.term), ()))
            out.append(LibraryTerm(t.term, t.channel, t.factors, t.unit, t.values, t.scale, al))
    return out, dropped


def candidate(t: LibraryTerm) -> Candidate:
    """The selection candidate of one library term: one column on its channel, coefficient
    ``coefficient`` in channel units per unit of the term."""
    col = t.values / t.scale

    def cols(e: StaticEvidence, K: FloatArray) -> FloatArray:
        return channel_column(e, t.channel, col)

    def params(theta: FloatArray, cov: FloatArray, K: FloatArray) -> tuple[dict[str, Any], dict[str, Any]]:
        return (
            {"coefficient": float(theta[0]) / t.scale},
            {"coefficient": float(np.sqrt(max(cov[0, 0], 0.0))) / t.scale},
        )

    return Candidate(f"{EFFECT}:{t.label}", t.label, (t.channel,), cols, (t.term,), params)


def physics(t: LibraryTerm) -> str:
    """One sentence of physics where the term has a known meaning, else a plain statement."""
    a = AXES[t.channel]
    kinds = sorted(b.kind for b in t.factors)
    f_axes = [b.axis for b in t.factors if b.kind == "f"]
    other = [AXES[k] for k in f_axes if k != t.channel]
    if t.term == f"f_{a}^3":
        return (
            f"third-order nonlinearity of the {a} channel: its output curves with the cube of its own input"
        )
    if t.term == f"f_{a}*abs(f_{a})":
        return (
            f"a second-order nonlinearity odd in the input: the {a} channel's scale factor grows with "
            f"|f_{a}| in both directions"
        )
    if kinds == ["f", "temp"]:
        if f_axes[0] == t.channel:
            return f"the {a} channel's scale factor follows the sensor temperature"
        return (
            f"the {a} axis's alignment towards {other[0]} follows temperature "
            "(the mount or the package flexes as it warms)"
        )
    if kinds == ["f", "t"]:
        if f_axes[0] == t.channel:
            return f"the {a} channel's scale factor drifts during the run (reference voltage, charging)"
        return f"the {a} axis's alignment towards {other[0]} drifts during the run (a mount creeping)"
    if kinds == ["f", "f"] and len(set(f_axes)) == 1 and other:
        return (
            f"the {a} channel responds to the square of the {other[0]} input "
            "(cross-axis nonlinearity, anisoelastic suspension)"
        )
    if kinds == ["abs"] and t.factors[0].axis != t.channel:
        return f"the {a} channel responds to the magnitude of the {AXES[t.factors[0].axis]} input"
    if kinds == ["temp", "temp"]:
        return f"the {a} channel's bias follows temperature nonlinearly"
    if kinds in (["t", "t"], ["t", "t", "t"]):
        return f"the {a} channel's bias drifts along a curve (a warm-up levelling off), not a line"
    return f"a term proportional to {t.term} on {CHANNELS[t.channel]} that the model lacks"
