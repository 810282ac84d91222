"""Diagnose a recording: windows -> window noise -> evidence -> ``bench.diagnosis.diagnose``.

A moving-table recording (``calibration_dynamic.is_dynamic``, with a table) goes to
``bench.diagnosis.dynamic.diagnose_dynamic`` instead. For the others, which specific force
each window is compared with (as in ``bench.calibration``):

* a table in the sidecar: f_w = Rᵀ [0, 0, g] at the window's circular-mean encoder angles;
* no table, every window labelled ``nominal_up`` (hand-held six-position): ±g along the
  named axis; the diagnosis then asks whether the unit really was there (``pose_error``);
* neither: orientation-free, f_w = g · L⁻¹(ȳ_w − b)/|L⁻¹(ȳ_w − b)| from the scalar fit,
  so only the magnitude of each reading is evidence.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.calibration import choose_windows, unused_warning, window_means
from bench.calibration_dynamic import is_dynamic
from bench.diagnosis import Diagnosis, StaticEvidence, diagnose
from bench.diagnosis.dynamic import diagnose_dynamic
from bench.estimation.dynamic_model import prepare_motion
from bench.estimation.scalar_fit import fit_scalar
from bench.estimation.windows import StaticWindow
from bench.kinematics import attitude, static_specific_force
from bench.recording import Recording

_AXES = {"+x": (0, 1.0), "-x": (0, -1.0), "+y": (1, 1.0), "-y": (1, -1.0), "+z": (2, 1.0), "-z": (2, -1.0)}


def _where(rec: Recording) -> str:
    return rec.source or "recording"


def recording_evidence(rec: Recording) -> StaticEvidence:
    """The static evidence of a recording (module docstring).

    :raises ValueError: no usable windows, a window whose noise cannot be estimated.
    """
    return _evidence(rec, list(choose_windows(rec).used))


def _evidence(rec: Recording, wins: list[StaticWindow]) -> StaticEvidence:
    try:
        y, V = window_means(rec, wins)
    except ValueError as exc:
        raise ValueError(f"{_where(rec)}: {exc}") from exc
    g = rec.sidecar.g_local_m_s2
    t = rec.t_s
    mid = np.array([(t[w.start] + t[w.stop - 1]) / 2 for w in wins])
    temp = None
    if rec.temp_c is not None:
        temp = np.array(
            [
                np.nanmean(rec.temp_c[w.slice]) if np.any(np.isfinite(rec.temp_c[w.slice])) else np.nan
                for w in wins
            ]
        )
    table = rec.sidecar.table
    q_rad = axes = mount = None
    known = True
    peak = 0.0
    if table is not None and rec.table_deg is not None:
        q = np.deg2rad(rec.table_deg)
        q_rad = np.array([np.arctan2(np.sin(q[w.slice]).mean(0), np.cos(q[w.slice]).mean(0)) for w in wins])
        axes, mount = table.axis_vectors, table.mount_matrix
        f = static_specific_force(attitude(axes, q_rad, mount), g)
        qu = rec.table_rad_unwrapped()
        assert qu is not None
        peak = float(np.max(np.abs(np.diff(qu, axis=0)) / np.diff(t)[:, None])) if t.size > 1 else 0.0
    elif all(w.nominal_up in _AXES for w in wins):
        f = _labelled_force(wins, g)
    else:
        f = _scalar_force(rec, y, V, g)
        known = False
    return StaticEvidence(
        y=y,
        V=V,
        f_m_s2=f,
        mid_s=mid,
        labels=tuple(w.label for w in wins),
        g_local_m_s2=g,
        temp_c=temp,
        table_rad=q_rad,
        axis_vectors=axes,
        mount=mount,
        orientation_known=known,
        peak_rate_rad_s=peak,
        window_samples=tuple(rec.accel_raw[w.slice] for w in wins),
        sample_rate_hz=rec.sidecar.sample_rate_hz,
    )


def _labelled_force(wins: list[StaticWindow], g: float) -> np.ndarray:
    f = np.zeros((len(wins), 3))
    for k, w in enumerate(wins):
        axis, sign = _AXES[str(w.nominal_up)]
        f[k, axis] = sign * g
    return f


def _scalar_force(rec: Recording, y: np.ndarray, V: np.ndarray, g: float) -> np.ndarray:
    try:
        sf = fit_scalar(y, V, g)
    except ValueError as exc:
        raise ValueError(f"{_where(rec)}: orientations unknown and the scalar fit failed: {exc}") from exc
    u = np.linalg.solve(sf.L, (y - sf.bias).T).T
    return g * u / np.linalg.norm(u, axis=1, keepdims=True)


def _diagnose_moving(rec: Recording) -> Diagnosis:
    geo = rec.sidecar.table
    q = rec.table_rad_unwrapped()
    assert geo is not None and q is not None
    y = np.asarray(rec.accel_raw, dtype=float)
    bad = np.argwhere(~np.isfinite(y))
    if bad.size:
        row, col = bad[0]
        raise ValueError(f"sample {row} (t = {rec.t_s[row]:.6g} s): {'xyz'[col]} channel is not finite")
    m = prepare_motion(rec.t_s, q, geo.axis_vectors, geo.mount_matrix)
    return diagnose_dynamic(
        m,
        y,
        rec.sidecar.g_local_m_s2,
        np.asarray(geo.lever_arm_m, dtype=float),
        temp_c=rec.temp_c,
        unit=rec.sidecar.unit_serial,
        channel_unit=rec.sidecar.channel_unit,
        source=rec.source,
    )


def diagnose_recording(rec: Recording) -> Diagnosis:
    """Diagnose one recording; every error message starts with the recording's path.

    A moving-table recording (``calibration_dynamic.is_dynamic``) goes to
    ``bench.diagnosis.dynamic.diagnose_dynamic``; every other one to the static diagnosis.
    """
    try:
        if rec.sidecar.table is not None and rec.table_deg is not None and is_dynamic(rec):
            return _diagnose_moving(rec)
        chosen = choose_windows(rec)
        ev = _evidence(rec, list(chosen.used))
        d = diagnose(
            ev, unit=rec.sidecar.unit_serial, channel_unit=rec.sidecar.channel_unit, source=rec.source
        )
        unused = unused_warning(chosen.unused)
        return d if unused is None else replace(d, notes=(unused, *d.notes))
    except ValueError as exc:
        msg = str(exc)
        where = _where(rec)
        raise ValueError(msg if msg.startswith(where) else f"{where}: {msg}") from exc
