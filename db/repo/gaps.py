"""The sample gaps of runs (``sample_gap`` rows), as ``bench.records.GapRecord`` in and out."""

from __future__ import annotations

import dataclasses
from collections.abc import Collection, Iterable

import sqlalchemy as sa
from sqlalchemy.orm import Session

from bench.records import GapRecord
from db.models import SampleGap


def _record(row: SampleGap) -> GapRecord:
    return GapRecord(
        first_lost_seq=row.first_lost_seq,
        n_lost=row.n_lost,
        cause=row.cause,
        after_row=row.after_row,
        t_last_s=row.t_last_s,
        t_resume_s=row.t_resume_s,
        window_index=row.window_index,
        window_label=row.window_label,
        action=row.action,
        daq_epoch=row.daq_epoch,
    )


def add_gap(session: Session, run_id: str, gap: GapRecord) -> None:
    """Append a gap to the run's gaps (the next ``seq``)."""
    last = session.scalar(sa.select(sa.func.max(SampleGap.seq)).where(SampleGap.run_id == run_id))
    session.add(SampleGap(run_id=run_id, seq=0 if last is None else last + 1, **dataclasses.asdict(gap)))
    session.flush()


def replace_gaps(session: Session, run_id: str, gaps: Iterable[GapRecord]) -> None:
    """Make ``gaps`` (in order) the run's gaps, dropping those stored before (a resume cuts the
    rows after its last durable chunk, and the gaps with them)."""
    session.execute(sa.delete(SampleGap).where(SampleGap.run_id == run_id))
    session.add_all(SampleGap(run_id=run_id, seq=i, **dataclasses.asdict(gap)) for i, gap in enumerate(gaps))
    session.flush()


def list_gaps(session: Session, run_id: str) -> list[GapRecord]:
    """The run's gaps in the order they came."""
    rows = session.scalars(sa.select(SampleGap).where(SampleGap.run_id == run_id).order_by(SampleGap.seq))
    return [_record(r) for r in rows]


def gaps_of_runs(session: Session, run_ids: Collection[str]) -> dict[str, list[GapRecord]]:
    """The gaps of each run, by run id (runs without gaps left out), in one query."""
    if not run_ids:
        return {}
    out: dict[str, list[GapRecord]] = {}
    rows = session.scalars(
        sa.select(SampleGap)
        .where(SampleGap.run_id.in_(list(run_ids)))
        .order_by(SampleGap.run_id, SampleGap.seq)
    )
    for row in rows:
        out.setdefault(row.run_id, []).append(_record(row))
    return out
