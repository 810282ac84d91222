"""One simulated bench writing to a shared database (run in a separate process by the tests)."""

from __future__ import annotations

import multiprocessing.synchronize

from db.engine import make_engine, make_session_factory
from db.models import RunState
from db.repo import certificates, progress, runs, units

SHARED_SERIALS = [f"SN-SHARED-{i}" for i in range(3)]


def bench_worker(
    url: str,
    bench_name: str,
    n_runs: int,
    n_windows: int,
    start: multiprocessing.synchronize.Event,
    n_burst: int = 0,
) -> list[str]:
    """Create ``n_runs`` runs on shared units, each with windows, chunks and a certificate,
    then issue ``n_burst`` more certificates back to back (the tightest race on numbers).

    Every event is its own short transaction, as the run observer writes them. Returns the
    certificate numbers issued.
    """
    engine = make_engine(url)
    factory = make_session_factory(engine)
    start.wait(timeout=60)
    issued = []
    try:
        with factory.begin() as s:
            bench_id = units.get_or_create_bench(s, bench_name).id
        for r in range(n_runs):
            run_id = f"{bench_name}-run-{r}"
            with factory.begin() as s:
                unit = units.get_or_create_unit(s, SHARED_SERIALS[r % len(SHARED_SERIALS)], bench_id=bench_id)
                runs.create_run(s, run_id, unit.id, "static-12", bench_id=bench_id, state=RunState.RUNNING)
            for w in range(n_windows):
                with factory.begin() as s:
                    progress.record_chunk(
                        s,
                        run_id,
                        w,
                        first_sample=100 * w,
                        n_samples=100,
                        last_t_s=w + 0.99,
                        end_byte=1000 * (w + 1),
                    )
                with factory.begin() as s:
                    progress.record_window(s, run_id, w, start_s=float(w), end_s=w + 0.9, n_samples=90)
                    runs.heartbeat(s, run_id, progress=(w + 1) / n_windows)
            with factory.begin() as s:
                runs.finish_run(s, run_id, RunState.COMPLETED, outcome="PASS")
                issued.append(certificates.issue_certificate(s, run_id, {"run": run_id}).number)
        for b in range(n_burst):
            with factory.begin() as s:
                issued.append(certificates.issue_certificate(s, f"{bench_name}-run-0", {"burst": b}).number)
    finally:
        engine.dispose()
    return issued
