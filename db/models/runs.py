"""Runs, their completed windows and the durable chunks of their recordings.

A run's raw samples live in its recording CSV (``calbench-recording/1``); the database
keeps what is known to be durable: one :class:`SampleChunk` row per chunk flushed to the
file, and one :class:`RunWindow` row per completed window. After a crash the recording
is truncated to the last chunk's ``end_byte`` and the run resumes at window
``last_complete_window + 1``.
"""

from __future__ import annotations

import datetime as dt
from typing import TYPE_CHECKING, Any

import sqlalchemy as sa
from sqlalchemy.orm import Mapped, mapped_column, relationship

from bench.run_state import ACTIVE_STATES, FINAL_STATES, RESUMABLE_STATES, RunState
from db.base import Base, IntId
from db.models._enum import value_enum

if TYPE_CHECKING:
    from db.models.audit import RunAudit
    from db.models.units import Bench, Unit


__all__ = [
    "ACTIVE_STATES",
    "FINAL_STATES",
    "RESUMABLE_STATES",
    "Run",
    "RunState",
    "RunWindow",
    "SampleChunk",
    "SampleGap",
]


class Run(Base):
    """One procedure executed on one unit.

    :param id: the bench's run id (``bench.records.new_run_id``), shared by the recording's
        file name, this row and the REST resource.
    :param state: :class:`bench.run_state.RunState` (the one run vocabulary).
    :param outcome: ``PASS``/``FAIL``/``ERROR``/``ABORTED`` once finished, else ``None``.
    :param progress: fraction done, 0..1.
    :param params: the procedure's parameters (JSON), including the dwell choice and its reason;
        keys: :mod:`db.models.run_params`. The fit is the run's newest ``fit_model`` row, the
        sample gaps are ``sample_gap`` rows.
    :param kind: ``calibration`` or ``drift_check`` for a run the service queued, ``None`` for a
        run started from the command line.
    :param requested_dwell_s: the dwell the request asked for (s), ``None``: decided by the run.
    :param drift_night: a nightly drift check's scheduled night (ISO 8601), one check a night.
    :param sim_age_days: age (days) of the simulated unit a run on a simulated bench started
        with, so a resume measures the same sensor.
    :param abort_request: the reason of an abort asked of the run (sticky), ``None``: none.
    :param control_seq, control_action: the newest pause or continue request (numbered from 1;
        0: none); its owner applies each number once.
    :param resume_requested: an interrupted run queued to continue; the claim computes where.
    :param finishing_since: when the owner had done every step (UTC): from then on abort, pause
        and continue are refused (``db.repo.queue.enter_finishing``); ``None`` before.
    :param auto_resume: the next automatic resume of a run a device fault interrupted
        (``{"attempt", "not_before", "windows", "fault"}``; ``"gave_up": true`` once the tries are
        spent; ``station.execution.fault_retry``), ``None``: none.
    :param live_progress: the latest ``progress`` event's data, for the streams of every API
        process.
    :param final_event: the run's last event (state, outcome, error, certificate number), written
        once its results are stored; the event streams end with it.
    :param heartbeat_at: last sign of life of the owner process (UTC).
    :param owner_pid, owner_host: the process that owns the run, so a restart can tell
        a dead owner.
    :param last_complete_window: index of the last window whose data are durable, or
        ``None`` before the first one.
    :param n_samples: samples in the recording at the end of the run.
    :param limit_checks: the unit's limits evaluated on the fit (list of JSON objects).
    :param conformity_note: for a completed fit no limits judged (no PASS or FAIL): ``"no
        conformity statement: <why>"`` (``bench.records.RunRecord.conformity_note``), else ``None``.
    :param diagnosis: the ``calbench diagnose --json`` object of the run's recording (its
        findings are also ``finding`` rows), ``None``: not diagnosed.
    :param diagnosis_error: why the run has no diagnosis, ``None``: none said.
    :param certificate_error: why a completed run got no certificate (a refusal, results that
        could not be stored), ``None``: none said.
    """

    __tablename__ = "run"
    __table_args__ = (sa.CheckConstraint("progress >= 0 AND progress <= 1", name="progress_range"),)

    id: Mapped[str] = mapped_column(sa.String(64), primary_key=True, sort_order=-1)
    unit_id: Mapped[int] = mapped_column(sa.ForeignKey("unit.id", ondelete="RESTRICT"), index=True)
    bench_id: Mapped[int | None] = mapped_column(sa.ForeignKey("bench.id", ondelete="SET NULL"), index=True)
    procedure: Mapped[str] = mapped_column(sa.String(100))
    state: Mapped[RunState] = mapped_column(value_enum(RunState, "run_state"), index=True)
    outcome: Mapped[str | None] = mapped_column(sa.String(16))
    progress: Mapped[float] = mapped_column(sa.Float, default=0.0)
    recording_path: Mapped[str | None] = mapped_column(sa.String(1000))
    params: Mapped[dict[str, Any]] = mapped_column(default=dict)
    started_at: Mapped[dt.datetime | None]
    finished_at: Mapped[dt.datetime | None]
    heartbeat_at: Mapped[dt.datetime | None]
    owner_pid: Mapped[int | None]
    owner_host: Mapped[str | None] = mapped_column(sa.String(255))
    error: Mapped[str | None] = mapped_column(sa.Text)
    last_complete_window: Mapped[int | None]
    resume_count: Mapped[int] = mapped_column(default=0)
    n_samples: Mapped[int | None] = mapped_column(sa.BigInteger)
    limit_checks: Mapped[list[Any]] = mapped_column(default=list)
    kind: Mapped[str | None] = mapped_column(sa.String(16))
    requested_dwell_s: Mapped[float | None]
    drift_night: Mapped[str | None] = mapped_column(sa.String(40))
    sim_age_days: Mapped[float | None]
    abort_request: Mapped[str | None] = mapped_column(sa.Text)
    control_seq: Mapped[int] = mapped_column(default=0, server_default="0")
    control_action: Mapped[str | None] = mapped_column(sa.String(16))
    resume_requested: Mapped[bool] = mapped_column(default=False, server_default=sa.false())
    finishing_since: Mapped[dt.datetime | None]
    auto_resume: Mapped[dict[str, Any] | None]
    live_progress: Mapped[dict[str, Any] | None]
    final_event: Mapped[dict[str, Any] | None]
    conformity_note: Mapped[str | None] = mapped_column(sa.Text)
    diagnosis: Mapped[dict[str, Any] | None]
    diagnosis_error: Mapped[str | None] = mapped_column(sa.Text)
    certificate_error: Mapped[str | None] = mapped_column(sa.Text)

    unit: Mapped[Unit] = relationship(back_populates="runs", lazy="raise")
    bench: Mapped[Bench | None] = relationship(lazy="raise")
    audit: Mapped[list[RunAudit]] = relationship(
        lazy="raise",
        order_by="RunAudit.id",
        cascade="all, delete-orphan",
        passive_deletes=True,
    )
    windows: Mapped[list[RunWindow]] = relationship(
        back_populates="run",
        lazy="raise",
        order_by="RunWindow.index",
        cascade="all, delete-orphan",
        passive_deletes=True,
    )


