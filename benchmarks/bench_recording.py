"""Reading and writing a 1 kHz × 1 hour recording (3.6 million rows, t + 3 accel + 3 encoders).

Timings are printed as ratios against ``numpy.loadtxt`` of the same file measured in the
same run (the floor for a text reader), and against writing the same rows with
``csv.writer`` directly.
"""

from __future__ import annotations

import csv
import tempfile
import time
from pathlib import Path

import numpy as np

from bench.recording import Recording, Sidecar, TableAxis, TableGeometry, read_recording, write_recording

N_ROWS = 3_600_000


def main() -> None:
    rng = np.random.default_rng(0)
    t = np.arange(N_ROWS) * 1e-3
    rec = Recording(
        sidecar=Sidecar(
            unit_serial="BENCH",
            channel_unit="V",
            sample_rate_hz=1000.0,
            g_local_m_s2=9.81,
            table=TableGeometry(axes=tuple(TableAxis(f"a{i}", (0.0, 0.0, 1.0)) for i in range(3))),
        ),
        t_s=t,
        accel_raw=np.round(1.5 + rng.normal(0, 0.01, (N_ROWS, 3)), 6),
        table_deg=np.round(rng.uniform(-180, 180, (N_ROWS, 3)), 4),
    )
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "hour.csv"
        t0 = time.perf_counter()
        write_recording(rec, path)
        t_write = time.perf_counter() - t0
        base_path = Path(d) / "base.csv"
        t0 = time.perf_counter()
        with base_path.open("w", newline="") as f:
            csv.writer(f, lineterminator="\n").writerows(
                np.column_stack([rec.t_s, rec.accel_raw, rec.table_deg]).tolist()
            )
        t_write_base = time.perf_counter() - t0
        t0 = time.perf_counter()
        np.loadtxt(path, delimiter=",", skiprows=1)
        t_base = time.perf_counter() - t0
        t0 = time.perf_counter()
        back = read_recording(path)
        t_read = time.perf_counter() - t0
        assert back.n_samples == N_ROWS
        size_mb = path.stat().st_size / 1e6
    print(f"{N_ROWS} rows, {size_mb:.0f} MB")
    print(f"read_recording:  {t_read:6.2f} s  = {t_read / t_base:.2f} x numpy.loadtxt ({t_base:.2f} s)")
    ratio = t_write / t_write_base
    print(f"write_recording: {t_write:6.2f} s  = {ratio:.2f} x csv.writer ({t_write_base:.2f} s)")


if __name__ == "__main__":
    main()
