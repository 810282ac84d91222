"""What is durable of a run: completed windows and flushed chunks of its recording.

``record_window`` advances ``run.last_complete_window`` with a conditional UPDATE
(monotone, never backwards); ``record_chunk`` notes a chunk of samples that is on disk.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import sqlalchemy as sa
from sqlalchemy.orm import Session

from db.models import Run, RunWindow, SampleChunk
from db.notify import notify_run


def _finite(name: str, value: float, where: str) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{where}: {name} = {value!r} is not finite")
    return value


def _json_number(value: Any, name: str, where: str) -> Any:
    """NaN (not measured) -> ``None``; infinities refused; lists and tuples element-wise."""
    if isinstance(value, (list, tuple)):
        return [_json_number(v, f"{name}[{i}]", where) for i, v in enumerate(value)]
    if isinstance(value, float):
        if math.isnan(value):
            return None
        if math.isinf(value):
            raise ValueError(f"{where}: {name} = {value!r} is not finite")
    return value


def record_window(
    session: Session,
    run_id: str,
    index: int,
    *,
    start_s: float,
    end_s: float,
    n_samples: int,
    label: str = "",
    kind: str = "static",
    pose_deg: Sequence[float] = (),
    means: Mapping[str, Any] | None = None,
    step_index: int | None = None,
) -> RunWindow:
    """Store completed window ``index`` (0-based) and advance ``last_complete_window``; the run's
    listeners are told at commit (:func:`db.notify.notify_run`).

    :param start_s, end_s: window bounds on the recording clock (s), ``end_s >= start_s``.
    :param pose_deg: commanded table angles (deg); must be finite.
    :param means: means over the window (JSON-able; NaN floats are stored as ``null``,
        infinities refused).
    :raises ValueError: negative index or sample count, non-finite or reversed bounds.
    """
    where = f"run {run_id} window {index}"
    if index < 0 or n_samples < 0:
        raise ValueError(f"{where}: index and n_samples must be >= 0 (got {index}, {n_samples})")
    start_s, end_s = _finite("start_s", start_s, where), _finite("end_s", end_s, where)
    if end_s < start_s:
        raise ValueError(f"{where}: end_s {end_s} before start_s {start_s}")
    pose = [_finite(f"pose_deg[{i}]", a, where) for i, a in enumerate(pose_deg)]
    clean_means = {str(k): _json_number(v, f"means[{k!r}]", where) for k, v in (means or {}).items()}
    window = RunWindow(
        run_id=run_id,
        index=index,
        label=label,
        kind=kind,
        start_s=start_s,
        end_s=end_s,
        n_samples=n_samples,
        pose_deg=pose,
        means=clean_means,
        step_index=step_index,
    )
    session.add(window)
    session.flush()
    session.execute(
        sa.update(Run)
        .where(Run.id == run_id, sa.or_(Run.last_complete_window.is_(None), Run.last_complete_window < index))
        .values(last_complete_window=index)
        .execution_options(synchronize_session="fetch")
    )
    notify_run(session, run_id)
    return window


def record_chunk(
    session: Session,
    run_id: str,
    seq: int,
    *,
    first_sample: int,
    n_samples: int,
    last_t_s: float,
    end_byte: int | None,
    daq_seq: int | None = None,
    window_index: int | None = None,
) -> SampleChunk:
    """Note that chunk ``seq`` of the run's recording is durable (flushed and fsynced).

    :param end_byte: size of the recording CSV with this chunk written (bytes), or ``None``.
    :param daq_seq: DAQ sequence number of the chunk's last sample.
    :param window_index: window being recorded, ``None`` between windows.
    """
    where = f"run {run_id} chunk {seq}"
    if seq < 0 or first_sample < 0 or n_samples < 0 or (end_byte is not None and end_byte < 0):
        raise ValueError(f"{where}: seq, first_sample, n_samples and end_byte must be >= 0")
    chunk = SampleChunk(
        run_id=run_id,
        seq=seq,
        first_sample=first_sample,
        n_samples=n_samples,
        last_t_s=_finite("last_t_s", last_t_s, where),
        end_byte=end_byte,
        daq_seq=daq_seq,
        window_index=window_index,
    )
    session.add(chunk)
    session.flush()
    return chunk


def list_windows(session: Session, run_id: str) -> list[RunWindow]:
    """The run's completed windows in index order."""
    return list(
        session.scalars(sa.select(RunWindow).where(RunWindow.run_id == run_id).order_by(RunWindow.index))
    )


def last_chunk(session: Session, run_id: str) -> SampleChunk | None:
    """The run's last durable chunk, or ``None``."""
    return session.scalars(
        sa.select(SampleChunk).where(SampleChunk.run_id == run_id).order_by(SampleChunk.seq.desc()).limit(1)
    ).one_or_none()
