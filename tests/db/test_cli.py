"""``calbench runs [--json]`` and ``calbench db``, on SQLite and PostgreSQL."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from api.cli import main
from db.models import RunState
from db.repo import progress
from tests.db._factories import make_run


def _url(engine) -> str:
    return engine.url.render_as_string(hide_password=False)


def _dead_pid() -> int:
    out = subprocess.run(
        [sys.executable, "-c", "import os; print(os.getpid())"], capture_output=True, check=True
    )
    return int(out.stdout)


def test_runs_json_lists_runs_and_shows_dead_ones_interrupted(db_engine, db_session_factory, capsys):
    host = socket.gethostname()
    with db_session_factory.begin() as s:
        make_run(s, "R-dead", "SN-1", state=RunState.RUNNING, owner_pid=_dead_pid(), owner_host=host)
        make_run(s, "R-live", "SN-2", state=RunState.RUNNING, owner_pid=os.getpid(), owner_host=host)
        progress.record_window(s, "R-live", 0, start_s=0.0, end_s=10.0, n_samples=1000)
        make_run(s, "R-done", "SN-1", state=RunState.COMPLETED)
    assert main(["runs", "--json", "--database-url", _url(db_engine)]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert [r["id"] for r in rows] == ["R-done", "R-live", "R-dead"]
    by_id = {r["id"]: r for r in rows}
    assert {k: by_id["R-dead"][k] for k in ("unit_serial", "procedure", "state")} == {
        "unit_serial": "SN-1",
        "procedure": "static-12",
        "state": "interrupted",
    }
    assert by_id["R-live"]["state"] == "running" and by_id["R-live"]["last_complete_window"] == 0
    assert by_id["R-done"]["state"] == "completed"
    assert by_id["R-dead"]["bench"] == "bench-a" and "gone" in by_id["R-dead"]["error"]
    for row in rows:
        assert {"id", "unit_serial", "procedure", "state", "outcome", "progress", "started_at"} <= row.keys()


def test_runs_filters_and_table(db_engine, db_session_factory, capsys):
    with db_session_factory.begin() as s:
        make_run(s, "R-1", "SN-1", state=RunState.COMPLETED)
        make_run(s, "R-2", "SN-2", state=RunState.COMPLETED)
    assert main(["runs", "--json", "--unit", "SN-2", "--database-url", _url(db_engine)]) == 0
    assert [r["id"] for r in json.loads(capsys.readouterr().out)] == ["R-2"]
    assert main(["runs", "--database-url", _url(db_engine)]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert lines[0].split() == [
        "id",
        "unit",
        "procedure",
        "state",
        "outcome",
        "progress",
        "windows",
        "started",
    ]
    assert [ln.split()[0] for ln in lines[1:]] == ["R-2", "R-1"]


def test_runs_on_a_fresh_default_database_is_empty_list(tmp_path, monkeypatch, capsys):
    monkeypatch.delenv("CALBENCH_DATABASE_URL", raising=False)
    monkeypatch.setenv("CALBENCH_DATA_DIR", str(tmp_path))
    assert main(["runs", "--json"]) == 0
    assert json.loads(capsys.readouterr().out) == []
    assert (tmp_path / "calbench.db").is_file()


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["runs", "--limit", "0"], "--limit must be >= 1"),
        (["runs", "--database-url", "mysql://u@h/db"], "backend 'mysql' not supported"),
        (
            ["runs", "--database-url", "postgresql://postgres@127.0.0.1:1/none"],
            "cannot use database postgresql://",
        ),
        (["db", "current", "--database-url", "sqlite://"], "in-memory SQLite"),
    ],
)
def test_bad_input_exits_2_with_one_line(argv, message, capsys):
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "\n" not in err


def test_db_upgrade_and_current(tmp_path, capsys):
    # the newest revision file in the chain (revisions are numbered 0001, 0002, ...)
    versions = Path(__file__).resolve().parents[2] / "db" / "migrations" / "versions"
    head = max(p.name.split("_", 1)[0] for p in versions.glob("[0-9][0-9][0-9][0-9]_*.py"))
    url = f"sqlite:///{tmp_path / 'u.db'}"
    assert main(["db", "current", "--database-url", url]) == 0
    assert "empty (behind" in capsys.readouterr().out
    assert main(["db", "upgrade", "--database-url", url]) == 0
    assert f"empty -> {head}" in capsys.readouterr().out
    assert main(["db", "current", "--database-url", url]) == 0
    assert f"{head} (up to date)" in capsys.readouterr().out
