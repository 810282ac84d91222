"""The run page states the samples a run lost: each gap, where it is and what was done."""

from __future__ import annotations

import datetime as dt
from collections.abc import Iterator
from typing import Any

import pytest

from bench.records import GapRecord
from db.engine import make_session_factory
from db.migrate import open_database
from db.models import RunState
from db.repo.gaps import replace_gaps
from db.repo.runs import create_run
from db.repo.units import get_or_create_unit
from station.settings import Settings
from tests.browser.conftest import BROWSER
from tests.browser.live_server import live_service
from tests.support.service_helpers import VIEWER, service_settings

pytestmark = [*BROWSER, pytest.mark.timeout(300)]

GAPS = (
    GapRecord(1200, 37, "dropped", 1200, 6.0, 6.19, 2, "pos02", "window re-measured"),
    GapRecord(5100, 4000, "overflow", 5063, 25.31, 45.315, None, "", "between windows"),
)


def store_runs(settings: Settings) -> None:
    engine = open_database(settings.effective_database_url)
    with make_session_factory(engine).begin() as s:
        unit = get_or_create_unit(s, "SN-GAP-UI", channel_unit="V")
        t0 = dt.datetime(2025, 1, 1, tzinfo=dt.UTC)
        for run_id, gaps in (("run-gaps-ui", GAPS), ("run-clean-ui", ())):
            run = create_run(
                s,
                run_id,
                unit.id,
                "static-12",
                state=RunState.ERROR,
                now=t0,
            )
            replace_gaps(s, run_id, gaps)
            run.started_at, run.finished_at, run.n_samples, run.error = t0, t0, 40_000, "stopped for the test"
    engine.dispose()


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    settings = service_settings(tmp_path_factory.mktemp("gaps-ui"))
    with live_service(settings) as base:
        store_runs(settings)
        yield base


def test_the_run_page_lists_the_gaps_and_says_none_when_there_were_none(service: str, browser: Any) -> None:
    page = browser.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.on("console", lambda m: errors.append(m.text) if m.type == "error" else None)
    page.goto(f"{service}/")
    page.fill("#token-input", VIEWER)
    page.click("#token-form button[type=submit]")
    page.goto(f"{service}/#/runs/run-gaps-ui")
    page.wait_for_selector("#run-gaps")
    text = page.inner_text("#run-gaps")
    assert text.startswith("4037 in 2 gaps"), text
    assert "37 at 6.000 s (dropped; window pos02 re-measured)" in text
    assert "4000 at 25.310 s (overflow; between windows)" in text
    page.goto(f"{service}/#/runs/run-clean-ui")
    page.wait_for_selector("#run-gaps")
    assert page.inner_text("#run-gaps") == "none"
    assert not errors, errors
