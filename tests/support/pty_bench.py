"""A bench with real device paths: the simulated table served on a pseudo-terminal (the real
text protocol over a serial device path) and the simulated DAQ on a pymodbus server (Modbus
TCP on loopback), described by a bench file that is not the simulated one — so ``calbench run
--bench-file`` opens them with the real drivers, exactly as it would open a lab's table and DAQ."""

from __future__ import annotations

import contextlib
from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

from bench.bench_config import SIM_BENCH_FILE
from drivers.sim.bench import SimBench


@dataclass(frozen=True)
class PtyBench:
    """The simulated bench behind the paths, its table's device path and its bench file."""

    sim: SimBench
    table_path: str
    bench_file: Path


def write_bench_file(path: Path, table_url: str, daq_url: str) -> Path:
    """The simulated bench's file with real ``table_url`` and ``daq_url`` (same geometry)."""
    text = SIM_BENCH_FILE.read_text(encoding="utf-8")
    table_old, daq_old = 'url = "sim://"\nmount_rotation', '[daq]\nurl = "sim://"'
    assert table_old in text and daq_old in text
    text = text.replace(table_old, f'url = "{table_url}"\nmount_rotation', 1)
    text = text.replace(daq_old, f'[daq]\nurl = "{daq_url}"', 1)
    text = text.replace('name = "simulated bench"', 'name = "pty bench"', 1)
    path.write_text(text, encoding="utf-8")
    return path


@contextlib.contextmanager
def pty_bench(
    tmp_path: Path, *, speed: float, sample_rate_hz: float = 100.0, seed: int = 3
) -> Iterator[PtyBench]:
    """A :class:`SimBench` whose table is also served on a pseudo-terminal, and its bench file."""
    sim = SimBench(speed=speed, sample_rate_hz=sample_rate_hz, seed=seed)
    try:
        path = sim.table_server.serve_pty()
        bench_file = write_bench_file(tmp_path / "pty-bench.toml", f"serial://{path}", sim.daq_url)
        yield PtyBench(sim, path, bench_file)
    finally:
        sim.close()
