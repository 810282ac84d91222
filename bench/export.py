"""The fitted model in forms other tools load: imucal's calibration JSON, a Kalibr-style IMU
YAML, a C header and a plain JSON for firmware.

Every export carries the correction of the first-order model raw = b + K·f (``calbench
calibrate --json``): f = M·(raw − b) with M = K⁻¹, f the specific force in m/s², raw in the
channel unit. Pure: a :class:`bench.fitted_model.FittedModel` in, text out.

* ``imucal``: imucal's ``FerrarisCalibrationInfo`` JSON (format 2.0.0). imucal applies
  acc = R_a⁻¹·K_a⁻¹·(raw − b_a), so K = K_a·R_a with K_a = diag(|K_i|) (the norm of each row
  of K) and R_a the rows of K divided by their norms. No gyroscope was calibrated: its terms
  are the identity (K_g = R_g = I, K_ga = 0, b_g = 0) and the comment says so.
* ``kalibr``: the ``imu0`` block of a Kalibr IMU YAML (``rostopic``, ``update_rate``,
  ``accelerometer_noise_density`` in m/s²/√Hz, ``accelerometer_random_walk`` in m/s³/√Hz,
  gyroscope noise ``0`` as not measured) and the correction under ``calbench_correction``;
* ``c-header``: ``static const double`` arrays and an inline correction function (C99);
* ``json``: ``{"format": "calbench-correction/1", "bias", "correction_matrix", ...}``.
"""

from __future__ import annotations

import json
import math
import re
from typing import Any

import numpy as np

from bench.fitted_model import FittedModel

FORMATS = ("imucal", "kalibr", "c-header", "json")
"""Export formats, by name."""
MEDIA_TYPES = {"imucal": "application/json", "kalibr": "application/yaml", "c-header": "text/x-c",
               "json": "application/json"}  # fmt: skip
SUFFIX = {"imucal": ".imucal.json", "kalibr": ".kalibr.yaml", "c-header": ".h", "json": ".correction.json"}


def _model(fit: FittedModel) -> tuple[np.ndarray, np.ndarray, str]:
    b = np.asarray(fit.bias, dtype=float)
    K = np.asarray(fit.K, dtype=float)
    if b.shape != (3,) or K.shape != (3, 3) or not (np.all(np.isfinite(b)) and np.all(np.isfinite(K))):
        raise ValueError(f"bias must be 3 and scale_matrix 3x3 finite numbers, got {b.shape} and {K.shape}")
    if abs(np.linalg.det(K)) < 1e-12 * np.linalg.norm(K) ** 3:
        raise ValueError(f"scale_matrix is singular: {K.tolist()}")
    return b, K, fit.channel_unit


def correction(fit: FittedModel) -> tuple[np.ndarray, np.ndarray]:
    """(b (3,), M = K⁻¹ (3, 3)): f = M·(raw − b) in m/s².

    :raises ValueError: a non-finite or singular model.
    """
    b, K, _ = _model(fit)
    return b, np.linalg.inv(K)


def _serial(fit: FittedModel) -> str:
    return fit.unit_serial or "unknown"


def to_json(fit: FittedModel, source: str = "") -> str:
    """The plain correction JSON (``calbench-correction/1``)."""
    b, M = correction(fit)
    return json.dumps(
        {
            "format": "calbench-correction/1",
            "unit_serial": _serial(fit),
            "source": source,
            "channel_unit": fit.channel_unit,
            "equation": "f_m_s2 = correction_matrix @ (raw - bias)",
            "bias": b.tolist(),
            "correction_matrix": M.tolist(),
            "scale_matrix": np.asarray(fit.K, float).tolist(),
        },
        indent=2,
    )


def to_imucal(fit: FittedModel, source: str = "") -> str:
    """imucal's ``FerrarisCalibrationInfo`` JSON (accelerometer; gyroscope terms identity)."""
    b, K, unit = _model(fit)
    norms = np.linalg.norm(K, axis=1)
    doc = {
        "acc_unit": "m/s^2",
        "gyr_unit": "deg/s",
        "from_acc_unit": unit or "a.u.",
        "from_gyr_unit": "deg/s",
        "comment": f"calbench calibration of unit {_serial(fit)} {source}".strip()
        + ": accelerometer only; the gyroscope terms are the identity (no gyroscope was calibrated)",
        "K_a": np.diag(norms).tolist(),
        "R_a": (K / norms[:, None]).tolist(),
        "b_a": b.tolist(),
        "K_g": np.eye(3).tolist(),
        "R_g": np.eye(3).tolist(),
        "K_ga": np.zeros((3, 3)).tolist(),
        "b_g": [0.0, 0.0, 0.0],
        "cal_type": "Ferraris",
        "_format_version": "2.0.0",
    }
    return json.dumps(doc, indent=4)


