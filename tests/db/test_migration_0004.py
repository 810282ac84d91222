"""Migration 0004 on a database made at revision 0003 (the schema before it): every value a run
kept in ``params`` (control requests, service bookkeeping, procedure parameters, results)
arrives in its new home, on SQLite and on PostgreSQL; the downgrade gives the same ``params``
back."""

from __future__ import annotations

import copy
import datetime as dt
from typing import Any

import sqlalchemy as sa
from sqlalchemy.engine import Engine

from db.migrate import current_revision, downgrade, upgrade
from db.types import UtcDateTime
from tests.db.old_schema import SETUP as OLD_SETUP
from tests.db.old_schema import at_revision, row_counts, run_table

T0 = dt.datetime(2026, 11, 20, 2, 0, tzinfo=dt.UTC)

# the tables as revision 0003 has them (not the models: they follow the newest revision)
RUN = run_table()
AUTO = {"attempt": 2, "not_before": "2026-11-20T02:05:00+00:00", "windows": 3, "fault": "lost link"}
SETUP = {"run_id": "R-SERVICE", **OLD_SETUP}
RESULTS = {
    "calibration": {"method": "static-12", "bias": [0.01, -0.02, 0.03]},
    "diagnosis": {"findings": []},
    "sample_gaps": [{"n_lost": 4, "window_index": 3, "cause": "dropped"}],
    "certificate_error": "",
}
# params as main wrote them before 0004, each run with the columns the values move to
RUNS: dict[str, tuple[str, dict[str, Any], dict[str, Any]]] = {
    "R-SERVICE": (
        "completed",
        {
            **SETUP,
            **RESULTS,
            "service_kind": "calibration",
            "request": {"dwell_s": 3.0},
            "service_sim_age_days": 12.5,
            "control": {"seq": 2, "action": "continue"},
            "live": {"progress": 1.0, "window_index": 11, "state": "running"},
            "finishing_since": "2026-11-20T02:10:00.250000+00:00",
            "service_finished": {"state": "completed", "outcome": "PASS", "certificate_number": "C-1"},
        },
        {
            "kind": "calibration",
            "requested_dwell_s": 3.0,
            "sim_age_days": 12.5,
            "control_seq": 2,
            "control_action": "continue",
            "live_progress": {"progress": 1.0, "window_index": 11, "state": "running"},
            "final_event": {"state": "completed", "outcome": "PASS", "certificate_number": "C-1"},
            "abort_request": None,
            "resume_requested": False,
            "drift_night": None,
            "finishing_since": dt.datetime(2026, 11, 20, 2, 10, 0, 250000, tzinfo=dt.UTC),
            "auto_resume": None,
        },
    ),
    "R-DRIFT": (
        "queued",
        {
            "service_kind": "drift_check",
            "auto_resume": {
                "attempt": 2,
                "not_before": "2026-11-20T02:05:00+00:00",
                "windows": 3,
                "fault": "f",
            },
            "request": {"dwell_s": None, "note": "kept"},
            "bench": "bench-a",
            "drift_night": "2026-11-20T02:00:00+00:00",
            "resume_requested": True,
            "abort_requested": "operator abort over REST",
            "control": {"seq": 1, "action": "pause"},
        },
        {
            "kind": "drift_check",
            "requested_dwell_s": None,
            "drift_night": "2026-11-20T02:00:00+00:00",
            "resume_requested": True,
            "abort_request": "operator abort over REST",
            "control_seq": 1,
            "control_action": "pause",
            "live_progress": None,
            "final_event": None,
            "sim_age_days": None,
            "finishing_since": None,
            "auto_resume": {
                "attempt": 2,
                "not_before": "2026-11-20T02:05:00+00:00",
                "windows": 3,
                "fault": "f",
            },
        },
    ),
    "R-CLI": (
        "interrupted",
        {**SETUP, "run_id": "R-CLI", "sample_gaps": []},
        {
            "kind": None,
            "requested_dwell_s": None,
            "drift_night": None,
            "sim_age_days": None,
            "abort_request": None,
            "control_seq": 0,
            "control_action": None,
            "resume_requested": False,
            "live_progress": None,
            "final_event": None,
            "finishing_since": None,
            "auto_resume": None,
        },
    ),
}
MOVED = {
    "service_kind",
    "service_sim_age_days",
    "control",
    "live",
    "service_finished",
    "drift_night",
    "resume_requested",
    "abort_requested",
    "finishing_since",
    "auto_resume",
}


def _expected_params(params: dict[str, Any]) -> dict[str, Any]:
    """What ``params`` keeps: everything but the moved keys (``request``: its keys but dwell_s)."""
    rest = {k: v for k, v in params.items() if k not in MOVED and k != "request"}
    request = {k: v for k, v in (params.get("request") or {}).items() if k != "dwell_s"}
    if request:
        rest["request"] = request
    return rest


CHILDREN = ("fit_model", "finding", "run_window", "sample_chunk")
"""Tables whose rows refer to a run (ON DELETE CASCADE)."""


def _children(engine: Engine) -> dict[str, int]:
    return row_counts(engine, CHILDREN)


