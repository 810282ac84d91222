"""The fitted model in the units of a data sheet, beside the raw SI form.

* sensitivity S_i = K_ii · g_n (g_n = 9.80665 m/s², standard gravity, ISO 80000-3), in mV/g
  for a volt output (counts/g for a digital one), U(S_i) = U(K_ii) · g_n;
* cross-axis sensitivity (misalignment) r_ij = K_ij / K_ii, the response of channel i to an
  acceleration along j relative to its own, in mrad (≈ the angle between the sensitive axis
  and the ideal one for |r| ≪ 1), U by first-order propagation (``conformity.check_uncertainties``);
* zero-g output b_i in mV for a volt output.

Each value is rounded to the decimal place of its U's second significant digit (GUM 7.2.6,
:func:`station.certificates.rounding.round_expanded`), so value and U have matching digits.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from bench.fitted_model import FittedModel
from bench.limits import AXES
from station.certificates.budget import CertificateBudget
from station.certificates.conformity import check_uncertainties
from station.certificates.rounding import round_expanded

G_N_M_S2 = 9.80665
"""Standard acceleration of gravity (m/s²), the g of a data sheet's mV/g."""
_SCALE = {"V": (1000.0, "mV"), "mV": (1.0, "mV")}


def _pair(value: float, u: float) -> tuple[float, float]:
    return round_expanded(value, u, 1.0)


def datasheet_results(fit: FittedModel, budget: CertificateBudget | None) -> dict[str, Any]:
    """Sensitivity, zero-g output and cross-axis sensitivity of a fit with the certificate's U
    (``budget`` as in the results table; ``None``: Type A, k = 2).

    :raises ValueError: a value or its U cannot be rounded (not finite).
    """
    unit = fit.channel_unit
    factor, out_unit = _SCALE.get(unit, (1.0, unit))
    us = check_uncertainties(fit, budget)
    K = np.asarray(fit.K, float)
    b = np.asarray(fit.bias, float)
    sens = [
        _pair(K[i, i] * G_N_M_S2 * factor, us[f"scale_{a}"] * G_N_M_S2 * factor) for i, a in enumerate(AXES)
    ]
    zero = [_pair(b[i] * factor, us[f"bias_{a}"] * factor) for i, a in enumerate(AXES)]
    cross: list[list[tuple[float, float] | None]] = [
        [
            None if i == j else _pair(1e3 * K[i, j] / K[i, i], 1e3 * us[f"cross_axis_{a}{AXES[j]}"])
            for j in range(3)
        ]
        for i, a in enumerate(AXES)
    ]
    return {
        "sensitivity": {
            "value": [p[0] for p in sens],
            "expanded_uncertainty": [p[1] for p in sens],
            "unit": f"{out_unit}/g",
            "basis": "S_i = K_ii · g_n, g_n = 9.80665 m/s² (standard gravity)",
        },
        "zero_g_output": {
            "value": [p[0] for p in zero],
            "expanded_uncertainty": [p[1] for p in zero],
            "unit": out_unit,
            "basis": "b_i",
        },
        "cross_axis": {
            "value": [[None if p is None else p[0] for p in row] for row in cross],
            "expanded_uncertainty": [[None if p is None else p[1] for p in row] for row in cross],
            "unit": "mrad",
            "basis": "r_ij = K_ij / K_ii: the output of channel i per unit acceleration along axis j "
            "relative to its own sensitivity (row i, column j), ≈ the misalignment angle for |r| ≪ 1",
        },
    }
