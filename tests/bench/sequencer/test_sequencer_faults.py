"""Faults the bench recovers from are marked resumable, also when the link drops while the
table and the DAQ are being made safe after the last step (the recording is whole: a resume at
the window after the last one only makes the bench safe again and lets the run be fitted)."""

from __future__ import annotations

from pathlib import Path

import pytest

from bench.records import RunStart
from bench.run_recorder import RunRecorder
from bench.run_state import Outcome
from bench.sequencer.control import RunControl
from bench.sequencer.loop import Sequencer
from drivers.errors import DeviceError, DeviceTimeout, LinkLost
from tests.bench.sequencer.test_sequencer import FAST, FS, FakeDaq, FakeTable, Recorder, make, quick_static


class DaqLostAtStop(FakeDaq):
    def stop(self) -> None:
        raise LinkLost("DAQ link lost on write HR 410-410: connection reset by peer")


def test_a_link_lost_after_the_last_step_leaves_the_run_resumable_and_a_resume_finishes_it(
    tmp_path: Path,
) -> None:
    table = FakeTable()
    seq, _, _, obs, _ = make(tmp_path, quick_static(), table=table, daq=DaqLostAtStop(table))
    acq = seq.run()
    assert acq.outcome is Outcome.ERROR and acq.resumable, acq.error
    assert acq.error is not None and acq.error.startswith("completed; DAQ stop failed: LinkLost")
    assert len(acq.windows) == 12
    last = obs.chunks[-1]
    rec = RunRecorder.resume(tmp_path / "run.csv", last.end_byte, 12, last.seq + 1)
    proc = quick_static()
    start = RunStart("run-1", "SN-T1", proc.name, "bench-a", str(tmp_path / "run.csv"), FS, 3, 12, 100.0)
    table2 = FakeTable()
    again = Sequencer(
        table2, FakeDaq(table2), proc, rec, start, [Recorder()], RunControl(), FAST, start_window=12
    ).run()
    assert again.outcome is None and not again.resumable, again.error
    assert [w.index for w in again.windows] == list(range(12)) and table2.moves == []


@pytest.mark.parametrize(
    ("fault", "resumable"),
    [
        (DeviceTimeout("no reply within 1 s"), True),
        (LinkLost("port closed"), True),
        (DeviceError("axis 2: following error"), False),
    ],
)
def test_a_fault_mid_run_is_resumable_when_the_link_failed_not_when_the_device_reported_it(
    tmp_path: Path, fault: Exception, resumable: bool
) -> None:
    seq, table, _, obs, _ = make(tmp_path, quick_static())
    obs.hook = lambda w: setattr(table, "fail_move", fault) if w.index == 4 else None
    acq = seq.run()
    assert acq.outcome is Outcome.ERROR and acq.resumable is resumable
    assert table.stops >= 1 and len(acq.windows) == 5