class RunWindow(IntId, Base):
    """A completed window of a run.

    :param index: 0-based window index within the run (unique per run).
    :param kind: ``noise``/``static``/``rate``/``oscillation`` (``bench.records.WindowKind``).
    :param start_s, end_s: window bounds on the recording's clock (s).
    :param pose_deg: commanded table angles (deg, outermost first).
    :param means: means over the window, e.g. ``{"table_deg": [...], "temp_c": 24.9}``
        (JSON; a quantity not measured is ``null``).
    :param step_index: the procedure step that recorded the window.
    """

    __tablename__ = "run_window"
    __table_args__ = (sa.UniqueConstraint("run_id", "index"),)

    run_id: Mapped[str] = mapped_column(sa.String(64), sa.ForeignKey("run.id", ondelete="CASCADE"))
    index: Mapped[int]
    label: Mapped[str] = mapped_column(sa.String(100), default="")
    kind: Mapped[str] = mapped_column(sa.String(16), default="static")
    start_s: Mapped[float]
    end_s: Mapped[float]
    n_samples: Mapped[int]
    pose_deg: Mapped[list[Any]] = mapped_column(default=list)
    means: Mapped[dict[str, Any]] = mapped_column(default=dict)
    step_index: Mapped[int | None]

    run: Mapped[Run] = relationship(back_populates="windows", lazy="raise")


