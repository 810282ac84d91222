"""The sequencer on small in-test devices satisfying the RotaryTable / Daq protocols.

The fake DAQ produces samples on its own clock (``block`` samples per read, no sleeping on
the data clock), from a known sensor truth: raw = b + K·f, with f = Rᵀ·[0, 0, g] computed
here with scipy, independently of the code under test. Faults are switched on by tests.
"""

from __future__ import annotations

import math
import threading
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bench.procedures import build_procedure
from bench.procedures.steps import Procedure
from bench.recording.model import Sidecar, TableAxis, TableGeometry
from bench.recording.reader import read_recording
from bench.records import ChunkRecord, DwellChoice, Progress, RunStart, StateChange, WindowKind, WindowRecord
from bench.run_observer import NullObserver
from bench.run_recorder import RunRecorder
from bench.run_state import Outcome, RunState
from bench.sequencer.control import RunControl, SequencerConfig
from bench.sequencer.loop import Sequencer
from drivers.base import AxisMode, AxisStatus, SampleBlock, TableStatus
from drivers.errors import DataGap, DeviceTimeout, InterlockOpen, LinkLost

G = 9.81
FS = 200.0
AXES = np.array([[0, 0, 1], [1, 0, 0], [0, 0, 1]], dtype=float)
BIAS = np.array([0.02, -0.01, 0.03])
K = np.array([[1.01, 0.002, -0.001], [0.0, 0.99, 0.003], [0.001, 0.0, 1.02]])
NOISE = 1e-3


def specific_force(angles_deg: np.ndarray) -> np.ndarray:
    r = Rotation.identity()
    for u, th in zip(AXES, angles_deg, strict=True):
        r = r * Rotation.from_rotvec(u * math.radians(th))
    return r.inv().apply([0.0, 0.0, G])


class FakeTable:
    """Moves instantly (after ``move_delay_s``); faults by flags."""

    def __init__(self) -> None:
        self.pos = [0.0, 0.0, 0.0]
        self.rate = [0.0, 0.0, 0.0]
        self.interlock_ok = True
        self.stops = 0
        self.moves: list[tuple[float, ...]] = []
        self.fail_move: Exception | None = None
        self.hang_move = False
        self.move_delay_s = 0.0
        self.lock = threading.Lock()

    @property
    def n_axes(self) -> int:
        return 3

    def move_to(self, angles_deg: tuple[float, ...], timeout_s: float) -> None:
        if self.hang_move:
            time.sleep(60)
        if self.fail_move is not None:
            raise self.fail_move
        if not self.interlock_ok:
            raise InterlockOpen("interlock open")
        time.sleep(self.move_delay_s)
        with self.lock:
            self.pos = list(angles_deg)
            self.moves.append(tuple(angles_deg))

    def start_rate(self, axis: int, rate_deg_s: float) -> None:
        self.rate[axis - 1] = rate_deg_s

    def start_oscillation(self, axis: int, amplitude_deg: float, period_s: float) -> None:
        self.rate[axis - 1] = 2 * math.pi * amplitude_deg / period_s

    def positions_deg(self) -> tuple[float, ...]:
        return tuple(self.pos)

    def rates_deg_s(self) -> tuple[float, ...]:
        return tuple(self.rate)

    def stop(self) -> None:
        self.stops += 1
        self.rate = [0.0, 0.0, 0.0]

    def status(self) -> TableStatus:
        axes = tuple(
            AxisStatus(p, r, AxisMode.POSITION, True) for p, r in zip(self.pos, self.rate, strict=True)
        )
        return TableStatus(axes, self.interlock_ok, False)

    def close(self) -> None:
        pass


class FakeDaq:
    """``block`` samples per read on its own clock; latches the fake table's angles."""

    def __init__(self, table: FakeTable, seed: int = 1, block: int = 50) -> None:
        self.table = table
        self.rng = np.random.default_rng(seed)
        self.block = block
        self.seq = 0
        self.temp_c = 25.0
        self.gap_at: set[int] = set()
        self.fail: Exception | None = None
        self.silent = False
        self.reads = 0

    @property
    def sample_rate_hz(self) -> float:
        return FS

    @property
    def channel_unit(self) -> str:
        return "m/s2"

    def start(self) -> None:
        self.seq = 0

    def read_block(self, max_samples: int, timeout_s: float) -> SampleBlock:
        time.sleep(self.block / FS / 50.0)  # the data clock runs 50 times faster than the wall clock
        self.reads += 1
        if self.fail is not None:
            raise self.fail
        if self.silent:
            return SampleBlock(self.seq, np.zeros(0), np.zeros((0, 3)), np.zeros(0), np.zeros((0, 3)))
        if self.reads in self.gap_at:
            expected = self.seq
            self.seq += self.block
            raise DataGap(expected, self.seq)
        n = min(self.block, max_samples)
        with self.table.lock:
            pos = np.array(self.table.pos)
        f = specific_force(pos)
        raw = BIAS + K @ f + self.rng.normal(0, NOISE, (n, 3))
        t = (self.seq + np.arange(n)) / FS
        blk = SampleBlock(self.seq, t, raw, np.full(n, self.temp_c), np.tile(pos, (n, 1)))
        self.seq += n
        return blk

    def stop(self) -> None:
        pass

    def status(self) -> dict[str, object]:
        return {}

    def close(self) -> None:
        pass