def _fill_at_0003(engine: Engine) -> None:
    at_revision(engine, "0003")
    with engine.begin() as conn:
        for run_id, (state, params, _) in RUNS.items():
            conn.execute(
                sa.insert(RUN).values(
                    id=run_id,
                    unit_id=1,
                    bench_id=1,
                    procedure="static-12",
                    state=state,
                    progress=0.5,
                    params=copy.deepcopy(params),
                    resume_count=1,
                    limit_checks=[],
                )
            )
            conn.execute(
                sa.text(
                    "INSERT INTO fit_model (run_id, kind, contract, param_names, created_at)"
                    " VALUES (:r, 'static', '{}', '[]', CURRENT_TIMESTAMP)"
                ),
                {"r": run_id},
            )
            conn.execute(
                sa.text(
                    "INSERT INTO finding (run_id, effect, summary, parameters, sigma, created_at)"
                    " VALUES (:r, 'lever_arm', 's', '{}', '{}', CURRENT_TIMESTAMP)"
                ),
                {"r": run_id},
            )
            conn.execute(
                sa.text(
                    'INSERT INTO run_window (run_id, "index", label, kind, start_s, end_s, n_samples,'
                    " pose_deg, means, created_at) VALUES (:r, 0, 'w', 'static', 0, 1, 100, '[]', '{}',"
                    " CURRENT_TIMESTAMP)"
                ),
                {"r": run_id},
            )
            conn.execute(
                sa.text(
                    "INSERT INTO sample_chunk (run_id, seq, first_sample, n_samples, last_t_s, created_at)"
                    " VALUES (:r, 0, 0, 100, 1.0, CURRENT_TIMESTAMP)"
                ),
                {"r": run_id},
            )


# the run table as revision 0004 has it (the models follow the newest revision)
RUN_0004 = sa.table(
    "run",
    sa.column("id", sa.String),
    sa.column("state", sa.String),
    sa.column("params", sa.JSON),
    sa.column("kind", sa.String),
    sa.column("requested_dwell_s", sa.Double),
    sa.column("drift_night", sa.String),
    sa.column("sim_age_days", sa.Double),
    sa.column("abort_request", sa.Text),
    sa.column("control_seq", sa.Integer),
    sa.column("control_action", sa.String),
    sa.column("resume_requested", sa.Boolean),
    sa.column("finishing_since", UtcDateTime()),
    sa.column("auto_resume", sa.JSON),
    sa.column("live_progress", sa.JSON),
    sa.column("final_event", sa.JSON),
)


def _check_upgrade_and_downgrade(engine: Engine) -> None:
    _fill_at_0003(engine)
    children = _children(engine)
    assert set(children.values()) == {len(RUNS)}
    upgrade(engine, "0004")
    assert _children(engine) == children  # no row that refers to a run goes with the copy of run
    assert current_revision(engine) == "0004"
    with engine.connect() as conn:
        rows = {row.id: row for row in conn.execute(sa.select(RUN_0004))}
        assert conn.scalar(sa.text("SELECT count(*) FROM run_audit")) == 0
    for run_id, (state, params, columns) in RUNS.items():
        run = rows[run_id]
        assert run.state == state
        assert run.params == _expected_params(params), run_id
        got = {name: getattr(run, name) for name in columns}
        assert got == columns, run_id
    downgrade(engine, "0003")
    assert _children(engine) == children
    with engine.connect() as conn:
        stored = dict(conn.execute(sa.select(RUN.c.id, RUN.c.params)).all())
    for run_id, (_, params, _) in RUNS.items():
        assert stored[run_id] == params, run_id
    assert "run_audit" not in sa.inspect(engine).get_table_names()


def test_0004_moves_every_value(empty_engine: Engine) -> None:
    """On SQLite and on PostgreSQL (``tests.pg.empty_engine``)."""
    _check_upgrade_and_downgrade(empty_engine)


def test_the_moved_values_work_after_the_upgrade(empty_engine: Engine) -> None:
    """The claim and the control look-up read the migrated columns: a resume queued and the
    requests asked before the upgrade are seen after it."""
    from db.engine import make_session_factory
    from db.repo.queue import claim_next_run, pending_control

    _fill_at_0003(empty_engine)
    upgrade(empty_engine)
    with make_session_factory(empty_engine).begin() as s:
        pending = pending_control(s, "R-DRIFT")
        assert (pending.abort, pending.seq, pending.action) == ("operator abort over REST", 1, "pause")
        assert pending_control(s, "R-CLI") == type(pending)(None, 0, None)
        s.execute(sa.update(RUN).where(RUN.c.id != "R-DRIFT").values(state="completed"))
        claimed = claim_next_run(s, 1, owner_pid=4242, owner_host="h")
    # the resume requested before the upgrade is claimed as a resume, of a drift check
    assert claimed is not None and claimed.run_id == "R-DRIFT" and claimed.kind == "drift_check"
    assert claimed.point is not None and claimed.point.next_window_index == 0
    with make_session_factory(empty_engine).begin() as s:
        from db.models import Run

        run = s.get(Run, "R-DRIFT")
        assert run is not None and run.state.value == "running" and not run.resume_requested
        assert run.abort_request is None and run.resume_count == 2
