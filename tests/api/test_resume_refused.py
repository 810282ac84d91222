"""A resume the bench can no longer carry out is refused before it claims the run, with the
run, the procedure and the reason — over REST (409 with the message) and by ``calbench
resume`` (exit code 2, one line) — and the run is left as it was: ``interrupted``, not
claimed, not queued. Two stored runs a newer version or another bench leaves behind: one
recorded with a procedure this version does not know, one whose remaining rotations are
faster than the table's rate limit (300 deg/s on the outer axis)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from fastapi.testclient import TestClient
from sqlalchemy.orm import Session, sessionmaker

from api.cli import main
from api.main import create_app
from db.models import Run, RunState
from db.repo.runs import create_run
from db.repo.units import get_or_create_bench, get_or_create_unit
from tests.support.service_helpers import OP, service_settings

pytestmark = pytest.mark.timeout(120)

FAST = "run-fast-rates"
UNKNOWN = "run-unknown-procedure"


def store_interrupted(
    sessions: sessionmaker[Session], run_id: str, procedure: str, parameters: dict[str, object], last: int
) -> None:
    with sessions.begin() as s:
        bench = get_or_create_bench(s, "bench-api")
        unit = get_or_create_unit(s, f"SN-{run_id}", bench_id=bench.id)
        run = create_run(
            s,
            run_id,
            unit.id,
            procedure,
            bench_id=bench.id,
            params={"procedure": procedure, "parameters": parameters},
            recording_path=f"/nonexistent/run-{run_id}.csv",
            state=RunState.INTERRUPTED,
        )
        run.last_complete_window = last
        run.error = "interrupted: device fault: the table at serial:///dev/ttyUSB0 did not answer"


@pytest.fixture(scope="module")
def client(tmp_path_factory: pytest.TempPathFactory) -> Iterator[TestClient]:
    tmp = tmp_path_factory.mktemp("refused")
    with TestClient(create_app(service_settings(tmp), start_scheduler=False)) as c:
        sessions = c.app.state.services.sessions  # type: ignore[attr-defined]
        # rate-1axis at 1000 then 100 deg/s: windows 4 (pose 2 at +1000) and later still turn too fast
        store_interrupted(sessions, FAST, "rate-1axis", {"dwell_s": 5.0, "rates_deg_s": [1000.0, 100.0]}, 3)
        store_interrupted(sessions, UNKNOWN, "static-24-legacy", {"dwell_s": 5.0}, 5)
        c.tmp = tmp  # type: ignore[attr-defined]
        yield c


def stored(client: TestClient, run_id: str) -> tuple[RunState, int, object]:
    with client.app.state.services.sessions.begin() as s:  # type: ignore[attr-defined]
        run = s.get(Run, run_id)
        assert run is not None
        return run.state, run.resume_count, run.owner_pid


def test_rest_refuses_a_resume_whose_remaining_rotations_break_the_rate_limit(client: TestClient) -> None:
    before = stored(client, FAST)
    r = client.post(f"/api/runs/{FAST}/resume", headers=OP)
    assert r.status_code == 409, r.text
    detail = r.json()["detail"]
    assert detail.startswith(
        f"run {FAST}: the 14 windows of rate-1axis still to record (from window 5 of 18)"
    )
    assert "rate 1000 deg/s exceeds the axis 1 limit 300 deg/s" in detail
    assert stored(client, FAST) == before and before[0] is RunState.INTERRUPTED


def test_rest_refuses_a_resume_of_a_procedure_this_version_does_not_know(client: TestClient) -> None:
    r = client.post(f"/api/runs/{UNKNOWN}/resume", headers=OP)
    assert r.status_code == 409, r.text
    detail = r.json()["detail"]
    assert detail.startswith(
        f"run {UNKNOWN} was recorded with procedure 'static-24-legacy', which this calbench does not know"
    )
    assert "static-12" in detail
    assert stored(client, UNKNOWN)[0] is RunState.INTERRUPTED


@pytest.mark.parametrize(("run_id", "words"), [(FAST, "no longer fit"), (UNKNOWN, "'static-24-legacy'")])
def test_calbench_resume_refuses_with_one_line_and_exit_code_2(
    client: TestClient,
    run_id: str,
    words: str,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
) -> None:
    tmp: Path = client.tmp  # type: ignore[attr-defined]
    monkeypatch.setenv("CALBENCH_DATABASE_URL", f"sqlite:///{tmp / 'calbench.db'}")
    monkeypatch.setenv("CALBENCH_DATA_DIR", str(tmp))
    monkeypatch.setenv("CALBENCH_BENCH_NAME", "bench-cli")
    before = stored(client, run_id)
    code = main(["resume", run_id, "--sim"])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"calbench resume: run {run_id}") and words in err
    assert stored(client, run_id) == before
