"""Sample gaps stored on a run reach GET /api/runs/{id} (each gap), the run lists (the count)
and the certificate's conditions (one line)."""

from __future__ import annotations

import dataclasses
import datetime as dt
from pathlib import Path

from fastapi.testclient import TestClient

from api.main import create_app
from bench.records import GapRecord
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import RunState
from db.repo.gaps import replace_gaps
from db.repo.runs import create_run
from db.repo.units import get_or_create_unit
from station.certificates.certificate import sample_integrity
from tests.support.service_helpers import VIEW, service_settings

GAPS = (
    GapRecord(1200, 37, "dropped", 1200, 6.0, 6.19, 2, "pos02", "window re-measured"),
    GapRecord(5100, 4000, "overflow", 5063, 25.31, 45.315, None, "", "between windows"),
)


def test_gaps_are_returned_with_the_run_and_counted_in_lists(tmp_path: Path) -> None:
    settings = service_settings(tmp_path)
    app = create_app(settings, start_scheduler=False)
    with TestClient(app) as client:
        engine = open_database(settings.effective_database_url)
        with make_session_factory(engine).begin() as s:
            unit = get_or_create_unit(s, "SN-GAP", channel_unit="V")
            create_run(
                s,
                "run-gaps",
                unit.id,
                "static-12",
                params={"bench": "bench-a"},
                state=RunState.ERROR,
                now=dt.datetime(2025, 1, 1, tzinfo=dt.UTC),
            )
            replace_gaps(s, "run-gaps", GAPS)
            create_run(s, "run-clean", unit.id, "static-12", params={}, state=RunState.ERROR)
        engine.dispose()
        body = client.get("/api/runs/run-gaps", headers=VIEW).json()
        assert body["n_samples_lost"] == 37 + 4000
        assert [(g["after_row"], g["n_lost"], g["cause"], g["action"]) for g in body["gaps"]] == [
            (1200, 37, "dropped", "window re-measured"),
            (5063, 4000, "overflow", "between windows"),
        ]
        assert body["gaps"][0]["window_label"] == "pos02" and body["gaps"][1]["t_resume_s"] == 45.315
        listed = {r["id"]: r for r in client.get("/api/runs", headers=VIEW).json()}
        assert listed["run-gaps"]["gaps"] is None and listed["run-gaps"]["n_samples_lost"] == 4037
        assert client.get("/api/runs/run-clean", headers=VIEW).json()["gaps"] == []


def test_the_certificate_line_counts_what_was_lost_and_what_was_re_measured() -> None:
    line = sample_integrity([dataclasses.asdict(g) for g in GAPS])
    assert (
        line.startswith("4037 samples lost in 2 gaps")
        and "1 fell inside a window, which was re-measured" in line
    )
    restart = dataclasses.replace(GAPS[1], n_lost=None, cause="restart")
    assert "unknown number" in sample_integrity([dataclasses.asdict(restart)])
    assert sample_integrity([]) == "every sample the DAQ produced was recorded (no gap)"
