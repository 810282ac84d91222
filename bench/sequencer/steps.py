"""Executing the steps of a procedure, with suspension and re-recording of spoiled windows.

``execute_steps`` walks the procedure from the sequencer's ``start_window`` (0, or the
window after the last complete one of a resumed run). A step that records a window is
re-executed after any interruption, preceded by the last :class:`MoveTo` before it, so the
table is where the window expects it; windows already complete are never recorded twice.
"""

from __future__ import annotations

import contextlib
import functools
import math
import time

from bench.dwell_policy import dwell_from_noise_window
from bench.procedures.preview import move_time_s
from bench.procedures.steps import Dwell, MoveTo, NoiseWindow, Oscillate, Rotate, Step
from bench.run_state import RunState
from bench.sequencer.context import RunContext
from bench.sequencer.control import Interruption, WindowSpoiled
from bench.sequencer.safety import optional_table_method
from bench.sequencer.window import WindowCollector
from drivers.errors import DeviceError, DeviceTimeout, InterlockOpen


def execute_steps(seq: RunContext) -> None:
    """Run every remaining step of ``seq.procedure`` (see the module docstring)."""
    proc = seq.procedure
    i, pending_move = proc.resume_plan(seq.start_window)
    retries = 0
    while i < len(proc.steps):
        try:
            if pending_move is not None:
                run_step(seq, pending_move)
                pending_move = None
            run_step(seq, i)
            i += 1
            retries = 0
        except (Interruption, WindowSpoiled, InterlockOpen) as exc:
            seq.window = None
            if isinstance(exc, WindowSpoiled):
                retries += 1
                if retries > seq.config.max_window_retries:
                    limit = seq.config.max_window_retries
                    raise DeviceError(
                        f"window rejected: DAQ lost samples in the same window {retries} times "
                        f"(re-measured at most {limit} times): {exc}"
                    ) from exc
            else:
                hold(
                    seq,
                    exc
                    if isinstance(exc, Interruption)
                    else Interruption(RunState.SUSPENDED, f"interlock open: {exc}"),
                )
            i, pending_move = restart_point(seq, i)
    seq.step_index = len(proc.steps) - 1
    seq.progress(force=True)


def restart_point(seq: RunContext, i: int) -> tuple[int, int | None]:
    """Step to re-execute after step ``i`` was interrupted, and the move to do first."""
    steps = seq.procedure.steps
    if isinstance(steps[i], MoveTo):
        return i, None
    move = next((k for k in range(i - 1, -1, -1) if isinstance(steps[k], MoveTo)), None)
    return i, move


def hold(seq: RunContext, intr: Interruption) -> None:
    """Hold the table until the interruption clears (or abort, or the suspension deadline)."""
    with seq.holding():
        seq.control.take_resume_request()  # only a request made during this hold counts
        seq.set_state(intr.state, intr.reason)
        # An open interlock has already stopped the table; a failed stop is not news then.
        with contextlib.suppress(DeviceError, DeviceTimeout, InterlockOpen, OSError):
            seq.call(seq.table.stop, seq.config.stop_timeout_s, "stop")
        begun = time.monotonic()
        seq.hold_began_s = seq.now_s
        limit = seq.config.suspend_timeout_s
        try:
            while not _cleared(seq, intr):
                if limit is not None and time.monotonic() - begun > limit:
                    raise DeviceError(f"suspended for more than {limit:g} s ({intr.reason})")
                if intr.state is RunState.SUSPENDED and seq.control.take_resume_request():
                    _operator_resume(seq, intr)
                seq.pump_once(0.05)
        finally:
            seq.held_s += max(0.0, seq.now_s - seq.hold_began_s)
            seq.hold_began_s = None
        seq.set_state(RunState.RUNNING, f"resumed after: {intr.reason}")


def _operator_resume(seq: RunContext, intr: Interruption) -> None:
    """Prepare the table again (reset faults, close the interlocks); a refusal keeps the run
    suspended and says why."""
    prepare = optional_table_method(seq.table, "prepare")
    if prepare is None:
        return
    timeout = seq.config.move_timeout_margin_s
    try:
        seq.call(lambda: prepare(timeout), timeout + seq.config.stop_timeout_s, "prepare")
    except (DeviceError, DeviceTimeout, InterlockOpen, OSError) as exc:
        seq.set_state(RunState.SUSPENDED, f"{intr.reason}; resume refused: {type(exc).__name__}: {exc}")
        return
    seq.poll_status_soon()  # check the interlock now


def _cleared(seq: RunContext, intr: Interruption) -> bool:
    if intr.state is RunState.PAUSED:
        return not seq.control.pause_requested
    if not seq.status_due():
        return False
    st = seq.table.status()
    band = seq.config.temp_band_c
    temp_ok = band is None or not math.isfinite(seq.last_temp_c) or band[0] <= seq.last_temp_c <= band[1]
    return st.interlock_ok and not st.estop and temp_ok and not seq.control.pause_requested


