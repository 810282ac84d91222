"""A run interrupted and resumed: its progress goes on from its last kept window instead of
stepping back (before, a resumed run forgot the pace measured so far and the time held, and
its bar fell from 57 % to 44 % on these devices); the bar is the procedure's place on its
schedule, which grows with the windows done.

The in-test devices of ``test_sequencer`` move the table at once, so the measured pace of
moves is far from the preview's nominal one: the case where forgetting it shows most."""

from __future__ import annotations

import itertools
import threading
from pathlib import Path

import pytest

from bench.records import Progress, RunStart, WindowRecord
from bench.run_recorder import RunRecorder
from bench.sequencer.control import RunControl
from bench.sequencer.loop import Sequencer
from tests.bench.sequencer.test_sequencer import FAST, FS, FakeDaq, FakeTable, Recorder, make, quick_static

CRASH_AFTER = 6


def _crash_and_resume(tmp_path: Path, pause_at: int | None) -> tuple[list[Progress], list[Progress]]:
    """Run static-12 until window CRASH_AFTER (paused once at ``pause_at``), abort as a crash
    would, resume from the last durable chunk in a new Sequencer; both runs' progress events."""
    seq, _table, _, obs, ctl = make(tmp_path, quick_static())

    def hook(w: WindowRecord) -> None:
        if w.index == pause_at:
            ctl.pause()
            threading.Timer(0.3, ctl.resume).start()
        if w.index == CRASH_AFTER:
            ctl.abort("simulated crash")

    obs.hook = hook  # type: ignore[assignment]
    assert len(seq.run().windows) == CRASH_AFTER + 1
    last_chunk = obs.chunks[-1]
    rec = RunRecorder.resume(tmp_path / "run.csv", last_chunk.end_byte, CRASH_AFTER + 1, last_chunk.seq + 1)
    proc = quick_static()
    start = RunStart(
        "run-1", "SN-T1", proc.name, "bench-a", str(tmp_path / "run.csv"), FS, 3, 12, 100.0,
        resumed_from_window=CRASH_AFTER + 1,
    )  # fmt: skip
    table = FakeTable()
    obs2 = Recorder()
    acq = Sequencer(
        table,
        FakeDaq(table, seed=2),
        proc,
        rec,
        start,
        [obs2],
        RunControl(),
        FAST,
        start_window=CRASH_AFTER + 1,
    ).run()
    assert acq.outcome is None and len(acq.windows) == 12
    return obs.progress, obs2.progress


def _shown_before_crash(progress: list[Progress]) -> list[Progress]:
    """What the bar showed up to the end of the last window the resume keeps."""
    return [p for p in progress if p.window_index is not None and p.window_index <= CRASH_AFTER]


@pytest.mark.parametrize("pause_at", [None, 2])
def test_progress_never_steps_back_across_a_resume(tmp_path: Path, pause_at: int | None) -> None:
    before, after = _crash_and_resume(tmp_path, pause_at)
    shown = _shown_before_crash(before)
    assert shown and after
    # within the first process the bar only grows, though the pace is re-measured each window
    assert all(b.fraction >= a.fraction - 1e-9 for a, b in itertools.pairwise(shown))
    fractions = [p.fraction for p in after]
    # the resumed bar starts at or above what the first process showed by its last kept window...
    assert fractions[0] >= shown[-1].fraction - 1e-9, (shown[-1].fraction, fractions[0])
    # ...and only grows from there to the end
    assert all(b >= a - 1e-9 for a, b in itertools.pairwise(fractions))
    assert after[-1].fraction == pytest.approx(1.0, abs=0.02)
    # the time held before the crash stays held: the resumed run counts it as the first did
    held_before = max(p.held_s for p in shown)
    assert (held_before > 0.0) == (pause_at is not None)
    assert after[0].held_s == pytest.approx(held_before, abs=1e-9)
    # the expected end of the working time stays where the first process put it
    work_end_before = shown[-1].expected_total_s - shown[-1].held_s
    work_end_after = after[0].expected_total_s - after[0].held_s
    assert work_end_after == pytest.approx(work_end_before, rel=0.1)
