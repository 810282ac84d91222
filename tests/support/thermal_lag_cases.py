"""A temperature effect through a thermal lag, concealed in a static-12 recording, and the scoring
of a diagnosis against it (``benchmarks/study_thermal_lag.py``,
``tests/bench/diagnosis/test_thermal_lag_recordings.py``; docs/diagnose.md, "Bench physics
beyond the catalogue").

The recording is ``diagnose_cases.static_recording`` on the cycling temperature of the
catalogue's temperature case (±1.5 °C, 150 s, no warm-up), a ``temperature_bias`` of ``tc`` on
ay seen through the simulator's ``thermal_lag`` of ``tau_s`` (0: no lag, a plain
``temperature_bias``; tc = 0: clean). Scores:

- ``named``: a ``thermal_lag`` finding on ay with the coefficient within 3 sigma of the truth
  (and nothing on ax, az), or ``unexplained`` naming ay with no catalogue finding;
- ``plain_named``: a ``temperature_bias`` finding on ay within 3 sigma and no ``thermal_lag``;
- ``lag_claimed``: any ``thermal_lag`` finding;
- ``other``: catalogue findings or discovered terms other than the truth's own
  (``temperature_bias`` beside a lag counts: it is a partial mimic of it).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.diagnosis import Diagnosis
from bench.recording import Recording
from tests.support.diagnose_cases import CYCLING_TEMPERATURE, static_recording

CHANNEL = 1
"""The channel the concealed coefficient acts on (ay)."""


def lag_effects(tc: float, tau_s: float) -> dict[str, dict[str, Any]]:
    """The truth model's effects: ``temperature_bias`` tc on ay, through a lag ``tau_s`` (> 0)."""
    out: dict[str, dict[str, Any]] = {}
    if tc:
        out["temperature_bias"] = {"tc_m_s2_per_c": [0.0, tc, 0.0]}
    if tc and tau_s > 0:
        out["thermal_lag"] = {"tau_s": tau_s}
    return out


def lag_recording(tc: float, tau_s: float, seed: int) -> Recording:
    """The simulated recording (module docstring)."""
    return static_recording(lag_effects(tc, tau_s), seed, temperature=CYCLING_TEMPERATURE)


def lag_finding(d: Diagnosis) -> tuple[float, float, float, float] | None:
    """(tc, sigma, τ, sigma) of the ``thermal_lag`` finding on ay, or ``None``."""
    for f in d.findings:
        if f.effect == "thermal_lag":
            p, s = f.parameters, f.sigma
            return (
                float(p["tc_m_s2_per_c"][CHANNEL]),
                float(s["tc_m_s2_per_c"][CHANNEL]),
                float(p["tau_s"][CHANNEL]),
                float(s["tau_s"][CHANNEL]),
            )
    return None


def named(d: Diagnosis, tc: float) -> bool:
    """The lag named on ay within 3 sigma (nothing on the other channels), or ``unexplained`` on
    ay with no catalogue finding."""
    got = lag_finding(d)
    if got is not None:
        f = next(f for f in d.findings if f.effect == "thermal_lag")
        others = [i for i in (0, 2) if f.parameters["tc_m_s2_per_c"][i] != 0.0]
        return not others and got[1] > 0 and abs(got[0] - tc) < 3.0 * got[1]
    u = d.unexplained
    return u is not None and u.where.startswith("ay") and not d.findings and not d.discovered


def plain_named(d: Diagnosis, tc: float) -> bool:
    """A ``temperature_bias`` on ay within 3 sigma, and no ``thermal_lag``."""
    for f in d.findings:
        if f.effect == "temperature_bias" and lag_finding(d) is None:
            v, s = f.parameters["tc_m_s2_per_c"][CHANNEL], f.sigma["tc_m_s2_per_c"][CHANNEL]
            return bool(s > 0 and abs(v - tc) < 3.0 * s)
    return False


def other_claims(d: Diagnosis, truth: str) -> list[str]:
    """Findings and discovered terms beyond the truth's own effect ``truth`` (module docstring)."""
    return [f.effect for f in d.findings if f.effect != truth] + [
        f"{x.term}[{x.channel}]" for x in d.discovered
    ]


def z_scores(d: Diagnosis, tc: float, tau_s: float) -> tuple[float, float]:
    """(z of tc, z of τ) of the lag finding, NaN without one."""
    got = lag_finding(d)
    if got is None:
        return float("nan"), float("nan")
    return (got[0] - tc) / got[1], (got[2] - tau_s) / got[3] if got[3] > 0 else float(np.inf)
