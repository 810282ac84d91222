"""A completed run of a unit whose model has no limits shows no PASS or FAIL on any page: the
run page, the overview's run list and the unit's history say "no conformity statement" and why."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import httpx
import pytest
from playwright.sync_api import expect

from tests.browser.conftest import BROWSER
from tests.browser.live_server import live_service
from tests.browser.test_dashboard import DESK, ConsoleWatch
from tests.support.service_helpers import OP, OPERATOR, VIEW, service_settings

RUN_TIMEOUT_S = 240.0
NOTE = "no conformity statement: no limits are configured for model ADXL335"

pytestmark = [*BROWSER, pytest.mark.timeout(600)]


@pytest.fixture(scope="module")
def finished_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, str]]:
    """The service and the id of a completed run of SN-335, registered as model ADXL335 (the
    limits file has ADXL325 only)."""
    settings = service_settings(tmp_path_factory.mktemp("nolimits"), sim_speed=20.0, bench_name="bench-nl")
    with live_service(settings) as base:
        r = httpx.put(f"{base}/api/units/SN-335", json={"model": "ADXL335"}, headers=OP, timeout=30)
        assert r.status_code == 200, r.text
        r = httpx.post(
            f"{base}/api/runs", json={"unit_serial": "SN-335", "procedure": "static-12"}, headers=OP
        )
        assert r.status_code == 202, r.text
        run_id = r.json()["id"]
        deadline = time.monotonic() + RUN_TIMEOUT_S
        while time.monotonic() < deadline:
            run = httpx.get(f"{base}/api/runs/{run_id}", headers=VIEW, timeout=30).json()
            if run["state"] not in ("queued", "running", "paused", "suspended"):
                break
            time.sleep(0.2)
        assert run["state"] == "completed", run
        yield base, run_id


def _page(browser: Any, base: str, path: str) -> tuple[Any, Any, ConsoleWatch]:
    ctx = browser.new_context(viewport=DESK)
    ctx.add_init_script(f"localStorage.setItem('calbench.token', '{OPERATOR}')")
    page = ctx.new_page()
    console = ConsoleWatch(page)
    page.goto(f"{base}/{path}")
    return ctx, page, console


def _no_verdict_word(text: str) -> None:
    assert "PASS" not in text and "FAIL" not in text, text


def test_the_run_page_states_no_conformity_and_why(browser: Any, finished_run: tuple[str, str]) -> None:
    base, run_id = finished_run
    ctx, page, console = _page(browser, base, f"#/runs/{run_id}")
    expect(page.locator("#verdict-outcome")).to_have_text(NOTE, timeout=30_000)
    expect(page.locator("#run-step")).to_have_text(f"ended completed ({NOTE})")
    expect(page.locator("#limit-checks")).to_contain_text(NOTE)
    _no_verdict_word(page.inner_text("main") if page.locator("main").count() else page.inner_text("body"))
    assert console.errors == []
    ctx.close()


def test_the_run_list_and_the_unit_history_state_no_conformity(
    browser: Any, finished_run: tuple[str, str]
) -> None:
    base, run_id = finished_run
    ctx, page, console = _page(browser, base, "#/")
    link = page.locator(f"a[href='#/runs/{run_id}']").first
    expect(link).to_be_visible(timeout=30_000)
    row = page.locator("tr", has=page.locator(f"a[href='#/runs/{run_id}']"))
    expect(row).to_contain_text(NOTE)
    _no_verdict_word(row.inner_text())
    page.goto(f"{base}/#/units/SN-335")
    row = page.locator("section[aria-label='Runs'] tr", has=page.locator(f"a[href='#/runs/{run_id}']"))
    expect(row).to_contain_text(NOTE, timeout=30_000)
    _no_verdict_word(row.inner_text())
    assert console.errors == []
    ctx.close()