def _yaml_list(values: Any) -> str:
    return "[" + ", ".join(repr(float(v)) for v in values) + "]"


def to_kalibr(
    fit: FittedModel,
    *,
    sample_rate_hz: float,
    noise_density_m_s2_sqrt_hz: float,
    random_walk_m_s3_sqrt_hz: float,
    rostopic: str = "/imu0",
    source: str = "",
) -> str:
    """A Kalibr-style ``imu0`` YAML: noise parameters in Kalibr's units and the correction.

    :param noise_density_m_s2_sqrt_hz: white-noise density (continuous time), m/s²/√Hz.
    :param random_walk_m_s3_sqrt_hz: bias random walk, m/s³/√Hz.
    :raises ValueError: a non-finite or negative noise value, a non-positive rate.
    """
    for name, v in (("noise density", noise_density_m_s2_sqrt_hz), ("random walk", random_walk_m_s3_sqrt_hz)):
        if not (math.isfinite(v) and v >= 0):
            raise ValueError(f"kalibr export: accelerometer {name} must be a finite number >= 0, got {v!r}")
    if not (math.isfinite(sample_rate_hz) and sample_rate_hz > 0):
        raise ValueError(f"kalibr export: sample rate must be > 0 Hz, got {sample_rate_hz!r}")
    b, M = correction(fit)
    unit = fit.channel_unit
    rows = "\n".join(f"      - {_yaml_list(r)}" for r in M)
    return (
        f"# calbench calibration of unit {_serial(fit)} {source}\n".replace(" \n", "\n")
        + "# Kalibr IMU layout; the gyroscope was not calibrated (its noise values are 0: not measured)\n"
        "imu0:\n"
        f"  rostopic: {rostopic}\n"
        f"  update_rate: {float(sample_rate_hz)!r}\n"
        f"  accelerometer_noise_density: {float(noise_density_m_s2_sqrt_hz)!r}  # [ m / s^2 / sqrt(Hz) ]\n"
        f"  accelerometer_random_walk: {float(random_walk_m_s3_sqrt_hz)!r}  # [ m / s^3 / sqrt(Hz) ]\n"
        "  gyroscope_noise_density: 0.0\n"
        "  gyroscope_random_walk: 0.0\n"
        "  time_offset: 0.0\n"
        "  T_i_b:\n"
        "    - [1.0, 0.0, 0.0, 0.0]\n    - [0.0, 1.0, 0.0, 0.0]\n"
        "    - [0.0, 0.0, 1.0, 0.0]\n    - [0.0, 0.0, 0.0, 1.0]\n"
        "  calbench_correction:  # f [m/s^2] = correction_matrix @ (raw - bias)\n"
        f"    channel_unit: {json.dumps(unit)}\n"
        f"    bias: {_yaml_list(b)}\n"
        f"    correction_matrix:\n{rows}\n"
    )


def _c_name(serial: str) -> str:
    return re.sub(r"[^A-Za-z0-9]", "_", serial).upper()


def to_c_header(fit: FittedModel, source: str = "") -> str:
    """A C99 header: the bias, the correction matrix and ``calbench_correct(raw, f_m_s2)``."""
    b, M = correction(fit)
    serial = _serial(fit)
    guard = f"CALBENCH_CAL_{_c_name(serial)}_H"

    def num(v: float) -> str:
        return f"{float(v):.17g}"

    rows = ",\n    ".join("{" + ", ".join(num(v) for v in r) + "}" for r in M)
    unit = fit.channel_unit.replace("*/", "")
    comment = f"calbench calibration of unit {serial} {source}".strip().replace("*/", "")
    return f"""/* {comment}
 * f [m/s^2] = CALBENCH_CORRECTION * (raw - CALBENCH_BIAS), raw in {unit} */
#ifndef {guard}
#define {guard}

static const double CALBENCH_BIAS[3] = {{{", ".join(num(v) for v in b)}}};
static const double CALBENCH_CORRECTION[3][3] = {{
    {rows}
}};

static inline void calbench_correct(const double raw[3], double f_m_s2[3])
{{
    int i, j;
    for (i = 0; i < 3; ++i) {{
        f_m_s2[i] = 0.0;
        for (j = 0; j < 3; ++j) f_m_s2[i] += CALBENCH_CORRECTION[i][j] * (raw[j] - CALBENCH_BIAS[j]);
    }}
}}

#endif /* {guard} */
"""
