"""Effects concealed in simulated static-12 recordings (truth model: drivers/sim/physics.py).

Sizes are multiples of the detection limits measured with this recording (typical ADXL-like
triad, 30 s windows at 100 Hz; docs/diagnose.md): the finding must name the effect and
recover the injected value within 3 of its own sigmas. Clean recordings: at most 2 % may
report anything.
"""

from __future__ import annotations

from concurrent.futures import ProcessPoolExecutor
from typing import Any

import numpy as np
import pytest

from bench.diagnose_recording import diagnose_recording
from tests.bench.diagnosis_sim import static_recording

# effect, parameters at 10x the detection limit, parameter checked, index
CASES: list[tuple[str, dict[str, Any], str, tuple[int, ...]]] = [
    ("nonlinearity_quadratic", {"k2_per_g": [0.0, 0.0, 1.3e-3]}, "k2_per_g", (2,)),
    ("scale_asymmetry", {"delta": [2.6e-3, 0.0, 0.0]}, "delta", (0,)),
    ("table_tilt", {"tilt_rad": [7e-4, 0.0]}, "tilt_rad", (0,)),
    ("encoder_offset", {"offset_deg": [0.0, 0.05, 0.0]}, "offset_deg", (1,)),
]


@pytest.mark.slow
@pytest.mark.parametrize(("effect", "params", "name", "index"), CASES, ids=[c[0] for c in CASES])
def test_effect_at_ten_times_its_limit_is_found_and_measured(effect, params, name, index) -> None:
    d = diagnose_recording(static_recording({effect: params}, seed=11))
    found = {f.effect: f for f in d.findings}
    assert effect in found, f"{effect} not found; findings {list(found)}"
    f = found[effect]
    est = np.asarray(f.parameters[name])[index]
    sig = np.asarray(f.sigma[name])[index]
    truth = np.asarray(params[name])[index]
    assert abs(est - truth) < 3 * sig, f"{effect}: {est} vs {truth} ± {sig}"
    assert f.delta_bic < 0 and d.final.chi2_dof < d.baseline.chi2_dof


def _clean(seed: int) -> list[str]:
    return [f.effect for f in diagnose_recording(static_recording({}, seed=seed)).findings]


@pytest.mark.slow
@pytest.mark.xfail(
    strict=True, reason="known: more than 1 of these 50 clean recordings report a finding (docs/diagnose.md)"
)
def test_false_finding_rate_on_fifty_clean_recordings() -> None:
    with ProcessPoolExecutor(2) as ex:
        results = list(ex.map(_clean, range(1000, 1050)))
    false = [r for r in results if r]
    assert len(false) <= 1, false  # 1/50 = 2 %
