"""Every sample the DAQ produced is either in the recording, at its place on the time axis,
or named by a recorded gap: host stalls, ring overflows, samples dropped inside the DAQ and
lost Modbus replies injected at random during a whole run on the simulated bench.

The simulated DAQ's engine tags every sample it produces with its DAQ epoch and sequence
number, carried in the temperature channel (``1e6 · epoch + seq``, exact in FLOAT32), and
logs where each epoch stopped; each recorded row says which sample it is, so the check does
not rely on the recording's own time stamps.
"""

from __future__ import annotations

import threading
import time
from pathlib import Path

import numpy as np
import pytest

from bench.bench_config import SIM_BENCH_FILE, load_bench_config
from bench.procedures import build_procedure
from bench.recording.reader import read_recording
from bench.records import GapRecord, RunStart
from bench.run_recorder import RunRecorder
from bench.run_sidecar import gap_from_json
from bench.sequencer.control import SequencerConfig
from bench.sequencer.loop import Sequencer
from drivers.factory import BenchDevices, open_table
from drivers.modbus_daq import ModbusDaq
from drivers.sim.bench import SimBench
from station.execution.devices import bench_sidecar

pytestmark = [pytest.mark.slow, pytest.mark.timeout(300)]

RATE_HZ = 200.0
SPEED = 10.0  # 2000 samples per wall second
RING = 1000  # half a wall second: a stall longer than that overflows the ring
MAX_FAULTS = 45  # then the run finishes in peace, however slow the machine


EPOCH_TAG = 1_000_000


class ProducedLog:
    """Wraps the engine: tags every sample with (epoch, sequence), notes each epoch's end."""

    def __init__(self, sim: SimBench) -> None:
        self.epoch = -1
        self.counter_at_stop: dict[int, int] = {}
        engine = sim.engine
        produce, start, stop = engine._produce, engine.start, engine.stop

        def tagged_produce(k: np.ndarray) -> None:
            produce(k)
            pos = (engine._stored - k.shape[0] + np.arange(k.shape[0])) % engine.capacity
            engine._temp[pos] = EPOCH_TAG * self.epoch + k

        def logged_start() -> None:
            self.epoch += 1
            start()

        def logged_stop() -> None:
            stop()
            self.counter_at_stop[self.epoch] = engine.counter

        engine._produce = tagged_produce  # type: ignore[method-assign]
        engine.start = logged_start  # type: ignore[method-assign]
        engine.stop = logged_stop  # type: ignore[method-assign]


class Faults:
    """Injects a random fault every 0.2-0.6 wall seconds, at most MAX_FAULTS; counts them."""

    def __init__(self, sim: SimBench, daq: ModbusDaq, seed: int) -> None:
        self.rng = np.random.default_rng(seed)
        self.sim, self.daq = sim, daq
        self.counts = {"stall": 0, "drop": 0, "reply": 0}
        self._stall_s = 0.0
        self._stop = threading.Event()
        read = daq.read_block

        def stalling_read(max_samples: int, timeout_s: float):  # type: ignore[no-untyped-def]
            stall, self._stall_s = self._stall_s, 0.0
            if stall:
                time.sleep(stall)  # the host does not come back to the DAQ for a while
            return read(max_samples, timeout_s)

        daq.read_block = stalling_read  # type: ignore[method-assign]
        self._thread = threading.Thread(target=self._loop, daemon=True)

    def _loop(self) -> None:
        while sum(self.counts.values()) < MAX_FAULTS and not self._stop.wait(
            float(self.rng.uniform(0.2, 0.6))
        ):
            kind = str(self.rng.choice(["stall", "drop", "reply"]))
            self.counts[kind] += 1
            if kind == "stall":
                self._stall_s = float(self.rng.uniform(0.1, 1.2))  # about half of them overflow the ring
            elif kind == "drop":
                self.sim.engine.drop_next(int(self.rng.integers(1, 300)))
            else:
                self.sim.daq_server.drop_replies(1, after=int(self.rng.integers(0, 30)))  # type: ignore[union-attr]

    def __enter__(self) -> Faults:
        self._thread.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self._stop.set()
        self._thread.join(5.0)


