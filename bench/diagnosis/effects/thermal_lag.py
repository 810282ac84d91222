"""``thermal_lag``: the bias follows the temperature of the sensing element, which lags the
thermometer through a first-order lag of time constant τ (a profiled parameter).

The element's temperature T_e obeys τ·Ṫ_e = T − T_e with T_e(0) = T(0), over the recording's
whole temperature column (every sample, between the windows too), each sample's T held over the
interval before it (the simulator's ``thermal_lag``, docs/physics-model.md). Exactly, for
sample k after sample k − 1 (Δ_k = t_k − t_{k−1}, a_k = exp(−Δ_k/τ)):

    T_e[k] = a_k·T_e[k−1] + (1 − a_k)·T[k]

Column for channel i (window w): K_ii·(mean over window w of T_e − 25 °C), coefficient tc_i in
m/s²/°C, the contract's ``temperature_bias`` seen through the lag; τ → 0 gives T_e = T and so
``temperature_bias``'s column exactly. τ is not linear in the model: the candidate is a
one-parameter family (``base.Family``) whose τ the selection profiles on a grid
(``profiled.resolve``: the gate sized for the search by Davies' bound, and the lag must beat
τ = 0, a plain ``temperature_bias``, before it is claimed).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.diagnosis.effects.base import (
    AXES,
    Candidate,
    EffectKind,
    Family,
    FloatArray,
    ParamSpec,
    channel_column,
)
from bench.diagnosis.effects.sensor import REFERENCE_TEMP_C
from bench.diagnosis.evidence import StaticEvidence
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds


def lagged_c(t_s: FloatArray, temp_c: FloatArray, tau_s: float, block_decay: float = 50.0) -> FloatArray:
    """(n,) the first-order lag T_e of ``temp_c`` (n,) (°C) on the clock ``t_s`` (n,) (s), time
    constant ``tau_s`` (s), T_e(0) = T(0), exact for T held over the interval before each sample
    (module docstring). ``tau_s`` ≤ 0 returns T itself.

    Vectorised by blocks: with c_k = Σ_{j≤k} Δ_j/τ, inside a block that starts at sample s,
    T_e[k] = e^{−(c_k − c_s)}·(T_e[s] + Σ_{s<j≤k} (1 − a_j)·T[j]·e^{c_j − c_s}).
    A block holds at most ``block_decay`` e-foldings, so its weights stay below e^50, far inside
    float64's range, and no sum cancels (all weights > 0); the result does not depend on it.
    """
    t = np.asarray(t_s, dtype=float)
    temp = np.asarray(temp_c, dtype=float)
    if tau_s <= 0 or t.size < 2:
        return temp.copy()
    d = np.diff(t) / tau_s
    if float(np.min(d)) > block_decay:  # every step forgets all but e^-block_decay: T_e = T
        return temp.copy()
    c = np.concatenate([[0.0], np.cumsum(d)])
    gain = np.concatenate([[0.0], -np.expm1(-d)])  # 1 − a_k
    out = np.empty_like(temp)
    out[0] = temp[0]
    s = 0
    while s < t.size - 1:
        e = int(np.searchsorted(c, c[s] + block_decay, side="right"))
        if e <= s + 1:  # one step alone decays by more than e^block_decay
            out[s + 1] = out[s] + gain[s + 1] * (temp[s + 1] - out[s])
            s += 1
            continue
        rel = c[s + 1 : e] - c[s]
        acc = np.cumsum(gain[s + 1 : e] * temp[s + 1 : e] * np.exp(rel))
        out[s + 1 : e] = np.exp(-rel) * (out[s] + acc)
        s = e - 1
    return out


_MEANS: dict[float, FloatArray] = {}
"""Window means of T_e already computed for the run in ``_OWNER``, by τ (the three channels'
candidates and every step of a selection ask for the same ones)."""
_OWNER: list[object] = []
"""The run's columns (t, T, window bounds) whose means ``_MEANS`` holds: one run at a time."""
_LOCK = threading.Lock()
"""Diagnoses may run in threads (the station's API): owner and means change together."""


def window_means_c(ev: StaticEvidence, tau_s: float) -> FloatArray:
    """(m,) mean of T_e (°C) over each window's samples, T_e over the run's whole column.
    Kept per τ for the last run asked (memory only: the columns' identity is checked, so a
    result is never read for another run, and one run's columns at most are held)."""
    assert ev.run_t_s is not None and ev.run_temp_c is not None and ev.window_bounds is not None
    owner = [ev.run_t_s, ev.run_temp_c, ev.window_bounds]
    with _LOCK:
        if len(_OWNER) == 3 and all(a is b for a, b in zip(_OWNER, owner, strict=True)):
            hit = _MEANS.get(float(tau_s))
            if hit is not None:
                return hit
    te = lagged_c(ev.run_t_s, ev.run_temp_c, tau_s)
    csum = np.concatenate([[0.0], np.cumsum(te)])
    a, b = ev.window_bounds[:, 0], ev.window_bounds[:, 1]
    out = np.asarray((csum[b] - csum[a]) / (b - a), dtype=float)
    out.flags.writeable = False
    with _LOCK:
        if len(_OWNER) != 3 or any(a is not b for a, b in zip(_OWNER, owner, strict=True)):
            _MEANS.clear()
            _OWNER[:] = owner
        _MEANS[float(tau_s)] = out
    return out


