"""A database that refuses the run's writes: because its disk is full (SQLite's own ``database
or disk is full``, produced here by a real SQLite at its page limit) the run ends as a device
fault — resumable, the recording cut at its last durable chunk; for any other reason (a lock
never released, a constraint) it ends ERROR for good, as before."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest
import sqlalchemy as sa

from bench.records import RunStart, StateChange, WindowRecord
from bench.run_observer import NullObserver
from bench.run_recorder import RunRecorder
from bench.run_state import Outcome, RunState
from bench.sequencer.control import RunControl
from bench.sequencer.faults import is_disk_full, resumable_fault
from bench.sequencer.loop import Sequencer
from bench.sequencer.observers import ObserverError, Observers
from tests.bench.sequencer.test_sequencer import FAST, FS, FakeDaq, FakeTable, Recorder, quick_static, sidecar

pytestmark = pytest.mark.timeout(120)


def sqlite_refusal(tmp_path: Path, kind: str) -> Exception:
    """A real refusal of SQLite through SQLAlchemy: ``full`` (the file may not grow: SQLITE_FULL,
    what a full disk gives), ``locked`` (another connection holds the write lock) or
    ``constraint`` (a UNIQUE key twice)."""
    db = tmp_path / f"{kind}.db"
    engine = sa.create_engine(f"sqlite:///{db}", connect_args={"timeout": 0.0})
    with engine.begin() as c:
        c.exec_driver_sql("CREATE TABLE t (k INTEGER PRIMARY KEY, x BLOB)")
        c.exec_driver_sql("INSERT INTO t VALUES (1, zeroblob(10))")
    other = sqlite3.connect(db, isolation_level=None)
    try:
        with engine.begin() as c:
            if kind == "full":
                c.exec_driver_sql("PRAGMA max_page_count = 3")
                for k in range(2, 100):
                    c.exec_driver_sql(f"INSERT INTO t VALUES ({k}, zeroblob(4000))")
            elif kind == "locked":
                other.execute("BEGIN EXCLUSIVE")
                c.exec_driver_sql("INSERT INTO t VALUES (2, zeroblob(10))")
            else:
                c.exec_driver_sql("INSERT INTO t VALUES (1, zeroblob(10))")
    except sa.exc.DBAPIError as exc:
        return exc
    finally:
        other.close()
        engine.dispose()
    raise AssertionError(f"SQLite did not refuse ({kind})")


class Refusing(Recorder):
    """The run's database observer refusing every write from window ``at`` on."""

    def __init__(self, exc: Exception, at: int) -> None:
        super().__init__()
        self.exc, self.at, self.refused = exc, at, 0

    def on_window(self, run_id: str, window: WindowRecord) -> None:
        if window.index >= self.at:
            self.refused += 1
            raise self.exc
        super().on_window(run_id, window)


class StateRefusing(NullObserver):
    def __init__(self, exc: Exception) -> None:
        self.exc = exc

    def on_state(self, run_id: str, change: StateChange) -> None:
        raise self.exc


def run_refused(tmp_path: Path, exc: Exception) -> tuple[object, Refusing, Path]:
    proc = quick_static()
    csv = tmp_path / "run.csv"
    obs = Refusing(exc, at=4)
    start = RunStart("run-1", "SN-T1", proc.name, "bench-a", str(csv), FS, 3, proc.n_windows, 100.0)
    rec = RunRecorder.create(csv, sidecar(), True, {"run_id": "run-1"}, chunk_s=1.0, min_chunk_wall_s=0.0)
    table = FakeTable()
    seq = Sequencer(table, FakeDaq(table), proc, rec, start, [obs], RunControl(), FAST)
    return seq.run(), obs, csv


@pytest.mark.parametrize(("kind", "resumable"), [("full", True), ("locked", False), ("constraint", False)])
def test_only_a_full_disk_makes_a_database_refusal_resumable(
    tmp_path: Path, kind: str, resumable: bool
) -> None:
    exc = sqlite_refusal(tmp_path, kind)
    assert ("database or disk is full" in str(exc)) is resumable  # what SQLite said, not our reading
    with pytest.raises(ObserverError) as info:
        Observers([StateRefusing(exc)]).notify("on_state", "r", StateChange(RunState.RUNNING))
    assert is_disk_full(info.value) is resumable
    assert resumable_fault(info.value) is resumable


@pytest.mark.parametrize(("kind", "resumable"), [("full", True), ("locked", False)])
def test_a_run_whose_database_refuses_ends_resumable_only_on_a_full_disk(
    tmp_path: Path, kind: str, resumable: bool
) -> None:
    acq, obs, csv = run_refused(tmp_path, sqlite_refusal(tmp_path, kind))
    assert acq.outcome is Outcome.ERROR and acq.resumable is resumable  # type: ignore[attr-defined]
    assert "observer Refusing.on_window failed" in (acq.error or "")  # type: ignore[attr-defined]
    assert obs.refused == 1 and [w.index for w in obs.windows] == [0, 1, 2, 3]
    # the recording holds every window the sequencer completed, whole to its last chunk
    assert csv.stat().st_size == obs.chunks[-1].end_byte