def run_step(seq: RunContext, i: int) -> None:
    """Execute step ``i``."""
    step: Step = seq.procedure.steps[i]
    seq.step_index = i
    seq.where = f"step {i} ({type(step).__name__} {getattr(step, 'label', '')})"
    fs = seq.daq.sample_rate_hz
    if isinstance(step, MoveTo):
        _move(seq, step)
        return
    index = seq.next_window
    pose = seq.positions_deg
    if isinstance(step, NoiseWindow):
        col = WindowCollector(
            index, step.label, step.kind, round(step.duration_s * fs), pose, i, keep_samples=True
        )
        seq.record_window(col)
        choice = dwell_from_noise_window(col.samples(), fs)
        seq.dwell = choice
        seq.recorder.record_dwell(choice)
        seq.notify("on_dwell", seq.start.run_id, choice)
    elif isinstance(step, Dwell):
        duration = step.duration_s
        if duration is None:
            if seq.dwell is None:
                raise ValueError(f"{seq.where}: no dwell time chosen (no Allan result, no noise window)")
            duration = seq.dwell.dwell_s
        seq.record_window(WindowCollector(index, step.label, step.kind, round(duration * fs), pose, i))
    elif isinstance(step, Rotate):
        seq.call(
            lambda: seq.table.start_rate(step.axis, step.rate_deg_s), seq.config.stop_timeout_s, "start_rate"
        )
        seq.wait_data(step.spinup_s)
        seq.record_window(WindowCollector(index, step.label, step.kind, round(step.duration_s * fs), pose, i))
        _stop_and_settle(seq)
    elif isinstance(step, Oscillate):
        for axis, amp, period in zip(step.axes, step.amplitudes_deg, step.periods_s, strict=True):
            seq.call(
                functools.partial(seq.table.start_oscillation, axis, amp, period),
                seq.config.stop_timeout_s,
                "start_oscillation",
            )
        seq.record_window(WindowCollector(index, step.label, step.kind, round(step.duration_s * fs), pose, i))
        _stop_and_settle(seq)


def _move(seq: RunContext, step: MoveTo) -> None:
    lim = seq.config.limits
    here = seq.positions_deg
    est = max(
        (
            move_time_s(
                abs(((b - a + 180.0) % 360.0) - 180.0) if lim.continuous[k] else abs(b - a),
                lim.max_rate_deg_s[k],
                lim.max_acc_deg_s2[k],
            )
            for k, (a, b) in enumerate(zip(here, step.angles_deg, strict=False))
        ),
        default=0.0,
    )
    timeout = seq.config.move_timeout_factor * est + seq.config.move_timeout_margin_s
    seq.call(
        lambda: seq.table.move_to(step.angles_deg, timeout), timeout + seq.config.stop_timeout_s, "move_to"
    )
    seq.check_table()
    _wait_until_at(seq, step.angles_deg, timeout)
    seq.wait_data(step.settle_s)


def _wait_until_at(seq: RunContext, target_deg: tuple[float, ...], timeout_s: float) -> None:
    """Drain samples until the encoder angles they carry are at ``target_deg``.

    Blocks queued while the move ran show the table still moving; the settling time counts
    from the first sample at the target, not from when ``move_to`` returned.
    """
    tol = seq.config.in_position_tol_deg
    end = time.monotonic() + timeout_s

    def off_deg() -> float:
        pairs = zip(seq.positions_deg, target_deg, strict=False)
        return max((abs((p - t + 180.0) % 360.0 - 180.0) for p, t in pairs), default=0.0)

    while off_deg() > tol:
        if time.monotonic() > end:
            raise DeviceTimeout(
                f"table reported in position but the encoders read {seq.positions_deg} deg, "
                f"not {target_deg} deg"
            )
        seq.pump_once()


def _stop_and_settle(seq: RunContext) -> None:
    """Stop the motion and wait (recording) until every axis is at rest."""
    seq.call(seq.table.stop, seq.config.stop_timeout_s, "stop")
    lim = seq.config.limits
    decel_s = max(r / a for r, a in zip(lim.max_rate_deg_s, lim.max_acc_deg_s2, strict=True))
    end = time.monotonic() + seq.config.move_timeout_factor * decel_s + seq.config.move_timeout_margin_s
    while True:
        rates = seq.call(seq.table.rates_deg_s, seq.config.stop_timeout_s, "rates_deg_s")
        if max((abs(r) for r in rates), default=0.0) < seq.config.rest_rate_deg_s:
            return
        if time.monotonic() > end:
            raise DeviceTimeout(f"table still turning ({rates} deg/s) after stop")
        seq.pump_once(0.05)
