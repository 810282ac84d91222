"""What a bench run produces, as plain frozen data.

A run is executed by :mod:`bench.sequencer`; everything that wants to know about it (the
database, the REST service, a progress bar) implements
:class:`bench.run_observer.RunObserver` and is handed these records as the run goes
(openhtf's ``TestRecord`` + output callbacks). The samples themselves go to the recording
(``bench.run_recorder``), not through observers: an observer learns *that* a chunk of
samples is safely on disk (:class:`ChunkRecord`) and *that* a window is complete
(:class:`WindowRecord`), which is what a restart needs to resume. The run's states and its
verdict (:class:`~bench.run_state.RunState`, :class:`~bench.run_state.Outcome`) are in
:mod:`bench.run_state`.

Times are UTC ``datetime`` (timezone-aware) for wall clock and seconds (``*_s``) on the
recording's clock (the ``t`` column) for everything inside the run.
"""

from __future__ import annotations

import enum
import os
import secrets
import socket
from dataclasses import dataclass, field
from datetime import UTC, datetime
from typing import TYPE_CHECKING

from bench.limit_check import LimitCheck
from bench.run_state import Outcome, RunState

if TYPE_CHECKING:
    from bench.calibration.analysis import Analysis
    from bench.calibration.result import CalibrationResult


class WindowKind(enum.Enum):
    """What the table did during a window."""

    NOISE = "noise"
    """Static window recorded first to measure the unit's noise (dwell policy)."""
    STATIC = "static"
    """The table held a pose; the window's samples enter the static fit."""
    RATE = "rate"
    """One axis turned at constant rate."""
    OSCILLATION = "oscillation"
    """One or more axes oscillated."""


def utc_now() -> datetime:
    """The current time, timezone-aware UTC."""
    return datetime.now(UTC)


def new_run_id(unit_serial: str, started_at: datetime | None = None) -> str:
    """A unique, sortable, file-name-safe run id, e.g. ``20250101T120000Z-SN0001-3fa9c2``.

    The bench assigns run ids (not the database), so a recording's file name, its database
    row and the REST resource all share one key from the first sample on.
    """
    when = (started_at or utc_now()).astimezone(UTC)
    safe = "".join(c if c.isalnum() or c in "-_" else "_" for c in unit_serial)[:32] or "unit"
    return f"{when:%Y%m%dT%H%M%SZ}-{safe}-{secrets.token_hex(3)}"


@dataclass(frozen=True)
class DwellChoice:
    """The static dwell time of a run and why it was chosen (stored with the run).

    :param dwell_s: dwell per static pose (s).
    :param source: ``"allan"`` (the unit's last Allan characterisation), ``"noise_window"``
        (a static window this run recorded first), ``"fixed"`` (given explicitly).
    :param reason: one sentence for the operator and the certificate.
    :param details: numbers behind the choice (e.g. ``{"tau_min_s": 40.0, "sigma_min": 1e-5}``).
    """

    dwell_s: float
    source: str
    reason: str
    details: dict[str, float | str] = field(default_factory=dict)


@dataclass(frozen=True)
class RunStart:
    """Everything known when a run starts (or is resumed).

    :param run_id: opaque string key of the run. With a database the composition root
        creates the run row first and passes its id (``str(run.id)``); without one,
        :func:`new_run_id` makes one.
    :param unit_serial: unit under test.
    :param procedure: registry name, e.g. ``"static-12"``.
    :param bench_name: which bench (several benches may share one database).
    :param recording_path: the CSV the samples are written to (sidecar beside it, same stem).
    :param sample_rate_hz: DAQ rate.
    :param n_axes: table axes.
    :param n_windows: windows the procedure will record.
    :param expected_duration_s: preview duration of the whole procedure (s).
    :param dwell: the dwell choice; ``None`` until a noise window has decided it.
    :param parameters: the procedure's parameters (JSON-serialisable).
    :param started_at: wall-clock start (UTC).
    :param host: host name of the process executing the run.
    :param pid: process id executing the run (a restart marks the run INTERRUPTED when that
        process is gone).
    :param resumed_from_window: ``None`` for a fresh run; for a resumed run, the index of the
        first window recorded by this process.
    """

    run_id: str
    unit_serial: str
    procedure: str
    bench_name: str
    recording_path: str
    sample_rate_hz: float
    n_axes: int
    n_windows: int
    expected_duration_s: float
    dwell: DwellChoice | None = None
    parameters: dict[str, object] = field(default_factory=dict)
    started_at: datetime = field(default_factory=utc_now)
    host: str = field(default_factory=socket.gethostname)
    pid: int = field(default_factory=os.getpid)
    resumed_from_window: int | None = None