class Recorder(NullObserver):
    def __init__(self) -> None:
        self.states: list[StateChange] = []
        self.windows: list[WindowRecord] = []
        self.chunks: list[ChunkRecord] = []
        self.dwells: list[DwellChoice] = []
        self.starts: list[RunStart] = []
        self.progress: list[Progress] = []
        self.hook = None

    def on_progress(self, run_id: str, progress: Progress) -> None:
        self.progress.append(progress)

    def on_start(self, start: RunStart) -> None:
        self.starts.append(start)

    def on_state(self, run_id: str, change: StateChange) -> None:
        self.states.append(change)

    def on_window(self, run_id: str, window: WindowRecord) -> None:
        self.windows.append(window)
        if self.hook is not None:
            self.hook(window)

    def on_chunk(self, run_id: str, chunk: ChunkRecord) -> None:
        self.chunks.append(chunk)

    def on_dwell(self, run_id: str, dwell: DwellChoice) -> None:
        self.dwells.append(dwell)


def sidecar() -> Sidecar:
    names = ("outer", "middle", "inner")
    geom = TableGeometry(tuple(TableAxis(n, tuple(a)) for n, a in zip(names, AXES.tolist(), strict=True)))
    return Sidecar("SN-T1", "m/s2", FS, G, procedure="static-12", table=geom)


FAST = SequencerConfig(
    status_poll_s=0.01,
    progress_interval_s=0.01,
    stall_timeout_s=2.0,
    stop_timeout_s=2.0,
    move_timeout_margin_s=2.0,
    chunk_s=1.0,
    min_chunk_wall_s=0.0,
)


def make(
    tmp_path: Path,
    proc: Procedure,
    table: FakeTable | None = None,
    daq: FakeDaq | None = None,
    config: SequencerConfig = FAST,
    dwell: DwellChoice | None = None,
) -> tuple[Sequencer, FakeTable, FakeDaq, Recorder, RunControl]:
    table = table or FakeTable()
    daq = daq or FakeDaq(table)
    obs = Recorder()
    ctl = RunControl()
    start = RunStart(
        "run-1", "SN-T1", proc.name, "bench-a", str(tmp_path / "run.csv"), FS, 3, proc.n_windows, 100.0
    )
    rec = RunRecorder.create(
        tmp_path / "run.csv", sidecar(), True, {"run_id": "run-1"}, chunk_s=1.0, min_chunk_wall_s=0.0
    )
    seq = Sequencer(table, daq, proc, rec, start, [obs], ctl, config, dwell=dwell)
    return seq, table, daq, obs, ctl


def quick_static(dwell_s: float | None = 1.0) -> Procedure:
    return build_procedure("static-12", dwell_s=dwell_s, settle_s=0.2, noise_window_s=30.0)


def fit_bias_k(rec_windows: list[WindowRecord]) -> tuple[np.ndarray, np.ndarray]:
    f = np.array([specific_force(np.array(w.mean_table_deg)) for w in rec_windows])
    y = np.array([[w.means["ax"], w.means["ay"], w.means["az"]] for w in rec_windows])
    a = np.hstack([np.ones((len(f), 1)), f])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    return coef[0], coef[1:].T


