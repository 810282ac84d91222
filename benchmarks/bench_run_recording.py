"""Sustained recording of a 1 kHz stream by the sequencer, as ratios to real time.

1. Pipeline: a paced synthetic DAQ produces a 1 kHz stream at ×100 real time (100 000
   samples per wall second) into a ring holding 2 s of wall time (as a real DAQ's 2 s buffer
   at real time; 200 s of data at ×100); a reader that falls behind loses samples
   (``DataGap``), so "zero gaps" is the check that the sequencer, the incremental recording
   (flush + fsync per chunk) and the database observer (``db.observer.DbRunObserver`` on
   SQLite, one transaction per chunk and window) keep up. Run with the bench's chunking
   (a chunk per 1 s of data, at most every 0.2 s of wall time) and with a chunk per data
   second whatever the wall time (100 fsync + commit per wall second at ×100). Printed: data
   seconds recorded per wall second (×real time), the gaps, the database writes per wall
   second and per data second, and the most the pipeline sustains (DAQ paced at ×1000).
2. Formatting: the CSV text of a block by ``bench.recording.rows.format_block`` (one ``%``
   over a row template) against the ``csv`` module (the previous writer), same bytes.
3. Real drivers: the simulated bench at 1 kHz over Modbus TCP and the table's text protocol,
   at several simulation speeds; printed: the speed actually sustained and the gaps. The DAQ
   register map moves at most 120 samples per window in reads of 125 registers (≈0.4 ms per
   round trip on loopback): about 20 000 samples/s, i.e. ×20 at 1 kHz, whatever the
   pipeline behind it can take (docs/daq-registers.md).
"""

from __future__ import annotations

import csv
import io
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.procedures.steps import Dwell, MoveTo, Procedure
from bench.recording.model import Sidecar, TableAxis, TableGeometry
from bench.recording.rows import format_block
from bench.recording.writer import RecordingWriter
from bench.records import ChunkRecord, RunStart
from bench.run_observer import NullObserver
from bench.run_recorder import RunRecorder
from bench.sequencer.control import SequencerConfig
from bench.sequencer.loop import Sequencer
from db.engine import make_session_factory
from db.migrate import open_database
from db.observer import DbRunObserver
from drivers.base import AxisMode, AxisStatus, SampleBlock, TableStatus
from drivers.errors import DataGap
from drivers.factory import open_bench
from station.execution.devices import sim_url
from station.settings import Settings

RATE_HZ = 1000.0
SPEED = 100.0
DATA_S = 600.0


class StillTable:
    """A table that is always in position (the benchmark measures the sample path)."""

    n_axes = 3

    def move_to(self, angles_deg: tuple[float, ...], timeout_s: float) -> None:
        pass

    def start_rate(self, axis: int, rate_deg_s: float) -> None:
        pass

    def start_oscillation(self, axis: int, amplitude_deg: float, period_s: float) -> None:
        pass

    def positions_deg(self) -> tuple[float, ...]:
        return (0.0, 0.0, 0.0)

    def rates_deg_s(self) -> tuple[float, ...]:
        return (0.0, 0.0, 0.0)

    def stop(self) -> None:
        pass

    def status(self) -> TableStatus:
        axes = tuple(AxisStatus(0.0, 0.0, AxisMode.POSITION, True) for _ in range(3))
        return TableStatus(axes, True, False)

    def close(self) -> None:
        pass


