"""The live view's hook: every block reaches it after it is recorded, and a view that fails
costs the run nothing (before, there was no view of the signal at all)."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from bench.recording.reader import read_recording
from bench.run_observer import NullObserver
from tests.bench.sequencer.test_sequencer import FakeDaq, FakeTable, make, quick_static


class Viewer(NullObserver):
    def __init__(self, fail_after: int | None = None) -> None:
        self.t: list[np.ndarray] = []
        self.table: list[np.ndarray] = []
        self.fail_after = fail_after

    def on_samples(self, run_id: str, t_s: np.ndarray, accel: np.ndarray, table_deg: np.ndarray) -> None:
        if self.fail_after is not None and len(self.t) >= self.fail_after:
            raise RuntimeError("the view's socket closed")
        assert accel.shape == (len(t_s), 3) and table_deg.shape == (len(t_s), 3)
        self.t.append(np.array(t_s))
        self.table.append(np.array(table_deg))


def test_the_view_sees_every_recorded_sample_and_a_failing_view_costs_none(tmp_path: Path) -> None:
    table = FakeTable()
    seq, _table, _daq, obs, _ctl = make(tmp_path, quick_static(), table=table, daq=FakeDaq(table))
    good, bad = Viewer(), Viewer(fail_after=3)
    seq._observers = type(seq._observers)([obs, bad, good])
    acq = seq.run()
    assert acq.outcome is None, acq.error
    rec = read_recording(tmp_path / "run.csv")
    assert len(acq.windows) == 12 and acq.n_samples == len(rec.t_s)
    seen = np.concatenate(good.t)
    np.testing.assert_array_equal(seen, rec.t_s)  # the same samples, in order, none missing
    assert rec.table_deg is not None
    np.testing.assert_allclose(np.concatenate(good.table), rec.table_deg, atol=1e-6)
    assert len(bad.t) == 3  # told no more after it failed; the run went on
