"""Small builders shared by the db tests."""

from __future__ import annotations

from sqlalchemy.orm import Session

from db.models import Run, RunState
from db.repo.runs import create_run
from db.repo.units import get_or_create_bench, get_or_create_unit


def make_run(
    session: Session,
    run_id: str = "20250101T000000Z-SN0001-aaaaaa",
    serial: str = "SN-0001",
    *,
    state: RunState = RunState.RUNNING,
    owner_pid: int | None = None,
    owner_host: str | None = None,
    bench_name: str = "bench-a",
) -> Run:
    """A run of ``serial`` on ``bench_name``, flushed."""
    bench = get_or_create_bench(session, bench_name, table_url="sim://", daq_url="sim://")
    unit = get_or_create_unit(session, serial, model="QA-3000", channel_unit="V", bench_id=bench.id)
    return create_run(
        session,
        run_id,
        unit.id,
        "static-12",
        bench_id=bench.id,
        state=state,
        params={"dwell": {"dwell_s": 40.0, "source": "fixed", "reason": "given"}},
        recording_path=f"/data/{run_id}.csv",
        owner_pid=owner_pid,
        owner_host=owner_host,
    )
