"""The drift test's reference uncertainty on the same bench leaves out a moving certificate's
bias-wander line (the run-to-run repeatability u_rep already counts both runs' wander) as it
leaves out the bench-common lines; on another bench U/k stands."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from bench.estimation.static_design import PARAMETER_NAMES
from bench.uncertainty.budget import WANDER_GROUP
from bench.uncertainty.drift import reference_uncertainty


def _certificate() -> dict[str, Any]:
    """b_* lines: Type A 3, temperature 4, DAQ gain 5 (bench-common), wander 12 (u_c 14)."""
    lines = [
        {"group": "Type A", "contribution": 3.0},
        {"group": "temperature: bias", "contribution": 4.0},
        {"group": "DAQ gain", "contribution": 5.0},
        {"group": WANDER_GROUP, "contribution": 12.0},
    ]
    quantities = {p: {"contributions": lines} for p in PARAMETER_NAMES}
    u_c = math.sqrt(9 + 16 + 25 + 144)
    return {
        "results": {
            "bias": {"expanded_uncertainty": [2 * u_c] * 3, "k": 2.0},
            "uncertainty_budget": {"quantities": quantities},
        }
    }


def test_same_bench_leaves_out_the_wander_line_and_the_bench_common_ones() -> None:
    u, _ = reference_uncertainty(_certificate(), "bias", same_bench=True)
    np.testing.assert_allclose(u, [5.0, 5.0, 5.0])  # sqrt(3² + 4²)


def test_another_bench_keeps_the_full_u() -> None:
    u, _ = reference_uncertainty(_certificate(), "bias", same_bench=False)
    assert u == pytest.approx([math.sqrt(194.0)] * 3)
