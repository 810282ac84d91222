"""Effects inside the sensor: terms added to channel i, scaled by its own sensitivity K_ii.

Catalogue (``docs/cli-contract.md``; g0 = 9.80665 m/s²), each column evaluated per window w:

    nonlinearity_quadratic   raw_i += K_ii · k2_i · f_i² / g0
    scale_asymmetry          raw_i += K_ii · (δ_i / 2) · |f_i|
    cross_coupling           raw_i += K_ii · Σ_{j<k} c_ijk f_j f_k / g0     (xy, xz, yz)
    temperature_bias         raw_i += K_ii · tc_i · (T − 25 °C)
    bias_drift               raw_i += K_ii · d_i · t

Each is linear in its parameters once K_ii is known (it is, from the first-order fit, to a
relative 1e-4), so every channel is a separate candidate with the contract's parameter as
its coefficient.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.diagnosis.effects.base import AXES, Candidate, EffectKind, FloatArray, ParamSpec, channel_column
from bench.diagnosis.evidence import G0_M_S2, StaticEvidence
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds

REFERENCE_TEMP_C = 25.0

_PAIRS = ((0, 1), (0, 2), (1, 2))


def _vector_params(name: str, i: int, q: int = 1) -> Callable[..., tuple[dict[str, Any], dict[str, Any]]]:
    def convert(theta: FloatArray, cov: FloatArray, K: FloatArray) -> tuple[dict[str, Any], dict[str, Any]]:
        sig = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        if q == 1:
            v, s = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
            v[i], s[i] = float(theta[0]), float(sig[0])
            return {name: v}, {name: s}
        vm = [[0.0] * q for _ in range(3)]
        sm = [[0.0] * q for _ in range(3)]
        vm[i] = [float(x) for x in theta]
        sm[i] = [float(x) for x in sig]
        return {name: vm}, {name: sm}

    return convert


@dataclass(frozen=True)
class ChannelEffect:
    """A sensor effect with one regressor (or ``q``) per channel (see the module docstring)."""

    id: str
    parameters: tuple[ParamSpec, ...]
    explanation: str
    regressor: Callable[[StaticEvidence, int], FloatArray]
    regressor_names: tuple[str, ...] = ("",)
    kind: EffectKind = "columns"
    needs_table: bool = False

    def observable(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> tuple[bool, str]:
        if self.id == "temperature_bias":
            if not ev.has_temperature:
                return False, "the recording has no temperature channel"
            assert ev.temp_c is not None
            span = float(np.ptp(ev.temp_c))
            if span < th.min_temperature_span_c:
                return False, f"temperature varied by only {span:.3g} °C over the windows"
            return True, f"temperature spans {span:.2g} °C over the windows"
        if self.id == "bias_drift":
            return True, f"windows span {np.ptp(ev.mid_s):.0f} s"
        return True, "needs several input levels per axis; checked against the pose set below"

    def candidates(self, ev: StaticEvidence, th: Thresholds = THRESHOLDS) -> list[Candidate]:
        out = []
        name = self.parameters[0].name
        q = len(self.regressor_names)
        for i in range(3):

            def cols(e: StaticEvidence, K: FloatArray, i: int = i) -> FloatArray:
                return channel_column(e, i, K[i, i] * self.regressor(e, i))

            names = tuple(f"{name}[{AXES[i]}]{r}" for r in self.regressor_names)
            out.append(
                Candidate(self.id, f"{self.id}[{AXES[i]}]", (i,), cols, names, _vector_params(name, i, q))
            )
        return out


def _quadratic(ev: StaticEvidence, i: int) -> FloatArray:
    return ev.f_m_s2[:, i] ** 2 / G0_M_S2


def _abs(ev: StaticEvidence, i: int) -> FloatArray:
    return 0.5 * np.abs(ev.f_m_s2[:, i])


def _products(ev: StaticEvidence, i: int) -> FloatArray:
    f = ev.f_m_s2
    return np.stack([f[:, j] * f[:, k] for j, k in _PAIRS], axis=1) / G0_M_S2


def _temperature(ev: StaticEvidence, i: int) -> FloatArray:
    assert ev.temp_c is not None
    return ev.temp_c - REFERENCE_TEMP_C


def _time(ev: StaticEvidence, i: int) -> FloatArray:
    return ev.mid_s


NONLINEARITY = ChannelEffect(
    "nonlinearity_quadratic",
    (ParamSpec("k2_per_g", "1/g", (3,)),),
    "the sensing element's output is not exactly proportional to its input: a second-order "
    "term makes the reading at +1 g and −1 g differ from ±K·g by the same amount",
    _quadratic,
)
ASYMMETRY = ChannelEffect(
    "scale_asymmetry",
    (ParamSpec("delta", "1", (3,)),),
    "the scale factor differs for positive and negative input (asymmetric suspension or "
    "readout), so the reading moves with |f_i|",
    _abs,
)
CROSS_COUPLING = ChannelEffect(
    "cross_coupling",
    (ParamSpec("c_per_g", "1/g", (3, 3)),),
    "an axis responds to the product of the inputs across it (proof-mass pendulosity, "
    "anisoelastic suspension), visible at the diagonal orientations",
    _products,
    ("xy", "xz", "yz"),
)
TEMPERATURE = ChannelEffect(
    "temperature_bias",
    (ParamSpec("tc_m_s2_per_c", "m/s²/°C", (3,)),),
    "the zero-g output follows the sensor's temperature (thermal stress in the die and package)",
    _temperature,
)
DRIFT = ChannelEffect(
    "bias_drift",
    (ParamSpec("drift_m_s2_per_s", "m/s²/s", (3,)),),
    "the zero-g output moves steadily with time during the run (warm-up, charging, ageing)",
    _time,
)