@dataclass(frozen=True)
class ChunkRecord:
    """A chunk of samples that is now flushed and fsync'ed to the recording.

    :param seq: 0-based chunk number within the run (continues across a resume).
    :param first_sample: index of the chunk's first sample in the recording (0-based row).
    :param n_samples: samples in the chunk.
    :param last_t_s: time stamp of the chunk's last sample (recording clock, s).
    :param end_byte: size of the recording CSV once this chunk is durable (bytes); a resume
        cuts the file here, everything before it is safe.
    :param window_index: window being recorded when the chunk was written, ``None`` between
        windows (moves, settling, spin-up).
    """

    seq: int
    first_sample: int
    n_samples: int
    last_t_s: float
    end_byte: int
    window_index: int | None = None

    @property
    def n_samples_total(self) -> int:
        """Samples in the recording after this chunk."""
        return self.first_sample + self.n_samples


@dataclass(frozen=True)
class WindowRecord:
    """One completed window; once reported, its samples and segment are on disk.

    :param index: 0-based window index within the procedure (stable across a resume).
    :param label: e.g. ``"pos01"``, ``"rate+200"``, ``"noise"``.
    :param kind: what the table did.
    :param start_s: first sample time of the window (recording clock, s).
    :param end_s: last sample time (s).
    :param n_samples: samples in the window.
    :param pose_deg: commanded table angles at the window (deg, outermost first).
    :param mean_table_deg: mean encoder angles over the window (deg).
    :param temp_c_mean: mean sensor temperature (°C), NaN if not measured.
    :param step_index: index of the step that recorded this window.
    :param means: per-channel means over the window in the recording's units, keyed by CSV
        column (``ax``, ``ay``, ``az``, ``temp``).
    """

    index: int
    label: str
    kind: WindowKind
    start_s: float
    end_s: float
    n_samples: int
    pose_deg: tuple[float, ...]
    mean_table_deg: tuple[float, ...]
    temp_c_mean: float
    step_index: int
    means: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class GapRecord:
    """Samples the DAQ produced that the recording does not hold, where they were lost.

    The recording's time axis keeps the hole: the row after the gap is stamped
    ``t_resume_s = t_last_s + (n_lost + 1) / sample_rate_hz`` (DAQ sample clock), never
    moved up against the row before it.

    :param first_lost_seq: DAQ sequence number of the first lost sample (in ``daq_epoch``);
        ``None`` when the DAQ did not say (a restart).
    :param n_lost: samples lost (``None``: unknown, the DAQ's counter restarted).
    :param cause: ``"dropped"`` (the DAQ never kept them), ``"overflow"`` (its ring overwrote
        them before the host read them), ``"restart"`` (acquisition restarted after
        repeated gaps; ``n_lost`` counts the samples seen lost before the restart) or
        ``"unknown"``.
    :param after_row: rows in the recording before the gap (0-based index of the row after it).
    :param t_last_s: time stamp of the last row before the gap (recording clock, s);
        ``None`` at the very start.
    :param t_resume_s: where the next row is stamped (recording clock, s).
    :param window_index: window being recorded when the gap came, ``None`` between windows.
    :param window_label: that window's label ("" between windows).
    :param action: the rule applied: ``"window re-measured"`` (its samples are not used),
        ``"between windows"`` (no window used the lost span).
    :param daq_epoch: acquisition epoch (0, then +1 at each DAQ restart, when the
        sequence numbers start again at 0).
    """

    first_lost_seq: int | None
    n_lost: int | None
    cause: str
    after_row: int
    t_last_s: float | None
    t_resume_s: float
    window_index: int | None
    window_label: str
    action: str
    daq_epoch: int = 0


