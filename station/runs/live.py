"""What the service knows of the run holding its bench, and the observers that tell it.

:class:`LiveRun` is the runner's view of one run (state, phase, progress, control handle);
:class:`HubObserver` publishes the run's state, progress and windows to the event streams;
:class:`ServiceParamsObserver` stores with the run what a later resume needs (the kind of
service run, the age of the simulated unit); :class:`DbLiveObserver` its latest progress and
the decimated tail of its signal (:mod:`bench.live_signal`).
"""

from __future__ import annotations

import dataclasses
import datetime as dt
import math
import threading
import time
from collections.abc import Callable
from typing import Any, Literal

from sqlalchemy.orm import Session, sessionmaker

from bench.live_signal import Samples, SignalTail, view_to_json
from bench.records import GapRecord, Progress, RunRecord, RunStart, StateChange, WindowRecord, utc_now
from bench.run_observer import NullObserver
from bench.run_state import RunState
from bench.sequencer.control import RunControl
from db.models import Run
from db.repo.runs import set_live_progress, set_service_run
from station.runs.analysis_eta import AnalysisPace
from station.runs.hub import ProgressHub

RunKind = Literal["calibration", "drift_check"]
Phase = Literal["recording", "analysing", "certificate"]
"""What a live run is doing: recording its windows on the bench, analysing the recording (fit,
verdict, diagnosis, budget: no pause or abort any more), storing its certificate or drift check."""
PHASES: tuple[Phase, ...] = ("recording", "analysing", "certificate")


@dataclasses.dataclass
class LiveRun:
    """What the runner knows of the run holding the bench (thread-safe enough: the worker
    writes plain attributes, readers take snapshots)."""

    id: str
    unit_serial: str
    procedure: str
    kind: RunKind
    control: RunControl
    age_days: float
    resumed: bool = False
    shutdown: bool = False
    state: RunState = RunState.QUEUED
    progress: float = 0.0
    phase: Phase = "recording"
    created_at: dt.datetime = dataclasses.field(default_factory=utc_now)
    record: RunRecord | None = None
    error: str | None = None
    done: threading.Event = dataclasses.field(default_factory=threading.Event)
    extra: dict[str, Any] = dataclasses.field(default_factory=dict)
    analysis: AnalysisPace | None = None
    """The bench's analysis pace for this procedure (:mod:`station.runs.analysis_eta`), ``None``:
    no analysed run of it yet."""
    analysis_s: float | None = None
    """Expected analysis wall time (s) once the recording is over, ``None``: unknown."""
    analysing_since: float | None = None
    """``time.monotonic()`` when the recording ended and the analysis began."""

    def expected_analysis_s(self) -> float | None:
        """Expected analysis wall time (s) after the recording, ``None``: unknown."""
        return None if self.analysis is None else self.analysis.expected_s()


class HubObserver(NullObserver):
    """Run observer that publishes state, progress and windows to the hub and the live run."""

    def __init__(self, live: LiveRun, hub: ProgressHub) -> None:
        self.live, self.hub = live, hub

    def on_start(self, start: RunStart) -> None:
        self.live.state = RunState.RUNNING
        self.hub.publish(self.live.id, "state", {"state": RunState.RUNNING.value, "reason": "started"})

    def on_state(self, run_id: str, change: StateChange) -> None:
        self.live.state = change.state
        self.hub.publish(run_id, "state", {"state": change.state.value, "reason": change.reason})

    def on_progress(self, run_id: str, progress: Progress) -> None:
        self.live.state = progress.state
        self.live.progress = progress.fraction
        self.hub.publish(run_id, "progress", progress_data(progress, self.live.expected_analysis_s()))

    def on_phase(self, run_id: str, phase: Phase) -> None:
        """The recording is over: the run is analysed (then its certificate is stored)."""
        self.live.phase = phase
        if phase == "analysing":
            self.live.analysing_since = time.monotonic()
            self.live.analysis_s = self.live.expected_analysis_s()
        self.hub.publish(run_id, "progress", phase_data(self.live, phase))

    def on_gap(self, run_id: str, gap: GapRecord) -> None:
        """A sample gap, as the run page shows it (``GET /api/runs/{id}`` ``gaps`` items)."""
        self.hub.publish(run_id, "gap", dataclasses.asdict(gap))

    def on_window(self, run_id: str, window: WindowRecord) -> None:
        self.hub.publish(
            run_id,
            "window",
            {
                "index": window.index,
                "label": window.label,
                "kind": window.kind.value,
                "pose_deg": list(window.pose_deg),
                "n_samples": window.n_samples,
                "means": window_means(window.means),
            },
        )


class ServiceParamsObserver(NullObserver):
    """Stores the kind of service run and, on a simulated bench, the simulated unit's age with
    the run when it starts (or resumes), so a resume after a restart continues the same
    measurement (``Run.kind``, ``Run.sim_age_days``)."""

    def __init__(self, live: LiveRun, sessions: sessionmaker[Session], sim: bool) -> None:
        self.live, self.sessions, self.sim = live, sessions, sim

    def on_start(self, start: RunStart) -> None:
        with self.sessions.begin() as s:
            set_service_run(
                s, start.run_id, self.live.kind, sim_age_days=self.live.age_days if self.sim else None
            )


