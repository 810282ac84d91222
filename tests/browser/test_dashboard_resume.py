"""The run page's Pause, Continue and Resume controls in headless Chromium.

A run is started over REST and the service stops with it live (its lifespan ends), so the
run is stored ``interrupted``. On a new service over the same database an operator opens the
run page, presses Resume and follows the resumed run live to its certificate; a viewer sees
the controls disabled. A second run is paused and continued from the page.
"""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import httpx
import pytest

from tests.browser.conftest import BROWSER
from tests.browser.live_server import live_service
from tests.browser.test_dashboard import DESK, ConsoleWatch, shot
from tests.support.service_helpers import OP, OPERATOR, VIEW, VIEWER, service_settings

pytestmark = [*BROWSER, pytest.mark.timeout(600)]
DEADLINE_S = 240.0


def poll(base: str, run_id: str, cond: Any, what: str) -> dict[str, Any]:
    deadline = time.monotonic() + DEADLINE_S
    while time.monotonic() < deadline:
        run = httpx.get(f"{base}/api/runs/{run_id}", headers=VIEW, timeout=30).json()
        if cond(run):
            return run
        time.sleep(0.2)
    raise AssertionError(f"waited {DEADLINE_S} s for {what}: {run}")


def page_as(browser: Any, token: str) -> tuple[Any, Any, ConsoleWatch]:
    ctx = browser.new_context(viewport=DESK)
    ctx.add_init_script(f"localStorage.setItem('calbench.token', {json.dumps(token)})")
    page = ctx.new_page()
    return ctx, page, ConsoleWatch(page)


def test_resume_pause_and_continue_from_the_run_page(tmp_path: Path, browser: Any) -> None:
    settings = service_settings(tmp_path, sim_speed=20.0, bench_name="bench-ui-resume")
    with live_service(settings) as base:
        r = httpx.post(
            f"{base}/api/runs",
            json={"unit_serial": "SN-UI-RES", "procedure": "static-12"},
            headers=OP,
            timeout=30,
        )
        run_id = r.json()["id"]
        poll(base, run_id, lambda b: (b.get("last_complete_window") or -1) >= 2, "three windows")
    with live_service(settings) as base:
        assert poll(base, run_id, lambda b: True, "the run")["state"] == "interrupted"
        viewer_ctx, vpage, _ = page_as(browser, VIEWER)
        vpage.goto(f"{base}/#/runs/{run_id}")
        vpage.wait_for_selector("#resume-run")
        assert vpage.is_disabled("#resume-run") and vpage.is_visible("#interrupted-note")
        viewer_ctx.close()

        ctx, page, console = page_as(browser, OPERATOR)
        page.goto(f"{base}/#/runs/{run_id}")
        page.wait_for_selector("#resume-run:not([disabled])")
        assert "interrupted" in page.inner_text("#run-state") and page.is_hidden("#pause-run")
        shot(page, "desk-run-interrupted")
        page.click("#resume-run")
        page.wait_for_selector("#run-state .badge.running", timeout=DEADLINE_S * 1000)
        assert page.is_visible("#pause-run") and page.is_hidden("#resume-run")
        page.wait_for_selector("#certificate strong", timeout=DEADLINE_S * 1000)
        assert "completed" in page.inner_text("#run-state")
        body = poll(base, run_id, lambda b: b.get("certificate_number"), "the certificate")
        assert page.inner_text("#certificate strong") == body["certificate_number"]
        shot(page, "desk-run-resumed")

        r = httpx.post(
            f"{base}/api/runs",
            json={"unit_serial": "SN-UI-PAUSE", "procedure": "static-12"},
            headers=OP,
            timeout=30,
        )
        second = r.json()["id"]
        page.goto(f"{base}/#/runs/{second}")
        page.wait_for_selector("#pause-run:visible:not([disabled])")
        page.click("#pause-run")
        page.wait_for_selector("#run-state .badge.paused", timeout=DEADLINE_S * 1000)
        assert page.is_visible("#continue-run") and page.is_hidden("#pause-run")
        shot(page, "desk-run-paused")
        page.click("#continue-run")
        page.wait_for_selector("#certificate strong", timeout=DEADLINE_S * 1000)
        done = poll(base, second, lambda b: b.get("certificate_number"), "the certificate")
        assert done["state"] == "completed"
        # The page shows the run's audit trail as stored: who started it, every action and state.
        page.wait_for_selector("#run-audit:visible")
        rows = page.locator("#run-audit-rows tr")
        assert rows.count() == len(done["audit"])
        cells = [rows.nth(i).inner_text() for i in range(rows.count())]
        for cell, stored in zip(cells, done["audit"], strict=True):
            assert stored["actor"] in cell and stored["at"][:19].replace("T", " ") in cell
        assert any("pause requested" in c for c in cells) and any("state: paused" in c for c in cells)
        assert page.inner_text("#run-started-by") == f" · started by {done['started_by']}"
        shot(page, "desk-run-audit")
        assert console.errors == []
        ctx.close()