class PacedDaq:
    """``rate × speed`` samples per wall second; a backlog over ``ring_wall_s`` of wall time is lost."""

    def __init__(self, rate_hz: float, speed: float, ring_wall_s: float = 2.0) -> None:
        self.rate_hz, self.speed, self.ring = rate_hz, speed, int(ring_wall_s * rate_hz * speed)
        self.rng = np.random.default_rng(0)
        self.next_seq = 0
        self.t0 = time.perf_counter()
        self.gaps = 0

    @property
    def sample_rate_hz(self) -> float:
        return self.rate_hz

    @property
    def channel_unit(self) -> str:
        return "V"

    def start(self) -> None:
        self.t0, self.next_seq = time.perf_counter(), 0

    def read_block(self, max_samples: int, timeout_s: float) -> SampleBlock:
        produced = int((time.perf_counter() - self.t0) * self.rate_hz * self.speed)
        if produced - self.next_seq > self.ring:
            expected, self.next_seq = self.next_seq, produced - self.ring
            self.gaps += 1
            raise DataGap(expected, self.next_seq)
        n = min(max_samples, produced - self.next_seq)
        if n <= 0:
            time.sleep(0.001)
            n = 0
        seq = self.next_seq + np.arange(n)
        self.next_seq += n
        return SampleBlock(
            int(seq[0]) if n else self.next_seq,
            seq / self.rate_hz,
            1.5 + 1e-3 * self.rng.standard_normal((n, 3)),
            np.full(n, 25.0),
            np.zeros((n, 3)),
        )

    def stop(self) -> None:
        pass

    def status(self) -> dict[str, object]:
        return {}

    def close(self) -> None:
        pass


class CountChunks(NullObserver):
    def __init__(self) -> None:
        self.chunks = 0

    def on_chunk(self, run_id: str, chunk: ChunkRecord) -> None:
        self.chunks += 1


def sidecar() -> Sidecar:
    axes = (
        TableAxis("outer", (0.0, 0.0, 1.0)),
        TableAxis("middle", (1.0, 0.0, 0.0)),
        TableAxis("inner", (0.0, 0.0, 1.0)),
    )
    return Sidecar("SN-BENCH", "V", RATE_HZ, 9.81, table=TableGeometry(axes))


