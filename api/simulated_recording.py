"""A simulated run as a calbench-recording/1 (and, beside it, what the truth was).

The recording carries what the bench *believes* (the sidecar geometry, local gravity),
never the truth: the truth goes to ``<stem>.truth.json`` so that a calibration or a
diagnosis of the recording can be checked against it, as with the example recordings in
``examples/`` (made this way, ``examples/README.md``).
"""

from __future__ import annotations

import json
from dataclasses import asdict
from pathlib import Path

import numpy as np

from bench.recording import Recording, Segment, Sidecar, TableAxis, TableGeometry, write_recording
from drivers.sim.offline import SimulatedRun

DEFAULT_AXIS_NAMES = ("outer", "middle", "inner")


def nominal_geometry(
    run: SimulatedRun, lever_arm_m: tuple[float, float, float] = (0.0, 0.0, 0.0)
) -> TableGeometry:
    """The geometry a bench would believe for ``run``: its true axes, the identity mount, ``lever_arm_m``,
    the encoders' step when they read in steps."""
    k = run.axis_vectors.shape[0]
    names = DEFAULT_AXIS_NAMES if k == 3 else tuple(f"axis{i + 1}" for i in range(k))
    axes = tuple(
        TableAxis(name, (float(a[0]), float(a[1]), float(a[2])))
        for name, a in zip(names, run.axis_vectors, strict=True)
    )
    step = run.encoder_resolution_deg
    return TableGeometry(
        axes=axes, lever_arm_m=lever_arm_m, encoder_resolution_deg=step if step > 0 else None
    )


def to_recording(
    run: SimulatedRun,
    *,
    serial: str,
    geometry: TableGeometry | None = None,
    g_local_m_s2: float | None = None,
    procedure: str | None = None,
    unit_model: str = "ADXL325 triad (simulated)",
) -> Recording:
    """Package a simulated run as a :class:`~bench.recording.Recording`.

    :param run: the simulated run.
    :param serial: the unit's serial number.
    :param geometry: what the bench believes about its table; default
        :func:`nominal_geometry` (true axes, identity mount, zero lever arm).
    :param g_local_m_s2: the bench's local gravity; default the run's true value.
    :param procedure: default the run's procedure.
    :raises ValueError: the geometry's axis count differs from the run's encoders.
    """
    geo = nominal_geometry(run) if geometry is None else geometry
    if len(geo.axes) != run.encoder_deg.shape[1]:
        raise ValueError(
            f"geometry has {len(geo.axes)} table axes, the run recorded {run.encoder_deg.shape[1]} encoders"
        )
    sidecar = Sidecar(
        unit_serial=serial,
        channel_unit=run.truth.channel_unit,
        sample_rate_hz=run.sample_rate_hz,
        g_local_m_s2=run.g_local_m_s2 if g_local_m_s2 is None else float(g_local_m_s2),
        unit_model=unit_model,
        procedure=run.procedure if procedure is None else procedure,
        table=geo,
        segments=tuple(Segment(float(a), float(b), label) for a, b, label in run.segments),
    )
    return Recording(
        sidecar=sidecar,
        t_s=run.t_s,
        accel_raw=run.raw,
        table_deg=run.encoder_deg,
        temp_c=run.temp_c,
    )


def truth_document(run: SimulatedRun, *, seed: int | None = None) -> dict[str, object]:
    """The truth of ``run`` as JSON-ready data.

    ``bias`` is the unit's fixed bias, ``bias_run`` the bias the run's windows saw (fixed
    part plus the windows' mean of the slow noise), ``scale_matrix`` K; then the effects,
    the noise, the true geometry and gravity.
    """
    truth = run.truth
    return {
        "channel_unit": truth.channel_unit,
        "bias": truth.bias.tolist(),
        "bias_run": run.bias_seen().tolist(),
        "scale_matrix": truth.K.tolist(),
        "effects": {k: {p: np.asarray(v).tolist() for p, v in ps.items()} for k, ps in truth.effects.items()},
        "noise": asdict(truth.noise),
        "axis_vectors": run.axis_vectors.tolist(),
        "mount_rotation": run.mount.tolist(),
        "g_local_m_s2": run.g_local_m_s2,
        "seed": seed,
    }


def truth_path_for(csv_path: str | Path) -> Path:
    """``run.csv`` -> ``run.truth.json``."""
    p = Path(csv_path)
    return p.with_name(p.stem + ".truth.json")


def write_simulated(
    path: str | Path,
    run: SimulatedRun,
    *,
    serial: str,
    geometry: TableGeometry | None = None,
    g_local_m_s2: float | None = None,
    procedure: str | None = None,
    seed: int | None = None,
    overwrite: bool = False,
    write_truth: bool = True,
) -> Recording:
    """Write ``run`` as ``path`` (CSV) + sidecar, and the truth beside them; returns the recording."""
    rec = to_recording(run, serial=serial, geometry=geometry, g_local_m_s2=g_local_m_s2, procedure=procedure)
    write_recording(rec, path, overwrite=overwrite)
    if write_truth:
        doc = truth_document(run, seed=seed)
        truth_path_for(path).write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    return rec
