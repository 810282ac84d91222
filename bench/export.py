"""The fitted model in forms other tools load: imucal's calibration JSON, a Kalibr-style IMU
YAML, a C header and a plain JSON for firmware.

Every export carries the correction of the first-order model raw = b + K·f (``calbench
calibrate --json``): f = M·(raw − b) with M = K⁻¹, f the specific force in m/s², raw in the
channel unit. Pure: a :class:`bench.fitted_model.FittedModel` in, text out.

* ``imucal``: imucal's ``FerrarisCalibrationInfo`` JSON (format 2.0.0). imucal applies
  acc = R_a⁻¹·K_a⁻¹·(raw − b_a), so K = K_a·R_a with K_a = diag(|K_i|) (the norm of each row
  of K) and R_a the rows of K divided by their norms. No gyroscope was calibrated: its terms
  are the identity (K_g = R_g = I, K_ga = 0, b_g = 0) and the comment says so.
* ``kalibr``: the ``imu0`` block of a Kalibr IMU YAML (``rostopic``, ``update_rate`` the
  recording's nominal sample rate, ``accelerometer_noise_density`` in m/s²/√Hz,
  ``accelerometer_random_walk`` in m/s³/√Hz) and the correction under ``calbench_correction``.
  No gyroscope was measured, so its two noise keys are left out (a comment says so) rather
  than stated as 0: Kalibr then asks for them instead of taking a perfect gyroscope;
* ``c-header``: ``static const double`` arrays and an inline correction function (C99);
* ``json``: ``{"format": "calbench-correction/1", "bias", "correction_matrix", ...}``.

Every export states the uncertainties of b and K and where they come from
(:class:`Uncertainty`): from a certified run, the certificate's number, date of issue and
expanded uncertainties U = k·u_c; otherwise the fit's own standard uncertainties (k = 1,
Type A only), marked as not certified.
"""

from __future__ import annotations

import json
import math
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from bench.fitted_model import FittedModel

FORMATS = ("imucal", "kalibr", "c-header", "json")
"""Export formats, by name."""
MEDIA_TYPES = {"imucal": "application/json", "kalibr": "application/yaml", "c-header": "text/x-c",
               "json": "application/json"}  # fmt: skip
SUFFIX = {"imucal": ".imucal.json", "kalibr": ".kalibr.yaml", "c-header": ".h", "json": ".correction.json"}


@dataclass(frozen=True)
class Uncertainty:
    """The uncertainties an export states for b and K, and their source.

    :param bias_u: (3,) uncertainty of b, channel units. :param scale_u: (3, 3) of K, channel unit
        per m/s². :param k_bias, k_scale: their coverage factors (1: standard uncertainties).
    :param certificate: the certificate's number (``None``: not certified).
    :param issued_on: its date of issue (ISO 8601), with ``certificate``.
    :param basis: one sentence: what the numbers are.
    """

    bias_u: tuple[float, float, float]
    scale_u: tuple[tuple[float, float, float], ...]
    k_bias: float
    k_scale: float
    certificate: str | None
    issued_on: str | None
    basis: str

    @classmethod
    def of_fit(cls, fit: FittedModel) -> Uncertainty:
        """The fit's own 1σ (Type A, k = 1), not certified."""
        b = tuple(float(v) for v in np.asarray(fit.bias_sigma, float))
        K = tuple((float(r[0]), float(r[1]), float(r[2])) for r in np.asarray(fit.K_sigma, float))
        basis = "standard uncertainties (k = 1) of the fit alone (Type A); not a certified calibration"
        return cls((b[0], b[1], b[2]), K, 1.0, 1.0, None, None, basis)

    def header_lines(self) -> list[str]:
        """The provenance in a few comment lines (no comment markers)."""
        if self.certificate is not None:
            head = f"certificate {self.certificate}, issued {self.issued_on}"
        else:
            head = "not certified"
        sym = "u" if self.certificate is None else "U"
        matrix = ", ".join(_yaml_list(r) for r in self.scale_u)
        return [
            head,
            f"uncertainties: {self.basis}",
            f"{sym}(bias) = {_yaml_list(self.bias_u)} (k = {self.k_bias:.3g})",
            f"{sym}(scale_matrix) = [{matrix}] (k = {self.k_scale:.3g})",
        ]

    def to_json(self, unit: str) -> dict[str, Any]:
        """The JSON form (``certificate`` ``None`` when not certified)."""
        return {
            "certificate": None
            if self.certificate is None
            else {"number": self.certificate, "issued_on": self.issued_on},
            "basis": self.basis,
            "bias": {"uncertainty": list(self.bias_u), "k": self.k_bias, "unit": unit},
            "scale_matrix": {
                "uncertainty": [list(r) for r in self.scale_u],
                "k": self.k_scale,
                "unit": f"{unit}/(m/s2)",
            },
        }


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


def to_json(fit: FittedModel, source: str = "", uncertainty: Uncertainty | None = None) -> str:
    """The plain correction JSON (``calbench-correction/1``); ``uncertainty`` default: the fit's."""
    b, M = correction(fit)
    u = uncertainty or Uncertainty.of_fit(fit)
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
            "uncertainty": u.to_json(fit.channel_unit),
        },
        indent=2,
    )


