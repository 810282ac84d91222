"""The sequencer: executes a procedure's steps on a RotaryTable and a Daq.

One thread (the caller's) executes the steps; a :class:`bench.sequencer.daq.DaqPump` thread
drains the DAQ. Every wait is a loop over sample blocks: each block goes to the recording
(:class:`bench.run_recorder.RunRecorder`), into the open window if any, and the loop checks
the control (abort, pause), the temperature band and, every ``status_poll_s``, the
table's interlock. Blocking table calls run in a helper thread under a deadline while the
loop keeps draining the DAQ. Window lengths and settling count DAQ samples, so a simulated
bench running faster than real time gives the same recording.

Pause, an open interlock or a temperature outside its band *suspend* the run: the window in
progress is dropped, the table held, and the window recorded again once the condition clears.
How the run ended (ABORTED, ERROR, whether the bench may resume it) is decided by
:mod:`bench.sequencer.outcome`; in every case the table is stopped (safe state), acquisition
stopped and the recording closed with everything recorded so far.

Step execution is in :mod:`bench.sequencer.steps` and the safe state in
:mod:`bench.sequencer.safety`, both over the :class:`~bench.sequencer.context.RunContext` this
class offers; the observers are told through :mod:`bench.sequencer.observers`, progress is
computed by :mod:`bench.sequencer.progress`; this module has the loop and life cycle.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from typing import TypeVar

import numpy as np

from bench.procedures.steps import Procedure
from bench.records import DwellChoice, RunStart, StateChange, WindowRecord
from bench.run_observer import RunObserver
from bench.run_recorder import RunRecorder
from bench.run_state import RunState
from bench.sequencer.control import AbortRequested, Interruption, RunControl, SequencerConfig, WindowSpoiled
from bench.sequencer.daq import DaqPump, Failed, Gap, Restarted
from bench.sequencer.deadline import call_with_deadline
from bench.sequencer.observers import Observers
from bench.sequencer.outcome import RUN_FAULTS, Acquisition, Ending
from bench.sequencer.progress import RemainingTime, run_progress
from bench.sequencer.safety import make_safe, prepare_table
from bench.sequencer.steps import execute_steps
from bench.sequencer.window import WindowCollector
from drivers.base import Daq, RotaryTable, SampleBlock
from drivers.errors import DataGap, DeviceError, DeviceTimeout

T = TypeVar("T")


class Sequencer:
    """Executes one run (see the module docstring).

    :param start_window: first window to record (a resumed run), 0 for a fresh run.
    :param dwell: the dwell choice, if known before the run (Allan, fixed, or stored by
        the interrupted run); otherwise a noise window of the procedure decides it.
    """

    def __init__(
        self,
        table: RotaryTable,
        daq: Daq,
        procedure: Procedure,
        recorder: RunRecorder,
        start: RunStart,
        observers: Sequence[RunObserver] = (),
        control: RunControl | None = None,
        config: SequencerConfig | None = None,
        dwell: DwellChoice | None = None,
        start_window: int = 0,
    ) -> None:
        self.table, self.daq, self.procedure, self.recorder = table, daq, procedure, recorder
        self.start, self._observers = start, Observers(observers)
        self.control = control or RunControl()
        self.config = config or SequencerConfig()
        self.dwell = dwell
        self.start_window = start_window
        self.next_window = start_window
        self.state = RunState.QUEUED
        self.window: WindowCollector | None = None
        self.now_s = recorder.last_t_s or 0.0
        self.held_s = recorder.held_s[-1] if recorder.held_s else 0.0  # a resumed run's holds so far
        self.hold_began_s: float | None = None
        self.eta = RemainingTime(
            procedure,
            self.config.limits,
            start_window,
            self.now_s - self.held_s,
            dwell.dwell_s if dwell else None,
            daq.sample_rate_hz,
        )
        self.eta.windows_kept(
            [
                (w.index, w.end_s - held, w.end_s - w.start_s)
                for w, held in zip(recorder.windows, recorder.held_s, strict=True)
            ]
        )
        self._eta_dwell_s = dwell.dwell_s if dwell else None
        self.step_index = 0
        self.where = "start"
        self.last_temp_c = float("nan")
        self.positions_deg: tuple[float, ...] = (0.0,) * table.n_axes
        self._pump = DaqPump(
            daq,
            self.config.block_max_samples,
            self.config.read_timeout_s,
            idle_wait_s=self.config.daq_idle_wait_s,
        )
        self._last_sample_wall = time.monotonic()
        self._last_status_wall = 0.0
        self._last_progress_wall = 0.0
        self._in_call = False
        self._holding = False
        self._daq_latches_table = False
        self._gaps = 0
        self._daq_epoch = 0
        self.safe_faults: list[BaseException] = []

    # -- observers -----------------------------------------------------------------------

    def notify(self, method: str, *args: object) -> None:
        """Call ``method`` on every observer; an exception becomes :class:`ObserverError`."""
        self._observers.notify(method, *args)

    def set_state(self, state: RunState, reason: str = "") -> None:
        """Change state and tell the observers."""
        self.state = state
        self.notify("on_state", self.start.run_id, StateChange(state, reason))

    def progress(self, force: bool = False) -> None:
        """Emit a progress event (at most every ``progress_interval_s``)."""
        now = time.monotonic()
        if not force and now - self._last_progress_wall < self.config.progress_interval_s:
            return
        self._last_progress_wall = now
        holding_s = 0.0 if self.hold_began_s is None else max(0.0, self.now_s - self.hold_began_s)
        held_s = self.held_s + holding_s
        if self.dwell is not None and self.dwell.dwell_s != self._eta_dwell_s:
            self._eta_dwell_s = self.dwell.dwell_s
            self.eta.set_dwell(self._eta_dwell_s)
        self.notify(
            "on_progress",
            self.start.run_id,
            run_progress(
                self.procedure,
                self.step_index,
                self.window.index if self.window else None,
                self.next_window,
                self.now_s,
                self.eta.remaining_s(self.now_s - held_s),
                self.positions_deg,
                self.state,
                held_s,
                self.eta.done_fraction(self.now_s - held_s),
            ),
        )

    # -- the sample loop -----------------------------------------------------------------

    def pump_once(self, wait_s: float = 0.05) -> None:
        """Handle at most one DAQ item; check abort, pause, stall, interlock."""
        if self.control.abort_requested:
            raise AbortRequested(self.control.abort_reason)
        if self.control.pause_requested and not (self._holding or self._in_call):
            raise Interruption(RunState.PAUSED, "operator pause")
        item = self._pump.next_item(wait_s, self.config.block_max_samples)
        if item is None and time.monotonic() - self._last_sample_wall > self.config.stall_timeout_s:
            gaps = f" ({self._gaps} sample gaps reported meanwhile)" if self._gaps else ""
            raise DeviceTimeout(f"no DAQ samples for {self.config.stall_timeout_s:g} s{gaps}")
        if isinstance(item, Failed):
            raise item.error
        if isinstance(item, Restarted):
            self._record_restart(item)
        elif isinstance(item, Gap):
            self._gaps += 1
            self._record_gap(item.error)
        elif item is not None:
            self._handle_block(item)
        if (
            not (self._in_call or self._holding)
            and time.monotonic() - self._last_status_wall > self.config.status_poll_s
        ):
            self.check_table()
        self.progress()

    def _record_gap(self, err: DataGap) -> None:
        """Record the gap where it happened; a window it falls in is spoiled (re-measured)."""
        w = self.window
        gap = self.recorder.record_gap(
            first_lost_seq=err.expected_seq,
            n_lost=err.n_lost,
            cause=err.cause or "unknown",
            window_index=w.index if w else None,
            window_label=w.label if w else "",
            action="window re-measured" if w else "between windows",
            daq_epoch=self._daq_epoch,
        )
        self._observers.gap(self.start.run_id, gap)
        if w is not None:
            raise WindowSpoiled(str(err))

    def _record_restart(self, item: Restarted) -> None:
        """The DAQ was restarted: record the samples it left unread and re-base the clock."""
        gap = self.recorder.record_gap(
            first_lost_seq=item.next_seq,
            n_lost=item.unread,
            cause="restart",
            window_index=None,
            window_label="",
            action="between windows",
            daq_epoch=self._daq_epoch,
            restart=True,
        )
        self._daq_epoch += 1
        self._observers.gap(self.start.run_id, gap)

    def _handle_block(self, block: SampleBlock) -> None:
        self._last_sample_wall = time.monotonic()
        t = self.recorder.to_recording_time(np.asarray(block.t_s, dtype=float))
        if block.table_deg is not None:
            table = np.asarray(block.table_deg, dtype=float)
            self.positions_deg = tuple(float(v) for v in table[-1])
            self._daq_latches_table = True
        else:
            table = np.tile(np.asarray(self.positions_deg, dtype=float), (block.n, 1))
        temp = np.asarray(block.temp_c, dtype=float)
        chunk = self.recorder.append(
            t,
            block.accel,
            table,
            temp if self.recorder.writer.has_temp else None,
            self.window.index if self.window else None,
        )
        if chunk is not None:
            self.notify("on_chunk", self.start.run_id, chunk)
        self.now_s = float(t[-1])
        if self.window is not None:
            self.window.add(t, block.accel, table, temp)
        self._observers.samples(self.start.run_id, t, block.accel, table)  # recorded first
        finite = temp[np.isfinite(temp)]
        if finite.size:
            self.last_temp_c = float(finite.mean())
            band = self.config.temp_band_c
            if band is not None and not band[0] <= self.last_temp_c <= band[1] and not self._holding:
                raise Interruption(RunState.SUSPENDED, self.temperature_reason())

    def temperature_reason(self) -> str:
        """Why the temperature suspends the run."""
        lo, hi = self.config.temp_band_c or (float("-inf"), float("inf"))
        return f"sensor temperature {self.last_temp_c:.2f} °C outside its band [{lo:g}, {hi:g}] °C"

    def check_table(self) -> None:
        """Poll the table: an open interlock or E-stop suspends the run."""
        self._last_status_wall = time.monotonic()
        st = self.table.status()
        if not self._daq_latches_table:
            self.positions_deg = tuple(a.position_deg for a in st.axes)
        if st.estop or not st.interlock_ok:
            raise Interruption(RunState.SUSPENDED, "emergency stop pressed" if st.estop else "interlock open")
        faults = [f"axis {i + 1}: {a.fault}" for i, a in enumerate(st.axes) if a.fault]
        if faults:
            raise DeviceError("table fault: " + "; ".join(faults))

    def wait_data(self, duration_s: float) -> None:
        """Keep recording for ``duration_s`` on the recording clock."""
        target = self.now_s + duration_s
        while self.now_s < target:
            self.pump_once()

    def call(self, fn: Callable[[], T], deadline_s: float, what: str) -> T:
        """Run a blocking table call in a helper thread, draining the DAQ until it returns.

        :raises DeviceTimeout: it did not return within ``deadline_s`` (wall clock).
        """
        self._in_call = True
        try:
            return call_with_deadline(fn, deadline_s, what, wait=lambda: self.pump_once(0.01))
        finally:
            self._in_call = False

    @contextmanager
    def holding(self) -> Iterator[None]:
        """While held (the table stopped for an interruption, or the run ending), the loop
        raises no pause, interlock or temperature interruption."""
        before = self._holding
        self._holding = True
        try:
            yield
        finally:
            self._holding = before

    def status_due(self) -> bool:
        """Whether ``status_poll_s`` has passed since the last table poll; marks it polled if so."""
        if time.monotonic() - self._last_status_wall < self.config.status_poll_s:
            return False
        self._last_status_wall = time.monotonic()
        return True

    def poll_status_soon(self) -> None:
        """Make the next :meth:`status_due` (and the loop's own poll) happen now."""
        self._last_status_wall = 0.0

    def finish_acquisition(self) -> list[str]:
        """Stop the DAQ pump and put the samples still queued into the recording.

        :returns: what failed (the pump did not stop in time, a block could not be saved).
        """
        problems: list[str] = []
        pump_problem = self._pump.stop(self.config.stop_timeout_s)
        if pump_problem:
            problems.append(pump_problem)
        # Samples still queued belong to the recording too, and so do the gaps between them;
        # after a failed write the recording is cut at its last durable chunk and takes no more.
        self.window = None
        with self.holding():
            for item in self._pump.drain() if self.recorder.failed is None else ():
                try:
                    if isinstance(item, Restarted):
                        self._record_restart(item)
                    elif isinstance(item, Gap):
                        self._record_gap(item.error)
                    elif isinstance(item, SampleBlock):
                        self._handle_block(item)
                except Exception as exc:
                    problems.append(f"saving the last samples failed: {exc}")
                    break
        return problems

    def record_window(self, collector: WindowCollector) -> WindowRecord:
        """Record a window to its end, close it in the recording, tell the observers."""
        self.window = collector
        try:
            while not collector.full:
                self.pump_once()
        finally:
            self.window = None
        rec = collector.record()
        chunk = self.recorder.close_window(rec, self.held_s)
        if chunk is not None:
            self.notify("on_chunk", self.start.run_id, chunk)
        self.notify("on_window", self.start.run_id, rec)
        self.next_window = rec.index + 1
        self.eta.window_done(rec.index, self.now_s - self.held_s, rec.end_s - rec.start_s)
        return rec

    # -- life cycle ----------------------------------------------------------------------

    def run(self) -> Acquisition:
        """Execute the procedure; never raises for device faults (they become ERROR)."""
        ending = Ending()
        try:
            self.notify("on_start", self.start)
            prepare_table(self)
            self._pump.start()
            self._last_sample_wall = time.monotonic()
            self.set_state(
                RunState.RUNNING,
                "resumed from window " + str(self.start_window) if self.start_window else "started",
            )
            execute_steps(self)
            aborted = self.control.enter_finishing()
            if aborted is not None:
                self.where = "the end of the last step"
                raise AbortRequested(aborted)
        except AbortRequested as exc:
            ending = Ending.aborted(self.where, exc)
        except RUN_FAULTS as exc:
            ending = Ending.fault(self.where, exc)
        finally:
            problems = make_safe(self)
        stop_error = self._pump.stop_error
        ending = ending.after_safe_state(problems, [*self.safe_faults, *([stop_error] if stop_error else [])])
        return Acquisition(
            ending.outcome,
            ending.error,
            tuple(self.recorder.windows),
            self.dwell,
            self.recorder.n_rows,
            tuple(self.recorder.gaps),
            ending.resumable,
        )
