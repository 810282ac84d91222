"""The incremental run recorder: chunks, windows, crash cut and resume."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from bench.recording.model import Sidecar, TableAxis, TableGeometry
from bench.recording.reader import read_recording
from bench.records import WindowKind, WindowRecord
from bench.run_recorder import RunRecorder

FS = 100.0


def sidecar() -> Sidecar:
    axes = (
        TableAxis("outer", (0.0, 0.0, 1.0)),
        TableAxis("middle", (1.0, 0.0, 0.0)),
        TableAxis("inner", (0.0, 0.0, 1.0)),
    )
    return Sidecar("SN-R", "V", FS, 9.81, procedure="static-12", table=TableGeometry(axes))


def block(rec: RunRecorder, t0: float, n: int, window: int | None) -> object:
    t = t0 + np.arange(n) / FS
    return rec.append(t, np.full((n, 3), 1.5), np.zeros((n, 3)), np.full(n, 25.0), window)


def window(index: int, start_s: float, end_s: float, n: int) -> WindowRecord:
    return WindowRecord(
        index,
        f"pos{index + 1:02d}",
        WindowKind.STATIC,
        start_s,
        end_s,
        n,
        (0.0, 0.0, 0.0),
        (0.0, 0.0, 0.0),
        25.0,
        2 * index + 1,
        {"ax": 1.5},
    )


def test_chunks_tile_the_file_and_windows_become_segments(tmp_path: Path) -> None:
    rec = RunRecorder.create(
        tmp_path / "r.csv", sidecar(), True, {"run_id": "x"}, chunk_s=1.0, min_chunk_wall_s=0.0
    )
    chunks = [c for i in range(5) if (c := block(rec, i * 0.5, 50, 0)) is not None]
    # A chunk closes once it spans a second of data: after the third block (t 0 .. 1.49 s).
    assert [(c.seq, c.first_sample, c.n_samples) for c in chunks] == [(0, 0, 150)]
    tail = rec.close_window(window(0, 0.0, 2.49, 250))  # flushes the rest with the window
    assert tail is not None and (tail.seq, tail.first_sample, tail.n_samples) == (1, 150, 100)
    assert tail.end_byte == (tmp_path / "r.csv").stat().st_size
    rec.close()
    out = read_recording(tmp_path / "r.csv")
    assert out.n_samples == 250 and [s.label for s in out.sidecar.segments or ()] == ["pos01"]
    assert out.sidecar.extra["calbench_windows"][0]["kind"] == "static"  # type: ignore[index]


def test_resume_cuts_at_the_durable_chunk_and_continues_the_clock(tmp_path: Path) -> None:
    path = tmp_path / "r.csv"
    rec = RunRecorder.create(path, sidecar(), True, {"run_id": "x"}, chunk_s=1.0, min_chunk_wall_s=0.0)
    block(rec, 0.0, 100, 0)
    c0 = rec.close_window(window(0, 0.0, 0.99, 100))
    assert c0 is not None
    block(rec, 1.0, 100, 1)
    rec.close_window(window(1, 1.0, 1.99, 100))  # on disk, but the database never heard of it
    block(rec, 2.0, 30, None)
    rec.writer.flush()
    with path.open("ab") as f:
        f.write(b"2.3,1.5,1.5")  # a torn line from the crash
    resumed = RunRecorder.resume(path, c0.end_byte, next_window=1, chunk_seq=c0.seq + 1)
    assert resumed.n_rows == 100 and resumed.windows == [window(0, 0.0, 0.99, 100)]
    t = resumed.to_recording_time(np.array([0.0, 0.01]))
    assert t[0] == pytest.approx(0.99 + 1 / FS)
    resumed.append(t, np.full((2, 3), 1.5), np.zeros((2, 3)), np.full(2, 25.0), 1)
    resumed.close()
    out = read_recording(path)
    assert out.n_samples == 102 and len(out.sidecar.segments or ()) == 1
    assert np.all(np.diff(out.t_s) > 0)


def test_resume_refuses_a_window_the_files_do_not_hold(tmp_path: Path) -> None:
    path = tmp_path / "r.csv"
    rec = RunRecorder.create(path, sidecar(), True, {}, chunk_s=1.0, min_chunk_wall_s=0.0)
    block(rec, 0.0, 10, None)
    rec.close()
    with pytest.raises(ValueError, match="cannot resume at window 3"):
        RunRecorder.resume(path, None, next_window=3, chunk_seq=1)


@pytest.mark.parametrize(
    ("key", "value", "message"),
    [
        ("calbench_windows", {"0": {}}, "'calbench_windows' is not a list"),
        ("calbench_run", [["run_id", "x"]], "'calbench_run' is not an object"),
    ],
)
def test_resume_names_a_sidecar_entry_of_the_wrong_json_type(
    tmp_path: Path, key: str, value: object, message: str
) -> None:
    path = tmp_path / "r.csv"
    rec = RunRecorder.create(path, sidecar(), True, {"run_id": "x"}, chunk_s=1.0, min_chunk_wall_s=0.0)
    block(rec, 0.0, 10, None)
    rec.close()
    sidecar_path = rec.writer.sidecar_path
    doc = json.loads(sidecar_path.read_text())
    doc[key] = value
    sidecar_path.write_text(json.dumps(doc))
    with pytest.raises(ValueError, match=message) as err:
        _ = RunRecorder.resume(path, None, next_window=0, chunk_seq=1).run_meta
    assert str(path) in str(err.value)


@pytest.mark.parametrize("where", ["flush", "write"])
def test_a_full_disk_cuts_the_recording_at_the_last_durable_chunk(tmp_path: Path, where: str) -> None:
    """ENOSPC while a chunk is flushed (the rows reached the file, fsync failed) or while rows
    are written: the error names the file and what was kept, the CSV ends exactly at the last
    durable chunk (no torn row), and the recorder refuses to write on."""
    import errno
    import os

    path = tmp_path / "r.csv"
    rec = RunRecorder.create(path, sidecar(), True, {"run_id": "x"}, chunk_s=1.0, min_chunk_wall_s=0.0)
    block(rec, 0.0, 100, 0)
    durable = rec.close_window(window(0, 0.0, 0.99, 100))
    assert durable is not None and durable.end_byte == path.stat().st_size
    block(rec, 1.0, 60, 1)  # buffered, not yet durable

    def full(*_: object) -> None:
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    if where == "flush":
        rec.writer.flush = lambda: (rec.writer._file.flush(), full())  # type: ignore[method-assign]
        kept = r"No space left on device.*cut at its last durable chunk \(100 rows"
        with pytest.raises(OSError, match=kept):
            rec.close_window(window(1, 1.0, 1.59, 60))
    else:
        real = rec.writer._file

        class HalfWritten:
            """Half of the next rows reach the file (a torn row), then the disk is full."""

            def write(self, text: str) -> int:
                real.write(text[: len(text) // 2])
                real.flush()
                full()
                return 0

            def __getattr__(self, name: str) -> object:
                return getattr(real, name)

        rec.writer._file = HalfWritten()  # type: ignore[assignment]
        real.flush()  # the buffered rows reach the file (not fsynced: not durable)
        assert path.stat().st_size > durable.end_byte  # the buffered rows are on disk, not durable
        with pytest.raises(OSError, match="No space left on device") as info:
            block(rec, 1.6, 10, 1)
        assert info.value.errno == errno.ENOSPC
    assert path.stat().st_size == durable.end_byte
    assert rec.n_rows == 100 and rec.failed is not None
    with pytest.raises(OSError, match=r"failed earlier.*nothing more is written"):
        block(rec, 3.0, 10, 1)
    assert rec.close() is None
    out = read_recording(path)
    assert out.n_samples == 100 and out.t_s[-1] == pytest.approx(0.99)
    assert [s.label for s in out.sidecar.segments or ()] == ["pos01"]