class SampleChunk(IntId, Base):
    """A chunk of samples flushed (and fsynced) to the run's recording CSV.

    :param seq: 0-based chunk number within the run (unique per run).
    :param first_sample: index of the chunk's first sample in the run.
    :param n_samples: samples in the chunk.
    :param last_t_s: time stamp of the chunk's last sample (s).
    :param end_byte: file size of the recording CSV once this chunk was durable (bytes):
        everything before it is safe; anything after it is a chunk in flight. ``None``
        when the writer could not tell.
    :param daq_seq: DAQ sequence number of the chunk's last sample, if known.
    :param window_index: window being recorded during the chunk, ``None`` between windows.
    """

    __tablename__ = "sample_chunk"
    __table_args__ = (sa.UniqueConstraint("run_id", "seq"),)

    run_id: Mapped[str] = mapped_column(sa.String(64), sa.ForeignKey("run.id", ondelete="CASCADE"))
    seq: Mapped[int]
    first_sample: Mapped[int] = mapped_column(sa.BigInteger)
    n_samples: Mapped[int]
    last_t_s: Mapped[float]
    end_byte: Mapped[int | None] = mapped_column(sa.BigInteger)
    daq_seq: Mapped[int | None] = mapped_column(sa.BigInteger)
    window_index: Mapped[int | None]


class SampleGap(IntId, Base):
    """A sample gap of a run (``bench.records.GapRecord``): samples the DAQ produced that the
    recording does not hold, where they were lost and the rule applied.

    :param seq: 0-based order of the gap within the run (unique per run).
    :param first_lost_seq: DAQ sequence number of the first lost sample, ``None``: not said.
    :param n_lost: samples lost, ``None``: unknown.
    :param cause: ``dropped``, ``overflow``, ``restart`` or ``unknown``.
    :param after_row: rows of the recording before the gap.
    :param t_last_s: time of the last row before the gap (recording clock, s), ``None`` at the start.
    :param t_resume_s: time of the next row (recording clock, s).
    :param window_index, window_label: the window being recorded, ``None`` and ``""`` between windows.
    :param action: the rule applied (``window re-measured``, ``between windows``).
    :param daq_epoch: acquisition epoch (+1 at each DAQ restart).
    """

    __tablename__ = "sample_gap"
    __table_args__ = (sa.UniqueConstraint("run_id", "seq"),)

    run_id: Mapped[str] = mapped_column(sa.String(64), sa.ForeignKey("run.id", ondelete="CASCADE"))
    seq: Mapped[int]
    first_lost_seq: Mapped[int | None] = mapped_column(sa.BigInteger)
    n_lost: Mapped[int | None] = mapped_column(sa.BigInteger)
    cause: Mapped[str] = mapped_column(sa.String(16))
    after_row: Mapped[int] = mapped_column(sa.BigInteger)
    t_last_s: Mapped[float | None]
    t_resume_s: Mapped[float]
    window_index: Mapped[int | None]
    window_label: Mapped[str] = mapped_column(sa.String(100), default="")
    action: Mapped[str] = mapped_column(sa.String(40))
    daq_epoch: Mapped[int] = mapped_column(default=0)