def test_full_static12_run_records_twelve_windows_that_recover_the_truth(tmp_path: Path) -> None:
    seq, table, _, obs, _ = make(tmp_path, quick_static())
    acq = seq.run()
    assert acq.outcome is None and acq.error is None
    assert len(acq.windows) == 12 == len(obs.windows)
    assert [w.index for w in obs.windows] == list(range(12))
    assert all(w.n_samples == 200 and w.kind is WindowKind.STATIC for w in acq.windows)
    assert table.stops >= 1  # safe state at the end
    rec = read_recording(tmp_path / "run.csv")
    assert rec.sidecar.segments is not None and len(rec.sidecar.segments) == 12
    assert rec.n_samples == acq.n_samples
    assert np.all(np.diff(rec.t_s) > 0)
    b, k = fit_bias_k(list(acq.windows))
    sigma_mean = NOISE / math.sqrt(200)  # per-window mean noise; the fit averages 12 of them
    np.testing.assert_allclose(b, BIAS, atol=6 * sigma_mean)
    np.testing.assert_allclose(k, K, atol=6 * sigma_mean / G)
    # The chunks tile the recording and the last one ends at its size.
    assert sum(c.n_samples for c in obs.chunks) == rec.n_samples
    assert [c.seq for c in obs.chunks] == list(range(len(obs.chunks)))
    assert obs.chunks[-1].end_byte == (tmp_path / "run.csv").stat().st_size
    assert [s.state for s in obs.states] == [RunState.RUNNING]


@pytest.mark.slow  # a whole run with its noise window, 17 s
def test_noise_window_decides_the_dwell_and_it_is_stored(tmp_path: Path) -> None:
    seq, *_, obs, _ = make(tmp_path, quick_static(dwell_s=None))
    acq = seq.run()
    assert acq.outcome is None, acq.error
    assert acq.windows[0].kind is WindowKind.NOISE and len(acq.windows) == 13
    assert len(obs.dwells) == 1 and obs.dwells[0].source == "noise_window"
    # white noise only: the Allan deviation falls to the longest tau, the reason says so
    assert "floor not reached" in obs.dwells[0].reason or "floor" in obs.dwells[0].reason
    dwell_n = round(obs.dwells[0].dwell_s * FS)
    assert all(w.n_samples == dwell_n for w in acq.windows[1:])
    meta = read_recording(tmp_path / "run.csv").sidecar.extra["calbench_run"]
    assert meta["dwell"]["source"] == "noise_window"  # type: ignore[index]


def test_abort_stops_the_table_and_keeps_the_recording(tmp_path: Path) -> None:
    seq, table, _, obs, ctl = make(tmp_path, quick_static())
    obs.hook = lambda w: ctl.abort("operator pressed abort") if w.index == 3 else None
    acq = seq.run()
    assert acq.outcome is Outcome.ABORTED and "operator pressed abort" in (acq.error or "")
    assert len(acq.windows) == 4 and table.stops >= 1
    rec = read_recording(tmp_path / "run.csv")
    assert len(rec.sidecar.segments or ()) == 4 and rec.n_samples == acq.n_samples


@pytest.mark.parametrize("fault", [DeviceTimeout("table did not reach position"), LinkLost("port closed")])
def test_table_fault_is_error_with_safe_state(tmp_path: Path, fault: Exception) -> None:
    seq, table, _, obs, _ = make(tmp_path, quick_static())
    obs.hook = lambda w: setattr(table, "fail_move", fault) if w.index == 4 else None
    acq = seq.run()
    assert acq.outcome is Outcome.ERROR
    assert "step 10 (MoveTo pos06)" in (acq.error or "") and str(fault) in (acq.error or "")
    assert table.stops >= 1 and len(acq.windows) == 5
    assert len(read_recording(tmp_path / "run.csv").sidecar.segments or ()) == 5


def test_daq_failure_is_error(tmp_path: Path) -> None:
    seq, table, daq, obs, _ = make(tmp_path, quick_static())
    obs.hook = lambda w: setattr(daq, "fail", LinkLost("Modbus connection reset")) if w.index == 2 else None
    acq = seq.run()
    assert acq.outcome is Outcome.ERROR and "Modbus connection reset" in (acq.error or "")
    assert table.stops >= 1


def test_daq_stall_is_a_timeout_not_a_hang(tmp_path: Path) -> None:
    seq, _table, daq, obs, _ = make(tmp_path, quick_static())
    obs.hook = lambda w: setattr(daq, "silent", True) if w.index == 0 else None
    acq = seq.run()
    assert acq.outcome is Outcome.ERROR and "no DAQ samples for 2 s" in (acq.error or "")


def test_hanging_move_hits_its_deadline(tmp_path: Path) -> None:
    cfg = SequencerConfig(
        **{**FAST.__dict__, "move_timeout_factor": 0.2, "move_timeout_margin_s": 0.5, "stop_timeout_s": 0.5}
    )
    seq, table, _, obs, _ = make(tmp_path, quick_static(), config=cfg)
    obs.hook = lambda w: setattr(table, "hang_move", True) if w.index == 0 else None
    acq = seq.run()
    assert acq.outcome is Outcome.ERROR and "table move_to did not return within" in (acq.error or "")
    assert table.stops >= 1