def to_imucal(fit: FittedModel, source: str = "", uncertainty: Uncertainty | None = None) -> str:
    """imucal's ``FerrarisCalibrationInfo`` JSON (accelerometer; gyroscope terms identity); the
    provenance and uncertainties in its ``comment`` (imucal's reader takes no other key)."""
    b, K, unit = _model(fit)
    u = uncertainty or Uncertainty.of_fit(fit)
    norms = np.linalg.norm(K, axis=1)
    doc = {
        "acc_unit": "m/s^2",
        "gyr_unit": "deg/s",
        "from_acc_unit": unit or "a.u.",
        "from_gyr_unit": "deg/s",
        "comment": f"calbench calibration of unit {_serial(fit)} {source}".strip()
        + ": accelerometer only; the gyroscope terms are the identity (no gyroscope was calibrated); "
        + "; ".join(u.header_lines())
        + " (of raw = bias + scale_matrix * f, scale_matrix = K_a @ R_a)",
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
    uncertainty: Uncertainty | None = None,
) -> str:
    """A Kalibr-style ``imu0`` YAML: noise parameters in Kalibr's units and the correction.

    :param sample_rate_hz: the IMU's rate (the recording's nominal ``sample_rate_hz``), Hz.
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
    u = uncertainty or Uncertainty.of_fit(fit)
    unit = fit.channel_unit
    rows = "\n".join(f"      - {_yaml_list(r)}" for r in M)
    u_rows = "\n".join(f"        - {_yaml_list(r)}" for r in u.scale_u)
    cert = (
        f"    number: {json.dumps(u.certificate)}\n    issued_on: {json.dumps(u.issued_on)}\n"
        if u.certificate is not None
        else "    number: null  # not certified\n"
    )
    return (
        f"# calbench calibration of unit {_serial(fit)} {source}\n".replace(" \n", "\n")
        + "".join(f"# {line}\n" for line in u.header_lines())
        + "# Kalibr IMU layout. No gyroscope was measured: gyroscope_noise_density and\n"
        "# gyroscope_random_walk are left out (unknown), to be set from the gyroscope's own noise analysis\n"
        "imu0:\n"
        f"  rostopic: {rostopic}\n"
        f"  update_rate: {float(sample_rate_hz)!r}  # [ Hz ]\n"
        f"  accelerometer_noise_density: {float(noise_density_m_s2_sqrt_hz)!r}  # [ m / s^2 / sqrt(Hz) ]\n"
        f"  accelerometer_random_walk: {float(random_walk_m_s3_sqrt_hz)!r}  # [ m / s^3 / sqrt(Hz) ]\n"
        "  time_offset: 0.0\n"
        "  T_i_b:\n"
        "    - [1.0, 0.0, 0.0, 0.0]\n    - [0.0, 1.0, 0.0, 0.0]\n"
        "    - [0.0, 0.0, 1.0, 0.0]\n    - [0.0, 0.0, 0.0, 1.0]\n"
        "  calbench_correction:  # f [m/s^2] = correction_matrix @ (raw - bias)\n"
        f"    channel_unit: {json.dumps(unit)}\n"
        f"    bias: {_yaml_list(b)}\n"
        f"    correction_matrix:\n{rows}\n"
        "  calbench_certificate:\n"
        f"{cert}"
        f"    uncertainty_basis: {json.dumps(u.basis)}\n"
        f"    bias_uncertainty: {_yaml_list(u.bias_u)}\n"
        f"    bias_k: {u.k_bias!r}\n"
        f"    scale_matrix_uncertainty:\n{u_rows}\n"
        f"    scale_matrix_k: {u.k_scale!r}\n"
    )


def _c_name(serial: str) -> str:
    return re.sub(r"[^A-Za-z0-9]", "_", serial).upper()


def to_c_header(fit: FittedModel, source: str = "", uncertainty: Uncertainty | None = None) -> str:
    """A C99 header: the bias, the correction matrix and ``calbench_correct(raw, f_m_s2)``; the
    provenance and uncertainties in its comment, the certificate's number as
    ``CALBENCH_CERTIFICATE`` (``""``: not certified)."""
    b, M = correction(fit)
    u = uncertainty or Uncertainty.of_fit(fit)
    serial = _serial(fit)
    guard = f"CALBENCH_CAL_{_c_name(serial)}_H"

    def num(v: float) -> str:
        return f"{float(v):.17g}"

    rows = ",\n    ".join("{" + ", ".join(num(v) for v in r) + "}" for r in M)
    unit = fit.channel_unit.replace("*/", "")
    comment = f"calbench calibration of unit {serial} {source}".strip().replace("*/", "")
    provenance = "".join(f"\n * {line}".replace("*/", "") for line in u.header_lines())
    number = json.dumps(u.certificate or "")
    return f"""/* {comment}{provenance}
 * f [m/s^2] = CALBENCH_CORRECTION * (raw - CALBENCH_BIAS), raw in {unit} */
#ifndef {guard}
#define {guard}

#define CALBENCH_CERTIFICATE {number}

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