def writer_baseline(tmp: Path, n: int) -> float:
    """Wall seconds for RecordingWriter.append of n rows in 4096-row blocks, flushing now and then."""
    w = RecordingWriter(tmp / "baseline.csv", sidecar(), 3, True)
    rng = np.random.default_rng(1)
    t0 = time.perf_counter()
    for start in range(0, n, 4096):
        k = min(4096, n - start)
        w.append(
            (start + np.arange(k)) / RATE_HZ,
            1.5 + 1e-3 * rng.standard_normal((k, 3)),
            np.zeros((k, 3)),
            np.full(k, 25.0),
        )
        if (start // 4096) % 25 == 0:
            w.flush()
    w.close()
    return time.perf_counter() - t0


def pipeline(tmp: Path, speed: float, min_chunk_wall_s: float, data_s: float = DATA_S) -> tuple[float, int]:
    """Run the pipeline on a DAQ paced at ``speed``; print and return (×real time, gaps)."""
    engine = open_database(f"sqlite:///{tmp / 'bench.db'}")
    sessions = make_session_factory(engine)
    run_id = "bench-run"
    proc = Procedure("bench", (MoveTo((0.0, 0.0, 0.0), "p", settle_s=0.0), Dwell("hold", data_s)), {})
    recorder = RunRecorder.create(
        tmp / "run.csv", sidecar(), True, {"run_id": run_id}, chunk_s=1.0, min_chunk_wall_s=min_chunk_wall_s
    )
    daq = PacedDaq(RATE_HZ, speed)
    count = CountChunks()
    start = RunStart(run_id, "SN-BENCH", "bench", "bench", str(tmp / "run.csv"), RATE_HZ, 3, 1, data_s)
    seq = Sequencer(
        StillTable(),
        daq,
        proc,
        recorder,
        start,
        [DbRunObserver(sessions), count],
        None,
        SequencerConfig(block_max_samples=8192),
    )
    t0 = time.perf_counter()
    acq = seq.run()
    wall = time.perf_counter() - t0
    engine.dispose()
    recorded_s = acq.n_samples / RATE_HZ
    sustained = recorded_s / wall
    outcome = acq.outcome.value if acq.outcome else "completed"
    print(
        f"  DAQ paced at x{speed:g}, chunks every >= {min_chunk_wall_s:g} s wall: {acq.n_samples} samples "
        f"({recorded_s:.0f} s of data) in {wall:.2f} s wall = x{sustained:.1f} real time "
        f"(sustained/required {sustained / speed:.2f}); DAQ gaps {daq.gaps}; outcome {outcome}"
    )
    print(
        f"    database: {count.chunks} chunk rows + 1 window = {count.chunks / wall:.1f} writes per "
        f"wall s, {count.chunks / recorded_s:.2f} per data s"
    )
    return sustained, daq.gaps


def formatting(n_rows: int = 200_000) -> None:
    """CSV text of the benchmark's rows: the csv module against format_block (same bytes)."""
    rng = np.random.default_rng(2)
    block = np.column_stack(
        [
            np.arange(n_rows) / RATE_HZ,
            1.5 + 1e-3 * rng.standard_normal((n_rows, 3)),
            rng.uniform(-180.0, 180.0, (n_rows, 3)),
            25.0 + 0.01 * rng.standard_normal(n_rows),
        ]
    )
    times = {}
    for name in ("csv module", "format_block"):
        t0 = time.perf_counter()
        for i in range(0, n_rows, 4096):
            part = block[i : i + 4096]
            if name == "csv module":
                buf = io.StringIO()
                csv.writer(buf, lineterminator="\n").writerows(part.tolist())
                text = buf.getvalue()
            else:
                text = format_block(part)
        times[name] = time.perf_counter() - t0
    assert text == format_block(part)
    base = times["csv module"]
    for name, dt in times.items():
        print(
            f"  {name}: {n_rows / dt / 1e3:.0f} k rows/s (8 full-precision floats per row) = "
            f"x{n_rows / RATE_HZ / dt:.0f} real time at 1 kHz; {base / dt:.2f} x the csv module"
        )


def real_drivers(tmp: Path) -> None:
    settings = Settings(data_dir=tmp, sim_sample_rate_hz=RATE_HZ)
    for speed in (5.0, 20.0, 50.0):
        devices = open_bench(sim_url(settings, speed, 0))
        try:
            steps = (MoveTo((0.0, 0.0, 0.0), "p", settle_s=0.0), Dwell("hold", 10.0 * speed))
            proc = Procedure("bench", steps, {})
            path = tmp / f"real-{speed:g}.csv"
            recorder = RunRecorder.create(path, sidecar(), True, {}, chunk_s=1.0, min_chunk_wall_s=0.2)
            start = RunStart("real", "SN-BENCH", "bench", "bench", str(path), RATE_HZ, 3, 1, 10.0 * speed)
            seq = Sequencer(devices.table, devices.daq, proc, recorder, start, [], None, SequencerConfig())
            t0 = time.perf_counter()
            acq = seq.run()
            wall = time.perf_counter() - t0
            outcome = acq.outcome.value if acq.outcome else "completed"
            why = f" ({acq.error})" if acq.error else ""
            print(
                f"  simulation x{speed:g}: x{acq.n_samples / RATE_HZ / wall:.1f} real time sustained over "
                f"{wall:.1f} s, gaps {seq._gaps} (one per ring overflow), outcome {outcome}{why}"
            )
        finally:
            devices.close()


def main() -> None:
    print("pipeline (sequencer + recording + database), synthetic 1 kHz stream:")
    ok = True
    capacity = 0.0
    for speed, min_wall in ((SPEED, 0.2), (SPEED, 0.0), (1000.0, 0.2)):
        with tempfile.TemporaryDirectory() as d:
            sustained, gaps = pipeline(Path(d), speed, min_wall, DATA_S if speed == SPEED else 3 * DATA_S)
        if speed == SPEED:
            ok = ok and gaps == 0
        else:
            capacity = sustained
    # Wall time includes start-up; the paced ring (2 s of wall time) turns any lasting lag into gaps.
    print(
        f"  x{SPEED:g} sustained with zero gaps: {'yes' if ok else 'NO'}; most the pipeline takes: "
        f"x{capacity:.0f} = {capacity / SPEED:.1f} x the requirement"
    )
    with tempfile.TemporaryDirectory() as d:
        base = writer_baseline(Path(d), 400_000)
    print(f"  RecordingWriter.append alone (4096-row blocks, flush every 25): x{400 / base:.0f} real time")
    print("CSV formatting of a block:")
    formatting()
    print(
        "real drivers (simulated bench over Modbus TCP; the register map caps a reader near "
        "20 000 samples/s, x20 at 1 kHz):"
    )
    with tempfile.TemporaryDirectory() as d:
        real_drivers(Path(d))


if __name__ == "__main__":
    main()
