"""Sustained recording of a 1 kHz stream by the sequencer, as ratios to real time.

1. Pipeline: a paced synthetic DAQ produces a 1 kHz stream at ×100 real time (100 000
   samples per wall second) into a ring holding 2 s of wall time (as a real DAQ's 2 s buffer
   at real time; 200 s of data at ×100); a reader that falls behind loses
   samples (``DataGap``), so "zero gaps" is the check that the sequencer, the incremental
   recording (flush + fsync per chunk) and the database observer (SQLite, one transaction per
   chunk and window) keep up. Printed: data seconds recorded per wall second (×real time), the
   gaps, and the database writes per wall second. Baseline in the same run: the same rows
   written by ``RecordingWriter.append`` alone in a tight loop (the writer's own ceiling).
2. Real drivers: the simulated bench at 1 kHz over Modbus TCP and the table's text protocol,
   at several simulation speeds; printed: the speed actually sustained and the gaps/restarts.
"""

from __future__ import annotations

import tempfile
import time
from pathlib import Path

import numpy as np

from api.bench_session import DbObserver, sim_url
from api.settings import Settings
from bench.procedures.steps import Dwell, MoveTo, Procedure
from bench.recording.model import Sidecar, TableAxis, TableGeometry
from bench.recording.writer import RecordingWriter
from bench.records import ChunkRecord, NullObserver, RunStart
from bench.run_recorder import RunRecorder
from bench.sequencer import Sequencer
from bench.sequencer_control import SequencerConfig
from db.engine import make_session_factory, open_database
from db.repo.runs import create_run
from db.repo.units import get_or_create_unit
from drivers.base import AxisMode, AxisStatus, SampleBlock, TableStatus
from drivers.errors import DataGap
from drivers.factory import open_bench

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
        return SampleBlock(int(seq[0]) if n else self.next_seq, seq / self.rate_hz,
                           1.5 + 1e-3 * self.rng.standard_normal((n, 3)), np.full(n, 25.0), np.zeros((n, 3)))

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
    axes = (TableAxis("outer", (0.0, 0.0, 1.0)), TableAxis("middle", (1.0, 0.0, 0.0)),
            TableAxis("inner", (0.0, 0.0, 1.0)))
    return Sidecar("SN-BENCH", "V", RATE_HZ, 9.81, table=TableGeometry(axes))


def writer_baseline(tmp: Path, n: int) -> float:
    """Wall seconds for RecordingWriter.append of n rows in 4096-row blocks, flushing now and then."""
    w = RecordingWriter(tmp / "baseline.csv", sidecar(), 3, True)
    rng = np.random.default_rng(1)
    t0 = time.perf_counter()
    for start in range(0, n, 4096):
        k = min(4096, n - start)
        w.append((start + np.arange(k)) / RATE_HZ, 1.5 + 1e-3 * rng.standard_normal((k, 3)), np.zeros((k, 3)),
                 np.full(k, 25.0))
        if (start // 4096) % 25 == 0:
            w.flush()
    w.close()
    return time.perf_counter() - t0


def pipeline(tmp: Path, speed: float) -> None:
    engine = open_database(f"sqlite:///{tmp / 'bench.db'}")
    sessions = make_session_factory(engine)
    run_id = "bench-run"
    with sessions.begin() as s:
        unit = get_or_create_unit(s, "SN-BENCH")
        from db.models import RunState as DbRunState

        create_run(s, run_id, unit.id, "bench", state=DbRunState.RUNNING)
    proc = Procedure("bench", (MoveTo((0.0, 0.0, 0.0), "p", settle_s=0.0), Dwell("hold", DATA_S)), {})
    recorder = RunRecorder.create(tmp / "run.csv", sidecar(), True, {"run_id": run_id}, chunk_s=1.0,
                                  min_chunk_wall_s=0.0)
    daq = PacedDaq(RATE_HZ, speed)
    count = CountChunks()
    start = RunStart(run_id, "SN-BENCH", "bench", "bench", str(tmp / "run.csv"), RATE_HZ, 3, 1, DATA_S)
    seq = Sequencer(StillTable(), daq, proc, recorder, start, [DbObserver(sessions), count], None,
                    SequencerConfig(block_max_samples=8192))
    t0 = time.perf_counter()
    acq = seq.run()
    wall = time.perf_counter() - t0
    engine.dispose()
    data_s = acq.n_samples / RATE_HZ
    base = writer_baseline(tmp, acq.n_samples)
    print(f"pipeline: 1 kHz stream paced at x{speed:g}: {acq.n_samples} samples ({data_s:.0f} s of data) "
          f"in {wall:.2f} s wall = x{data_s / wall:.1f} real time; DAQ gaps {daq.gaps}; outcome "
          f"{acq.outcome.value if acq.outcome else 'completed'}")
    # Over a finite run the ring hides a slow reader; keeping up means draining as fast as the DAQ fills.
    keeps_up = daq.gaps == 0 and data_s / wall >= 0.95 * speed
    ratio = data_s / wall / speed
    print(f"  keeps up with x{speed:g}: {'yes' if keeps_up else 'NO'} (sustained/required = {ratio:.2f})")
    print(f"  database: {count.chunks} chunk rows + 1 window in {wall:.2f} s = {count.chunks / wall:.1f} "
          f"writes/s, {count.chunks / data_s:.2f} per data second")
    print(f"  baseline RecordingWriter.append alone: x{data_s / base:.0f} real time; "
          f"pipeline/baseline wall ratio {wall / base:.1f}")


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
            print(f"real drivers at 1 kHz, simulation x{speed:g}: x{acq.n_samples / RATE_HZ / wall:.1f} real "
                  f"time sustained over {wall:.1f} s, gaps {seq._gaps}, outcome {outcome}{why}")
        finally:
            devices.close()


def main() -> None:
    for speed in (50.0, SPEED):
        with tempfile.TemporaryDirectory() as d:
            pipeline(Path(d), speed)
    with tempfile.TemporaryDirectory() as d:
        real_drivers(Path(d))


if __name__ == "__main__":
    main()
