"""Diagnose a recording: windows -> window noise -> evidence -> ``bench.diagnosis.diagnose``.

A moving-table recording (``kind.is_moving``, with a table) goes to
``bench.diagnosis.dynamic.diagnose_dynamic`` instead (imported only then). For the others, which
specific force each window is compared with (``windows.known_specific_force``, as in the
calibration):

* a table in the sidecar: f_w = Rᵀ [0, 0, g] at the window's mean encoder angles;
* no table, every window labelled ``nominal_up`` (hand-held six-position): ±g along the
  named axis; the diagnosis then asks whether the unit really was there (``pose_error``);
* neither: orientation-free, f_w = g · L⁻¹(ȳ_w − b)/|L⁻¹(ȳ_w − b)| from the scalar fit,
  so only the magnitude of each reading is evidence.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from bench.calibration.kind import is_moving
from bench.calibration.windows import (
    choose_windows,
    known_specific_force,
    moving_samples,
    table_window_angles,
    unused_warning,
    where,
    window_means,
)
from bench.diagnosis import Diagnosis, StaticEvidence, diagnose
from bench.diagnosis.hysteresis import last_move_sign
from bench.diagnosis.thresholds import THRESHOLDS, Thresholds
from bench.estimation.scalar_fit import fit_scalar
from bench.estimation.windows import StaticWindow
from bench.recording import Recording


def recording_evidence(rec: Recording) -> StaticEvidence:
    """The static evidence of a recording (module docstring).

    :raises ValueError: no usable windows, a window whose noise cannot be estimated.
    """
    return _evidence(rec, list(choose_windows(rec).used))


def _evidence(rec: Recording, wins: list[StaticWindow]) -> StaticEvidence:
    try:
        y, V = window_means(rec, wins)
    except ValueError as exc:
        raise ValueError(f"{where(rec)}: {exc}") from exc
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
    q_rad = axes = mount = qu = None
    peak = 0.0
    known_f = known_specific_force(rec, wins)
    if table is not None and rec.table_deg is not None:
        q_rad = table_window_angles(rec, wins)
        axes, mount = table.axis_vectors, table.mount_matrix
        qu = rec.table_rad_unwrapped()
        assert qu is not None
        peak = _peak_rate_rad_s(qu, t)
    known = known_f is not None
    run_temp = None if rec.temp_c is None else _filled(t, rec.temp_c)
    f = known_f if known_f is not None else _scalar_force(rec, y, V, g)
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
        window_temp_c=None if rec.temp_c is None else tuple(rec.temp_c[w.slice] for w in wins),
        window_t_s=tuple(t[w.slice] for w in wins),
        last_move_sign=None if qu is None else last_move_sign(qu, t, [w.start for w in wins]),
        encoder_resolution_deg=None if table is None or q_rad is None else table.encoder_resolution_deg,
        run_t_s=None if run_temp is None else t,
        run_temp_c=run_temp,
        window_bounds=None
        if run_temp is None
        else np.array([[w.start, w.stop] for w in wins], dtype=np.int64),
    )


def _filled(t_s: np.ndarray, temp_c: np.ndarray) -> np.ndarray | None:
    """(n,) the temperature column with its gaps (NaN) filled linearly in time, or ``None``
    where fewer than two samples carry a temperature."""
    ok = np.isfinite(temp_c)
    if np.count_nonzero(ok) < 2:
        return None
    if np.all(ok):
        return np.asarray(temp_c, dtype=float)
    return np.asarray(np.interp(t_s, t_s[ok], temp_c[ok]), dtype=float)


PEAK_RATE_CHUNK = 1 << 16


def _peak_rate_rad_s(q_rad: np.ndarray, t_s: np.ndarray) -> float:
    """max over samples and axes of |q[i+1] − q[i]| / (t[i+1] − t[i]) (rad/s), 0 for one sample.

    :param q_rad: (n, k) unwrapped encoder angles; :param t_s: (n,) time (s). Taken
    :data:`PEAK_RATE_CHUNK` steps at a time, so the temporaries stay small.
    """
    peak = 0.0
    for a in range(0, t_s.size - 1, PEAK_RATE_CHUNK):
        b = min(t_s.size, a + PEAK_RATE_CHUNK + 1)
        peak = max(peak, float(np.max(np.abs(np.diff(q_rad[a:b], axis=0)) / np.diff(t_s[a:b])[:, None])))
    return peak


def _scalar_force(rec: Recording, y: np.ndarray, V: np.ndarray, g: float) -> np.ndarray:
    try:
        sf = fit_scalar(y, V, g)
    except ValueError as exc:
        raise ValueError(f"{where(rec)}: orientations unknown and the scalar fit failed: {exc}") from exc
    u = np.linalg.solve(sf.L, (y - sf.bias).T).T
    return np.asarray(g * u / np.linalg.norm(u, axis=1, keepdims=True), dtype=float)


def _diagnose_moving(rec: Recording, th: Thresholds) -> Diagnosis:
    from bench.diagnosis.dynamic import diagnose_dynamic  # the moving stack, only for a moving recording

    geo = rec.sidecar.table
    assert geo is not None
    m, y = moving_samples(rec)
    return diagnose_dynamic(
        m,
        y,
        rec.sidecar.g_local_m_s2,
        np.asarray(geo.lever_arm_m, dtype=float),
        temp_c=rec.temp_c,
        unit=rec.sidecar.unit_serial,
        channel_unit=rec.sidecar.channel_unit,
        source=rec.source,
        thresholds=th,
    )


def diagnose_recording(rec: Recording, thresholds: Thresholds = THRESHOLDS) -> Diagnosis:
    """Diagnose one recording; every error message starts with the recording's path.

    A moving-table recording (``kind.is_moving``) goes to
    ``bench.diagnosis.dynamic.diagnose_dynamic``; every other one to the static diagnosis.
    ``thresholds``: the diagnosis's knobs (``bench.diagnosis.thresholds``).
    """
    try:
        if rec.sidecar.table is not None and rec.table_deg is not None and is_moving(rec):
            return _diagnose_moving(rec, thresholds)
        chosen = choose_windows(rec)
        ev = _evidence(rec, list(chosen.used))
        d = diagnose(
            ev,
            unit=rec.sidecar.unit_serial,
            channel_unit=rec.sidecar.channel_unit,
            source=rec.source,
            thresholds=thresholds,
        )
        unused = unused_warning(chosen.unused)
        return d if unused is None else replace(d, notes=(unused, *d.notes))
    except ValueError as exc:
        msg = str(exc)
        where_ = where(rec)
        raise ValueError(msg if msg.startswith(where_) else f"{where_}: {msg}") from exc