SIGNAL_KEY = "signal"
"""The key of ``Run.live_progress`` holding the signal's decimated tail, which the event
streams send as a ``signal`` event (:func:`bench.live_signal.view_to_json`)."""


class DbLiveObserver(NullObserver):
    """Stores the latest progress of the run (``Run.live_progress``) at most every
    ``min_interval_s`` (and always on a state change), for the event streams of API processes
    that do not hold the bench; with it, under :data:`SIGNAL_KEY`, the last ``signal_span_s``
    of the signal decimated to at most ``signal_points`` points (:class:`SignalTail`: memory
    bounded whatever the run's length; the recording is not decimated).

    :param clock: monotonic clock (s), replaceable in tests.
    """

    signal_span_s = 30.0
    signal_points = 300

    def __init__(
        self,
        sessions: sessionmaker[Session],
        min_interval_s: float = 1.0,
        clock: Callable[[], float] = time.monotonic,
        live: LiveRun | None = None,
    ) -> None:
        self.sessions, self.min_interval_s, self.clock = sessions, min_interval_s, clock
        self.live = live
        self._last = -math.inf
        self._signal: SignalTail | None = None

    def on_start(self, start: RunStart) -> None:
        self._signal = SignalTail(start.sample_rate_hz, self.signal_span_s, self.signal_points)

    def on_samples(self, run_id: str, t_s: Samples, accel: Samples, table_deg: Samples) -> None:
        """Keep the block in the signal's tail (sent with the next stored progress)."""
        if self._signal is not None:
            self._signal.add(t_s, accel, table_deg)

    def on_progress(self, run_id: str, progress: Progress) -> None:
        now = self.clock()
        if now - self._last < self.min_interval_s and progress.fraction < 1.0:
            return
        self._last = now
        analysis = None if self.live is None else self.live.expected_analysis_s()
        data = progress_data(progress, analysis)
        if self._signal is not None:
            data[SIGNAL_KEY] = view_to_json(self._signal.view())
        with self.sessions.begin() as s:
            set_live_progress(s, run_id, data)

    def on_phase(self, run_id: str, phase: Phase) -> None:
        """Store the run's new phase with its latest progress (always, not rate-limited)."""
        extra = {} if self.live is None else phase_data(self.live, phase)
        store_phase(self.sessions, run_id, phase, extra)


def phase_data(live: LiveRun, phase: Phase) -> dict[str, Any]:
    """The ``progress`` event of a new phase: the phase, the state and, once the recording is
    over, the expected analysis wall time (``analysis_s``, ``None``: no analysed run of the
    procedure on the bench yet) and when the analysis started (``analysis_started_at``, UTC)."""
    data: dict[str, Any] = {"phase": phase, "state": live.state.value}
    if phase == "analysing":
        live.extra.setdefault("analysis_started_at", utc_now().isoformat())
    if phase != "recording":
        data["analysis_s"] = live.analysis_s
        data["analysis_started_at"] = live.extra.get("analysis_started_at")
    return data


def store_phase(
    sessions: sessionmaker[Session], run_id: str, phase: Phase, extra: dict[str, Any] | None = None
) -> None:
    """Store ``phase`` in the run's latest progress (``Run.live_progress``), which the event
    streams of every API process send as a ``progress`` event (``extra``: more of its keys)."""
    with sessions.begin() as s:
        run = s.get(Run, run_id)
        last = run.live_progress if run is not None and isinstance(run.live_progress, dict) else {}
        done = last.get("progress", 0.0) if phase == "recording" else 1.0  # the recording's fraction
        data = {**last, **(extra or {}), "phase": phase, "progress": done, "remaining_s": 0.0}
        set_live_progress(s, run_id, data)


def window_means(means: Any) -> dict[str, float]:
    """A window's stored per-channel means (finite numbers only; other entries are not shown)."""
    if not isinstance(means, dict):
        return {}
    return {str(k): float(v) for k, v in means.items() if isinstance(v, int | float) and math.isfinite(v)}


def progress_data(progress: Progress, analysis_s: float | None = None) -> dict[str, Any]:
    """The ``progress`` event's data: ``progress`` the recording's fraction done, ``remaining_s``
    its remaining time on the bench clock (:mod:`bench.sequencer.progress`), ``analysis_s`` the
    analysis expected after it (wall s, :mod:`station.runs.analysis_eta`; ``None``: unknown)."""
    return {
        "phase": "recording",
        "progress": progress.fraction,
        "remaining_s": max(0.0, progress.expected_total_s - progress.elapsed_s),
        "analysis_s": analysis_s,
        "step_index": progress.step_index,
        "n_steps": progress.n_steps,
        "step_label": progress.step_label,
        "window_index": progress.window_index,
        "n_windows": progress.n_windows,
        "elapsed_s": progress.elapsed_s,
        "expected_total_s": progress.expected_total_s,
        "table_deg": list(progress.table_deg),
        "state": progress.state.value,
    }
