"""A plan's evaluation as JSON-ready values (µg, ppm, µrad), for the CLI and the REST route."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np
import numpy.typing as npt

from bench.planning.evaluation import Evaluation
from bench.planning.noise import G0_M_S2
from bench.planning.search import Plan
from bench.planning.trajectory import NUISANCE_NAMES


def evaluation_dict(e: Evaluation) -> dict[str, Any]:
    """Procedure, parameters, table time, predicted U (k = 2) per group and the bound."""
    u = e.predicted
    ug = 1e6 / G0_M_S2
    return {
        "procedure": e.procedure.name,
        "fit": e.fit,
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
        "nuisance_sigma": dict(zip(NUISANCE_NAMES, u.nuisance.tolist(), strict=False)),
        "notes": list(e.notes),
    }


def plan_dict(p: Plan, noise_text: str) -> dict[str, Any]:
    """The whole plan: noise, the chosen design (or ``None``), the body of ``POST /api/runs`` that
    starts it (``start``: procedure, dwell_s, parameters with the predicted U), the closest design
    when none meets the targets, problems."""
    return {
        "noise": noise_text,
        "plan": None if p.best is None else evaluation_dict(p.best),
        "start": None
        if p.best is None
        else {
            "procedure": p.best.procedure.name,
            "dwell_s": p.best.procedure.parameters["dwell_s"],
            "parameters": plan_parameters(p.best),
        },
        "closest": None if p.closest is None else evaluation_dict(p.closest),
        "problems": list(p.problems),
    }


PREDICTED_KEYS = {
    "bias_ug": "predicted_bias_u_ug",
    "scale_ppm": "predicted_scale_u_ppm",
    "misalignment_urad": "predicted_misalignment_u_urad",
}
"""Group -> the planned procedure's parameter holding the planner's predicted U (k = 2)."""


def plan_parameters(e: Evaluation) -> dict[str, float]:
    """The planned procedure's parameters for a start request: the design and its predicted U."""
    out = {k: float(v) for k, v in e.procedure.parameters.items() if isinstance(v, int | float)}
    u = evaluation_dict(e)["predicted_U_k2"]
    out.update({PREDICTED_KEYS[k]: float(v) for k, v in u.items()})
    out.pop("dwell_s", None)
    return out


def predicted_and_achieved(
    parameters: Mapping[str, object], K: npt.ArrayLike, K_sigma: npt.ArrayLike, bias_sigma: npt.ArrayLike
) -> dict[str, dict[str, float | None]]:
    """Per group, the planner's predicted U (k = 2) stored with the run and the U the fit achieved
    (2 × its largest standard uncertainty of the group, relative to the fitted scale: bias in µg,
    scale in ppm, misalignment in µrad).

    :param K: (3, 3) fitted scale matrix (channel unit per m/s²); ``K_sigma`` (3, 3) and
        ``bias_sigma`` (3,) its one-sigma uncertainties (channel units).
    """
    Km = np.asarray(K, dtype=float)
    d = np.abs(np.diag(Km))
    rel = np.asarray(K_sigma, dtype=float) / d[:, None]
    b = np.asarray(bias_sigma, dtype=float) / d / G0_M_S2
    achieved = {
        "bias_ug": 2e6 * float(np.max(b)),
        "scale_ppm": 2e6 * float(np.max(np.diag(rel))),
        "misalignment_urad": 2e6 * float(np.max(rel[~np.eye(3, dtype=bool)])),
    }
    out: dict[str, dict[str, float | None]] = {}
    for group, key in PREDICTED_KEYS.items():
        v = parameters.get(key)
        out[group] = {
            "predicted": float(v) if isinstance(v, int | float) else None,
            "achieved": achieved[group],
        }
    return out