def tau_grid_s(ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> tuple[float, ...]:
    """The time constants (s) searched: from ``th.lag_tau_min_s`` to the run's span, in steps of
    ``th.lag_grid_ratio``."""
    assert ev.run_t_s is not None
    span = float(ev.run_t_s[-1] - ev.run_t_s[0])
    n = max(int(np.ceil(np.log(span / th.lag_tau_min_s) / np.log(th.lag_grid_ratio))), 1) + 1
    return tuple(float(x) for x in np.geomspace(th.lag_tau_min_s, max(span, th.lag_tau_min_s), n))


def _column(ev: StaticEvidence, K: FloatArray, i: int, tau_s: float) -> FloatArray:
    return channel_column(ev, i, K[i, i] * (window_means_c(ev, tau_s) - REFERENCE_TEMP_C))


@dataclass(frozen=True)
class ThermalLag:
    """``thermal_lag`` (module docstring): one family of candidates per channel."""

    id: str = "thermal_lag"
    kind: EffectKind = "columns"
    needs_table: bool = False
    parameters: tuple[ParamSpec, ...] = (
        ParamSpec("tc_m_s2_per_c", "m/s²/°C", (3,)),
        ParamSpec("tau_s", "s", (3,)),
    )
    explanation: str = (
        "the zero-g output follows the temperature of the sensing element, which lags the "
        "thermometer (a first-order lag through the package and the mount): the bias follows "
        "the temperature late and smoothed, not as the thermometer reads it"
    )

    def observable(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> tuple[bool, str]:
        if not ev.has_temperature:
            return False, "the recording has no temperature channel"
        if ev.run_temp_c is None or ev.run_t_s is None or ev.window_bounds is None:
            return False, "needs the run's whole temperature column, not only each window's mean"
        assert ev.temp_c is not None
        span = float(np.ptp(ev.temp_c))
        if span < th.min_temperature_span_c:
            return False, f"temperature varied by only {span:.3g} °C over the windows"
        return True, f"temperature spans {span:.2g} °C over the windows; τ searched on the run's column"

    def candidates(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> list[Candidate]:
        grid = tau_grid_s(ev, th)
        return [self._family(i, grid) for i in range(3)]

    def _family(self, i: int, grid: tuple[float, ...]) -> Candidate:
        label = f"{self.id}[{AXES[i]}]"
        name = f"tc_m_s2_per_c[{AXES[i]}]"

        def column(ev: StaticEvidence, K: FloatArray, tau_s: float) -> FloatArray:
            return _column(ev, K, i, tau_s)

        def at(tau_s: float, inflation: float, tau_per_coef: float) -> Candidate:
            def cols(ev: StaticEvidence, K: FloatArray) -> FloatArray:
                return _column(ev, K, i, tau_s)

            def params(
                theta: FloatArray, cov: FloatArray, K: FloatArray
            ) -> tuple[dict[str, Any], dict[str, Any]]:
                c = float(theta[0])
                s_cond = float(np.sqrt(max(cov[0, 0], 0.0)))
                tc, s_tc, tau, s_tau = [0.0] * 3, [0.0] * 3, [0.0] * 3, [0.0] * 3
                tc[i], s_tc[i] = c, s_cond * float(np.sqrt(inflation))
                tau[i] = tau_s
                s_tau[i] = s_cond * tau_per_coef / abs(c) if c != 0 else float("inf")
                return {"tc_m_s2_per_c": tc, "tau_s": tau}, {"tc_m_s2_per_c": s_tc, "tau_s": s_tau}

            return Candidate(self.id, label, (i,), cols, (name,), params, extra_params=1)

        def null(ev: StaticEvidence, K: FloatArray) -> FloatArray:
            return _column(ev, K, i, 0.0)

        def placeholder(ev: StaticEvidence, K: FloatArray) -> FloatArray:
            return _column(ev, K, i, grid[0])

        def unresolved(
            theta: FloatArray, cov: FloatArray, K: FloatArray
        ) -> tuple[dict[str, Any], dict[str, Any]]:
            raise ValueError(f"{label}: a family's τ must be profiled (profiled.resolve) before it is fitted")

        fam = Family(grid=grid, column=column, null_column=null, at=at, reduces_to="temperature_bias")
        return Candidate(self.id, label, (i,), placeholder, (name,), unresolved, extra_params=1, family=fam)


THERMAL_LAG = ThermalLag()
