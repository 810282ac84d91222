"""``DbRunObserver``: the database as an output callback of bench runs.

Implements ``bench.run_observer.RunObserver``. Each event is written in its own short
transaction (``with factory.begin()``), so the database always holds the state of the
run up to its last event: the last complete window and the last durable chunk of the
recording, which is what a restart needs to resume. Transient database errors
(``OperationalError``: a lock held too long, a dropped connection) are retried a few
times before the error is raised to the sequencer, which then ends the run as ERROR.

The bench and the database share one state vocabulary (``bench.run_state.RunState``): a run's
record carries its final state (``RunState.finished`` of its outcome) as it is stored.
"""

from __future__ import annotations

import dataclasses
import time
from collections.abc import Callable
from typing import Any, TypeVar

from sqlalchemy.exc import OperationalError
from sqlalchemy.orm import Session, sessionmaker

from bench import records as br
from bench.run_observer import NullObserver
from bench.run_state import HOLDING_STATES, Outcome
from db.models import FINAL_STATES, Run, RunState
from db.models import run_params as rp
from db.notify import notify_run
from db.repo import gaps, progress, recovery, results, runs, units
from db.types import utc_now

T = TypeVar("T")

_LIVE = frozenset({RunState.QUEUED, *HOLDING_STATES})


def final_state(outcome: Outcome | None) -> RunState:
    """The stored state of a run that ended with ``outcome``."""
    return RunState.finished(outcome)


def finish_record(s: Session, record: br.RunRecord) -> bool:
    """Move a finished run to its final state with its outcome and error (False: it was final)."""
    return runs.finish_run(
        s,
        record.run_id,
        final_state(record.outcome),
        outcome=record.outcome.value if record.outcome is not None else None,
        error=record.error,
        now=record.ended_at,
    )


def store_fit(s: Session, record: br.RunRecord, *, replace: bool = True) -> None:
    """Store the run's one fit, from its analysis (``record.analysis``, else ``record.calibration``):
    its ``fit_model`` row (kind as the fit chose it, the ``calbench calibrate --json`` object, the
    covariance and its parameter names), the one home every reader takes it from. A fit already
    stored is replaced (``replace``) or kept.
    """
    fit = record.calibration
    if fit is None:
        raise ValueError(f"run {record.run_id} has no fit to store")
    if s.get(Run, record.run_id, with_for_update=True) is None:
        raise LookupError(f"run {record.run_id} not found")
    existing = results.list_fits(s, record.run_id)
    if existing and not replace:
        return
    for row in existing:
        s.delete(row)
    contract = record.analysis.contract() if record.analysis is not None else fit.to_contract()
    results.add_fit(
        s,
        record.run_id,
        fit.kind,
        contract,
        covariance=record.fit_covariance,
        param_names=record.fit_param_names,
    )


def update_stored_fit(
    s: Session, run_id: str, change: Callable[[dict[str, Any]], dict[str, Any] | None]
) -> None:
    """Change the run's stored fit: ``change`` gets the ``calibrate --json`` object of its
    ``fit_model`` row and gives the new one (``None``: no change)."""
    if s.get(Run, run_id, with_for_update=True) is None:
        return
    row = results.fit_of_run(s, run_id)
    if row is None or not isinstance(row.contract, dict):
        return
    new = change(row.contract)
    if new is None:
        return
    row.contract = new
    s.flush()