@dataclass(frozen=True)
class StateChange:
    """A run changed state.

    :param state: the new state.
    :param reason: why (e.g. ``"interlock open"``, ``"operator pause"``, ``"resumed from window 5"``).
    :param at: wall-clock time (UTC).
    """

    state: RunState
    reason: str = ""
    at: datetime = field(default_factory=utc_now)


@dataclass(frozen=True)
class Progress:
    """Where the run is, for a progress bar.

    :param step_index: index of the step being executed (0-based).
    :param n_steps: steps in the procedure.
    :param step_label: the step's label.
    :param window_index: window being recorded, or ``None`` during moves.
    :param n_windows: windows in the procedure.
    :param elapsed_s: run time so far on the recording clock (s).
    :param expected_total_s: expected duration of the whole run on the recording clock (s),
        holds so far included.
    :param table_deg: latest encoder angles (deg).
    :param state: current run state.
    :param held_s: recording-clock time spent held so far (operator pause, suspension), s.
    :param done_fraction: the procedure's fraction done by the sequencer's schedule
        (:meth:`bench.sequencer.progress.RemainingTime.done_fraction`); ``None``: not known.
    """

    step_index: int
    n_steps: int
    step_label: str
    window_index: int | None
    n_windows: int
    elapsed_s: float
    expected_total_s: float
    table_deg: tuple[float, ...]
    state: RunState
    held_s: float = 0.0
    done_fraction: float | None = None

    @property
    def fraction(self) -> float:
        """Fraction done, in [0, 1], for a progress bar: ``done_fraction`` where the sequencer
        gave it (windows done on the procedure's schedule: it never steps back when the pace
        is re-measured or the run resumes), else the expected working time done, time held
        counting in neither,

            fraction = (elapsed_s − held_s) / (expected_total_s − held_s);

        either stands still while the run is paused or suspended."""
        if self.done_fraction is not None:
            return min(1.0, max(0.0, self.done_fraction))
        working_s = self.expected_total_s - self.held_s
        if working_s <= 0:
            return 0.0
        return min(1.0, max(0.0, (self.elapsed_s - self.held_s) / working_s))


@dataclass(frozen=True)
class RunRecord:
    """The finished run (or the state it was left in), handed to every observer at the end.

    :param start: the run's :class:`RunStart` (of the last process that executed it).
    :param state: a final state (:meth:`RunState.finished` of the outcome), or INTERRUPTED when
        the caller could not finish.
    :param outcome: verdict, set when final; ``None`` for a completed fit that no limits judged
        (``conformity_note`` says why).
    :param windows: every completed window, including those recorded before a resume.
    :param ended_at: wall-clock end (UTC).
    :param error: for ERROR: what broke and where (one line), else ``None``.
    :param calibration: the fit (an observer that stores it writes its
        ``calbench calibrate --json`` object), or ``None`` when no fit was made (ERROR,
        ABORTED, too few windows).
    :param limit_checks: the unit's limits evaluated on the fit (empty: no limits given).
    :param conformity_note: for a completed fit without a verdict: ``"no conformity statement:
        <why no limits apply>"``; empty otherwise.
    :param n_samples: samples in the recording.
    :param dwell: the dwell choice actually used.
    :param fit_covariance: (p, p) covariance of the fitted parameters, or ``None``.
    :param fit_param_names: the p parameter names in covariance order.
    :param gaps: every sample gap of the run, in order (empty: no sample lost).
    :param analysis: the recording analysed once (``bench.calibration.analysis.analyse``):
        ``calibration`` is its fit; the service's finish adds the nominal |g| check, the
        diagnosis and the certificate's budget to it without reading the recording again.
    """

    start: RunStart
    state: RunState
    outcome: Outcome | None
    windows: tuple[WindowRecord, ...]
    ended_at: datetime = field(default_factory=utc_now)
    error: str | None = None
    calibration: CalibrationResult | None = None
    limit_checks: tuple[LimitCheck, ...] = ()
    conformity_note: str = ""
    n_samples: int = 0
    dwell: DwellChoice | None = None
    fit_covariance: tuple[tuple[float, ...], ...] | None = None
    fit_param_names: tuple[str, ...] = ()
    gaps: tuple[GapRecord, ...] = ()
    analysis: Analysis | None = None

    @property
    def run_id(self) -> str:
        """The run's id."""
        return self.start.run_id
