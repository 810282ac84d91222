"""A plan's evaluation as JSON-ready values (µg, ppm, µrad), for the CLI and the REST route."""

from __future__ import annotations

from typing import Any

from bench.planning.noise import G0_M_S2
from bench.planning.search import Evaluation, Plan


def evaluation_dict(e: Evaluation) -> dict[str, Any]:
    """Procedure, parameters, table time, predicted U (k = 2) per group and the bound."""
    u = e.predicted
    ug = 1e6 / G0_M_S2
    return {
        "procedure": e.procedure.name,
        "parameters": e.procedure.parameters,
        "duration_s": e.duration_s,
        "predicted_U_k2": {
            "bias_ug": 2 * u.bias * ug,
            "scale_ppm": 2e6 * u.scale,
            "misalignment_urad": 2e6 * u.misalignment,
        },
        "k_rms_sigma_ppm": 1e6 * u.k_rms,
        "bound_k_sigma_ppm": 1e6 * e.bound_k,
        "bound_bias_sigma_ug": e.bound_bias_m_s2 * ug,
        "k_fraction_of_bound": e.k_fraction_of_bound,
    }


def plan_dict(p: Plan, noise_text: str) -> dict[str, Any]:
    """The whole plan: noise, the chosen design (or ``None``), the closest one, problems."""
    return {
        "noise": noise_text,
        "plan": None if p.best is None else evaluation_dict(p.best),
        "closest": None if p.closest is None else evaluation_dict(p.closest),
        "problems": list(p.problems),
    }