def test_data_gap_in_a_window_re_records_it(tmp_path: Path) -> None:
    table = FakeTable()
    daq = FakeDaq(table)
    daq.gap_at = {30}  # the noise-free static-12 with 1 s dwell: read 30 lies inside a window
    seq, *_ = make(tmp_path, quick_static(), table=table, daq=daq)
    acq = seq.run()
    assert acq.outcome is None, acq.error
    assert len(acq.windows) == 12
    rec = read_recording(tmp_path / "run.csv")
    assert np.all(np.diff(rec.t_s) > 0)
    gaps = np.diff(rec.t_s) > 1.5 / FS
    assert gaps.sum() == 1  # the gap is visible in t, and no window spans it
    t_gap = rec.t_s[:-1][gaps][0]
    assert not any(w.start_s <= t_gap < w.end_s for w in acq.windows)
    # ...and recorded where it is: the rows on either side, the lost sequence numbers, the rule
    (g,) = acq.gaps
    row = int(np.flatnonzero(gaps)[0]) + 1
    assert (g.after_row, g.n_lost) == (row, daq.block)
    # read 30 usually falls inside a window (re-measured); on a loaded machine it may fall between
    assert g.action == ("between windows" if g.window_index is None else "window re-measured")
    assert g.t_last_s == rec.t_s[row - 1] and g.t_resume_s == pytest.approx(rec.t_s[row], abs=1e-9)
    assert rec.t_s[row] - rec.t_s[row - 1] == pytest.approx((daq.block + 1) / FS)
    assert rec.sidecar.extra["calbench_gaps"][0]["first_lost_seq"] == g.first_lost_seq


def test_repeated_gaps_restart_acquisition_and_the_clock_continues(tmp_path: Path) -> None:
    table = FakeTable()
    daq = FakeDaq(table)
    daq.gap_at = {40, 41, 42}  # a reader losing the race for the oldest samples, three times running
    seq, *_ = make(tmp_path, quick_static(), table=table, daq=daq)
    acq = seq.run()
    assert acq.outcome is None, acq.error
    assert len(acq.windows) == 12
    rec = read_recording(tmp_path / "run.csv")
    assert np.all(np.diff(rec.t_s) > 0)  # the DAQ clock restarted at 0; the recording's did not
    assert [g.cause for g in acq.gaps] == ["unknown"] * 3 + ["restart"]
    assert [g.daq_epoch for g in acq.gaps] == [0, 0, 0, 0]
    (row,) = np.flatnonzero(np.diff(rec.t_s) > 1.5 / FS) + 1  # one hole in t: the three gaps...
    assert {g.after_row for g in acq.gaps} == {row}
    lost = sum(g.n_lost or 0 for g in acq.gaps)
    assert lost == 3 * daq.block  # ...whose samples the restart did not fold away
    assert rec.t_s[row] - rec.t_s[row - 1] == pytest.approx((lost + 1) / FS)
    assert acq.gaps[-1].t_resume_s == pytest.approx(rec.t_s[row], abs=1e-9)


def test_resume_after_an_interrupted_run_completes_the_windows(tmp_path: Path) -> None:
    seq, _table, _, obs, ctl = make(tmp_path, quick_static())
    obs.hook = lambda w: ctl.abort("simulated crash") if w.index == 6 else None
    first = seq.run()
    assert len(first.windows) == 7
    # Resume as a restart would: cut at the last durable chunk, continue at window 7.
    last_chunk = obs.chunks[-1]
    rec = RunRecorder.resume(tmp_path / "run.csv", last_chunk.end_byte, 7, last_chunk.seq + 1)
    table2 = FakeTable()
    proc = quick_static()
    start = RunStart(
        "run-1",
        "SN-T1",
        proc.name,
        "bench-a",
        str(tmp_path / "run.csv"),
        FS,
        3,
        12,
        100.0,
        resumed_from_window=7,
    )
    obs2 = Recorder()
    acq = Sequencer(
        table2, FakeDaq(table2, seed=2), proc, rec, start, [obs2], RunControl(), FAST, start_window=7
    ).run()
    assert acq.outcome is None, acq.error
    assert [w.index for w in acq.windows] == list(range(12))
    assert [w.index for w in obs2.windows] == [7, 8, 9, 10, 11]
    assert table2.moves[0] == proc.steps[2 * 7].angles_deg  # type: ignore[union-attr]
    full = read_recording(tmp_path / "run.csv")
    assert len(full.sidecar.segments or ()) == 12 and np.all(np.diff(full.t_s) > 0)
    b, _k = fit_bias_k(list(acq.windows))
    np.testing.assert_allclose(b, BIAS, atol=6 * NOISE / math.sqrt(200))
