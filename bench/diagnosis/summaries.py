"""One sentence per finding, with the size of the effect in the units a metrologist reads."""

from __future__ import annotations

from typing import Any

import numpy as np

_AX = "xyz"


def _channels(v: Any) -> list[int]:
    a = np.asarray(v, dtype=float)
    a = a.reshape(3, -1)
    return [i for i in range(3) if np.any(a[i] != 0)]


def summary(
    effect: str, params: dict[str, Any], sigma: dict[str, Any], labels: tuple[str, ...], span_s: float
) -> str:
    """Human sentence for a finding of ``effect`` with contract ``params``/``sigma``."""
    if effect == "nonlinearity_quadratic":
        k2, s = np.asarray(params["k2_per_g"]), np.asarray(sigma["k2_per_g"])
        parts = [
            f"{_AX[i]} channel {k2[i]:.2e} ± {s[i]:.1e} per g ({k2[i] * 1e3:.3g} mg at 1 g)"
            for i in _channels(k2)
        ]
        return "second-order nonlinearity left out of the model: " + "; ".join(parts)
    if effect == "scale_asymmetry":
        d, s = np.asarray(params["delta"]), np.asarray(sigma["delta"])
        parts = [f"{_AX[i]} channel δ = {d[i]:.2e} ± {s[i]:.1e} ({d[i] * 1e6:.0f} ppm)" for i in _channels(d)]
        return "scale factor differs between positive and negative input: " + "; ".join(parts)
    if effect == "cross_coupling":
        c, s = np.asarray(params["c_per_g"]), np.asarray(sigma["c_per_g"])
        parts = []
        for i in _channels(c):
            terms = ", ".join(
                f"c_{p} = {c[i, k]:.2e} ± {s[i, k]:.1e}" for k, p in enumerate(("xy", "xz", "yz"))
            )
            parts.append(f"{_AX[i]} channel {terms} per g")
        return "products of the inputs leak into the output: " + "; ".join(parts)
    if effect == "temperature_bias":
        t, s = np.asarray(params["tc_m_s2_per_c"]), np.asarray(sigma["tc_m_s2_per_c"])
        parts = [f"{_AX[i]} channel {t[i]:.2e} ± {s[i]:.1e} m/s²/°C" for i in _channels(t)]
        return "bias follows the sensor temperature: " + "; ".join(parts)
    if effect == "thermal_lag":
        t, s = np.asarray(params["tc_m_s2_per_c"]), np.asarray(sigma["tc_m_s2_per_c"])
        tau, st = np.asarray(params["tau_s"]), np.asarray(sigma["tau_s"])
        parts = [
            f"{_AX[i]} channel {t[i]:.2e} ± {s[i]:.1e} m/s²/°C "
            f"through a lag of τ = {tau[i]:.3g} ± {st[i]:.2g} s"
            for i in _channels(t)
        ]
        return "bias follows the sensing element's temperature, which lags the thermometer: " + "; ".join(
            parts
        )
    if effect == "bias_drift":
        d, s = np.asarray(params["drift_m_s2_per_s"]), np.asarray(sigma["drift_m_s2_per_s"])
        parts = [
            f"{_AX[i]} channel {d[i]:.2e} ± {s[i]:.1e} m/s²/s "
            f"({d[i] * span_s:.2e} m/s² over the {span_s:.0f} s of windows)"
            for i in _channels(d)
        ]
        return "bias drifts during the run: " + "; ".join(parts)
    if effect == "table_tilt":
        t, s = np.asarray(params["tilt_rad"]), np.asarray(sigma["tilt_rad"])
        return (
            f"table base not level: a = {t[0] * 1e3:.3f} ± {s[0] * 1e3:.3f} mrad, b = {t[1] * 1e3:.3f} ± "
            f"{s[1] * 1e3:.3f} mrad ({np.rad2deg(np.hypot(*t)):.3f}° in all)"
        )
    if effect == "encoder_offset":
        o, s = np.asarray(params["offset_deg"]), np.asarray(sigma["offset_deg"])
        parts = [f"axis {j + 1} by {o[j]:.4f}° ± {s[j]:.4f}°" for j in range(o.size) if o[j] != 0]
        return "encoder zero off the axis's true zero: " + "; ".join(parts)
    if effect == "table_axis_error":
        a, s = np.asarray(params["angles_rad"]), np.asarray(sigma["angles_rad"])
        parts = [
            f"axis {j + 1} turned by {'ab'[q]} = {a[j, q] * 1e3:.3f} ± {s[j, q] * 1e3:.3f} mrad "
            f"({np.rad2deg(a[j, q]):.3f}°)"
            for j in range(a.shape[0])
            for q in range(2)
            if a[j, q] != 0
        ]
        return (
            "the table's axes are not where its geometry says (the bench's physics, not the unit's): "
            + "; ".join(parts)
        )
    if effect == "hysteresis":
        h, s = np.asarray(params["half_step"]), np.asarray(sigma["half_step"])
        parts = [
            f"{_AX[i]} channel ±{h[j, i]:.3g} ± {s[j, i]:.2g} by the direction of axis {j + 1}'s last move"
            for j in range(h.shape[0])
            for i in range(3)
            if h[j, i] != 0
        ]
        return "the output remembers the direction of the last move (hysteresis): " + "; ".join(parts)
    if effect == "pose_error":
        a = np.asarray(params["angles_rad"])
        mag = np.rad2deg(np.hypot(a[:, 0], a[:, 1]))
        w = int(np.argmax(mag))
        return (
            f"the unit was not where the recording says: windows off their nominal pose by "
            f"{np.sqrt(np.mean(mag**2)):.2g}° rms, most in window {labels[w]} ({mag[w]:.2g}°)"
        )
    if effect == "settling":
        text = (
            "the table still rings when the windows start: at "
            f"{params.get('frequency_hz', float('nan')):.2g} Hz "
            f"their first seconds carry {params.get('early_power_ratio', float('nan')):.2f}× the power "
            "of their second halves"
        )
        if "duration_s" in params:
            text += f"; the ring lasts {params['duration_s']:.1f} ± {sigma['duration_s']:.1f} s after a stop"
        return text
    return effect