class DbRunObserver(NullObserver):
    """Writes runs, windows, chunks, progress, dwell, sample gaps and outcome to the database.

    :param session_factory: ``db.engine.make_session_factory(engine)``.
    :param min_progress_interval_s: progress (and heartbeat) written at most this often (s).
    :param retries: attempts per event on ``OperationalError``; :param retry_wait_s: wait between them.
    :param clock: monotonic clock (s), replaceable in tests.
    :param defer_final_state: a run finished with a fit (PASS, FAIL, or completed without a
        verdict) has its results stored but its state stays live
        (``running``, progress 1) until the caller stores what follows (the service's
        certificate) and calls :func:`finish_record` in the same transaction, so a run that
        reads ``completed`` always has them.
    """

    def __init__(
        self,
        session_factory: sessionmaker[Session],
        *,
        min_progress_interval_s: float = 1.0,
        retries: int = 3,
        retry_wait_s: float = 0.5,
        clock: Callable[[], float] = time.monotonic,
        defer_final_state: bool = False,
    ) -> None:
        self._factory = session_factory
        self._defer_final_state = defer_final_state
        self._min_progress_interval_s = min_progress_interval_s
        self._retries = max(1, retries)
        self._retry_wait_s = retry_wait_s
        self._clock = clock
        self._last_progress: dict[str, float] = {}
        self._first_chunk_pending: set[str] = set()

    def _tx(self, fn: Callable[[Session], T], notify: str | None = None) -> T:
        """``fn`` in one transaction, retried on ``OperationalError``; with ``notify`` (a run id)
        the run's listeners are notified when it commits (:func:`db.notify.notify_run`)."""
        for attempt in range(1, self._retries + 1):
            try:
                with self._factory.begin() as session:
                    out = fn(session)
                    if notify is not None:
                        notify_run(session, notify)
                    return out
            except OperationalError:
                if attempt == self._retries:
                    raise
                time.sleep(self._retry_wait_s * attempt)
        raise AssertionError("unreachable")  # pragma: no cover

    # -- RunObserver -----------------------------------------------------------------------

    def on_start(self, start: br.RunStart) -> None:
        """Create the run (fresh) or hand it to this process (resumed)."""
        params: dict[str, Any] = {
            **start.parameters,
            rp.SAMPLE_RATE_HZ: start.sample_rate_hz,
            rp.N_AXES: start.n_axes,
            rp.N_WINDOWS: start.n_windows,
            rp.EXPECTED_DURATION_S: start.expected_duration_s,
        }
        if start.dwell is not None:
            params[rp.DWELL] = dataclasses.asdict(start.dwell)

        def write(s: Session) -> None:
            bench = units.get_or_create_bench(s, start.bench_name)
            unit = units.get_or_create_unit(s, start.unit_serial, bench_id=bench.id)
            run = s.get(Run, start.run_id, with_for_update=True)
            if run is None:
                runs.create_run(
                    s,
                    start.run_id,
                    unit.id,
                    start.procedure,
                    bench_id=bench.id,
                    params=params,
                    recording_path=start.recording_path,
                    state=RunState.RUNNING,
                    owner_pid=start.pid,
                    owner_host=start.host,
                    now=start.started_at,
                )
                return
            if run.state in FINAL_STATES:
                raise ValueError(
                    f"run {start.run_id} is {run.state.value}; a finished run cannot start again"
                )
            if run.unit_id != unit.id:
                raise ValueError(f"run {start.run_id} belongs to another unit than {start.unit_serial}")
            if run.state is RunState.INTERRUPTED:
                run.resume_count += 1
            run.state, run.owner_pid, run.owner_host = RunState.RUNNING, start.pid, start.host
            run.heartbeat_at, run.error, run.bench_id = utc_now(), None, bench.id
            run.started_at = run.started_at or start.started_at
            run.params = {**run.params, **params}
            run.recording_path = start.recording_path
            s.flush()
            if start.resumed_from_window is not None:
                recovery.rewind_run(s, start.run_id, start.resumed_from_window)

        self._tx(write, notify=start.run_id)
        self._first_chunk_pending.add(start.run_id)
        self._last_progress.pop(start.run_id, None)

    def on_state(self, run_id: str, change: br.StateChange) -> None:
        """Pause, suspension, resumption; INTERRUPTED marks the run resumable."""
        if change.state is RunState.INTERRUPTED:
            self._tx(
                lambda s: recovery.mark_run_interrupted(s, run_id, change.reason or "stopped", now=change.at)
            )
        elif change.state in _LIVE:
            self._tx(
                lambda s: runs.set_live_state(s, run_id, change.state, now=change.at, reason=change.reason)
            )

    def on_progress(self, run_id: str, p: br.Progress) -> None:
        """Progress fraction and heartbeat, at most every ``min_progress_interval_s``."""
        now = self._clock()
        last = self._last_progress.get(run_id)
        if last is not None and now - last < self._min_progress_interval_s:
            return
        self._last_progress[run_id] = now
        self._tx(lambda s: runs.heartbeat(s, run_id, progress=p.fraction))

    def on_chunk(self, run_id: str, chunk: br.ChunkRecord) -> None:
        """A durable chunk; the first one after a (re)start replaces stale rows from ``seq`` on."""
        first = run_id in self._first_chunk_pending

        def write(s: Session) -> None:
            if first:
                recovery.drop_chunks_from(s, run_id, chunk.seq)
            progress.record_chunk(
                s,
                run_id,
                chunk.seq,
                first_sample=chunk.first_sample,
                n_samples=chunk.n_samples,
                last_t_s=chunk.last_t_s,
                end_byte=chunk.end_byte,
                window_index=chunk.window_index,
            )
            runs.heartbeat(s, run_id)

        self._tx(write)
        self._first_chunk_pending.discard(run_id)

    def on_window(self, run_id: str, window: br.WindowRecord) -> None:
        """A complete window; advances ``last_complete_window``."""
        self._tx(lambda s: self._write_window(s, run_id, window))

    @staticmethod
    def _write_window(s: Session, run_id: str, w: br.WindowRecord) -> None:
        means: dict[str, Any] = {**w.means, "table_deg": list(w.mean_table_deg), "temp_c": w.temp_c_mean}
        progress.record_window(
            s,
            run_id,
            w.index,
            start_s=w.start_s,
            end_s=w.end_s,
            n_samples=w.n_samples,
            label=w.label,
            kind=w.kind.value,
            pose_deg=w.pose_deg,
            means=means,
            step_index=w.step_index,
        )

    def on_dwell(self, run_id: str, dwell: br.DwellChoice) -> None:
        """Store the dwell choice and its reason with the run's parameters."""
        self._tx(lambda s: runs.merge_params(s, run_id, {rp.DWELL: dataclasses.asdict(dwell)}))

    def on_gap(self, run_id: str, gap: br.GapRecord) -> None:
        """A sample gap, stored as it happens (a ``sample_gap`` row)."""

        def write(s: Session) -> None:
            if s.get(Run, run_id, with_for_update=True) is None:
                raise LookupError(f"run {run_id} not found")
            gaps.add_gap(s, run_id, gap)

        self._tx(write, notify=run_id)

    def on_finish(self, record: br.RunRecord) -> None:
        """Outcome, error, limit checks, any window not yet stored, and the fit
        (:func:`store_fit`) — the only place a bench run's fit is stored."""
        run_id = record.run_id

        def write(s: Session) -> None:
            stored = {w.index for w in progress.list_windows(s, run_id)}
            for w in record.windows:
                if w.index not in stored:
                    self._write_window(s, run_id, w)
            run = s.get(Run, run_id, with_for_update=True)
            if run is None:
                raise LookupError(f"run {run_id} was never started in the database")
            run.n_samples = record.n_samples
            run.limit_checks = [dataclasses.asdict(c) for c in record.limit_checks]
            # the recording's own list (a resume drops the gaps after the rows it cut)
            gaps.replace_gaps(s, run_id, record.gaps)
            if record.dwell is not None:
                run.params = {**run.params, rp.DWELL: dataclasses.asdict(record.dwell)}
            if record.conformity_note:
                run.conformity_note = record.conformity_note
            s.flush()
            if not record.state.is_final:
                recovery.mark_run_interrupted(s, run_id, record.error or "the run stopped before finishing")
                return
            if self._defer_final_state and record.state in (RunState.COMPLETED, RunState.FAILED):
                run.progress = 1.0
            else:
                finish_record(s, record)
            if record.calibration is not None:
                store_fit(s, record)

        self._tx(write, notify=run_id)
        self._first_chunk_pending.discard(run_id)
        self._last_progress.pop(run_id, None)
