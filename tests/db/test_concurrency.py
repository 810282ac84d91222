"""Two benches writing to one database at once must not clash.

Two processes (two benches) create runs on the same units, record windows and chunks and
issue certificates concurrently; afterwards every row is there exactly once and the
certificate numbers are unique and gap-free.
"""

from __future__ import annotations

import multiprocessing as mp
from concurrent.futures import ProcessPoolExecutor

import pytest
import sqlalchemy as sa

from db.models import Bench, Certificate, Run, RunState, RunWindow, SampleChunk, Unit
from tests.db._bench_worker import SHARED_SERIALS, bench_worker

pytestmark = [pytest.mark.slow, pytest.mark.timeout(600)]  # two benches writing whole runs at once

N_RUNS = 12
N_WINDOWS = 4
N_BURST = 25


def test_two_benches_writing_at_once(db_engine, db_session_factory):
    url = db_engine.url.render_as_string(hide_password=False)
    ctx = mp.get_context("spawn")
    start = ctx.Manager().Event()
    with ProcessPoolExecutor(max_workers=2, mp_context=ctx) as pool:
        futures = [
            pool.submit(bench_worker, url, name, N_RUNS, N_WINDOWS, start, N_BURST)
            for name in ("bench-a", "bench-b")
        ]
        start.set()
        issued = [f.result(timeout=240) for f in futures]

    all_numbers = issued[0] + issued[1]
    n_certs = 2 * (N_RUNS + N_BURST)
    assert len(set(all_numbers)) == n_certs
    with db_session_factory() as s:
        assert sorted(s.scalars(sa.select(Bench.name))) == ["bench-a", "bench-b"]
        assert sorted(s.scalars(sa.select(Unit.serial))) == sorted(SHARED_SERIALS)
        run_rows = s.execute(sa.select(Run.id, Run.state, Run.last_complete_window, Run.progress)).all()
        assert len(run_rows) == 2 * N_RUNS
        assert all(
            st is RunState.COMPLETED and lcw == N_WINDOWS - 1 and p == 1.0 for _, st, lcw, p in run_rows
        )
        assert s.scalar(sa.select(sa.func.count()).select_from(RunWindow)) == 2 * N_RUNS * N_WINDOWS
        assert s.scalar(sa.select(sa.func.count()).select_from(SampleChunk)) == 2 * N_RUNS * N_WINDOWS
        serials = sorted(s.scalars(sa.select(Certificate.serial)))
        assert serials == list(range(1, n_certs + 1))  # unique and gap-free
        assert sorted(s.scalars(sa.select(Certificate.number))) == sorted(all_numbers)