def check_integrity(t_s: np.ndarray, tag: np.ndarray, gaps: list[GapRecord], log: ProducedLog) -> int:
    """Assert the recording against what the DAQ produced; return the number of samples lost."""
    assert np.all(np.isfinite(tag)) and np.all(tag == np.round(tag))
    epoch = (tag // EPOCH_TAG).astype(int)
    seq = (tag - EPOCH_TAG * epoch).astype(int)
    at_row: dict[int, list[GapRecord]] = {}
    for g in gaps:
        at_row.setdefault(g.after_row, []).append(g)

    def lost_at(row: int) -> int:
        return sum(g.n_lost or 0 for g in at_row.get(row, []))

    # Before the first row: the samples of the first epoch before it are named by gaps.
    assert epoch[0] == 0 and lost_at(0) == seq[0], f"first row: epoch {epoch[0]}, sequence {seq[0]}"
    for i in range(1, len(seq)):
        periods = round(float(t_s[i] - t_s[i - 1]) * RATE_HZ)
        if epoch[i] == epoch[i - 1]:
            step = int(seq[i] - seq[i - 1])
            assert step >= 1, f"row {i}: sequence {seq[i]} after {seq[i - 1]}"
            assert lost_at(i) == step - 1, f"row {i}: {step - 1} samples missing, gaps say {lost_at(i)}"
            if step > 1:
                first = at_row[i][0].first_lost_seq
                assert first == seq[i - 1] + 1, f"row {i}: gap starts at {first}, not {seq[i - 1] + 1}"
        else:  # DAQ restarts: the old epoch's samples after the last row, any epoch with no row
            # at all (a restart right after a restart), then the new epoch's first samples
            e0, e1 = int(epoch[i - 1]), int(epoch[i])
            restarts = sum(g.cause == "restart" for g in at_row.get(i, []))
            assert e1 > e0 and restarts == e1 - e0, (
                f"row {i}: epoch {e0} -> {e1}, {restarts} restarts recorded"
            )
            old_left = log.counter_at_stop[e0] - 1 - int(seq[i - 1])
            skipped = sum(log.counter_at_stop[e] for e in range(e0 + 1, e1))
            expected = old_left + skipped + int(seq[i])
            assert lost_at(i) == expected, f"row {i}: restart loses {expected}, gaps say {lost_at(i)}"
            step = expected + 1
        assert periods == step, f"row {i}: t advances {periods} periods for {step} samples"
        assert abs(t_s[i] - t_s[i - 1] - step / RATE_HZ) < 1e-9
    tail = at_row.get(len(seq), [])  # met after the last row was written (the run was ending)
    assert set(at_row) <= set(range(len(seq) + 1))
    assert not tail or tail[0].first_lost_seq == seq[-1] + 1, f"a gap after the last row: {tail[0]}"
    return sum(g.n_lost or 0 for g in gaps)


def test_random_stalls_overflows_drops_and_lost_replies_are_all_reported(tmp_path: Path) -> None:
    sim = SimBench(speed=SPEED, sample_rate_hz=RATE_HZ, seed=11, ring_capacity=RING)
    log = ProducedLog(sim)
    table = open_table(sim.table_url)
    daq = ModbusDaq(sim.daq_url, timeout_s=0.3)
    try:
        proc = build_procedure("static-12", dwell_s=2.0, settle_s=0.2)
        sidecar_path = tmp_path / "run.csv"
        sc = bench_sidecar(
            BenchDevices(table, daq, sim), "SN-GAPS", proc.name, load_bench_config(SIM_BENCH_FILE)
        )
        recorder = RunRecorder.create(sidecar_path, sc, has_temp=True, run_meta={"run_id": "gaps"})
        start = RunStart(
            "gaps", "SN-GAPS", proc.name, "bench", str(sidecar_path), RATE_HZ, 3, proc.n_windows, 60.0
        )
        config = SequencerConfig(max_window_retries=50, stall_timeout_s=10.0, move_timeout_margin_s=20.0)
        with Faults(sim, daq, seed=5) as faults:
            acq = Sequencer(table, daq, proc, recorder, start, config=config).run()
        assert acq.outcome is None, acq.error
        assert len(acq.windows) == proc.n_windows
        rec = read_recording(sidecar_path)
        stored = [gap_from_json(d) for d in rec.sidecar.extra["calbench_gaps"]]  # type: ignore[union-attr]
        assert stored == list(acq.gaps)
        assert faults.counts["stall"] and faults.counts["drop"] and faults.counts["reply"]
        causes = {g.cause for g in acq.gaps}
        assert {"dropped", "overflow"} <= causes, causes  # both kinds of loss happened, and were named
        assert rec.temp_c is not None
        lost = check_integrity(rec.t_s, rec.temp_c, list(acq.gaps), log)
        assert rec.n_samples == acq.n_samples and lost > 0
        # The window rule: no window used a span with a hole in it.
        for g in acq.gaps:
            assert not any(w.start_s <= (g.t_last_s or -1.0) < w.end_s for w in acq.windows), g
    finally:
        table.close()
        daq.close()
        sim.close()
