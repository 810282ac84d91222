"""The dashboard in headless Chromium against a live service on loopback with a simulated bench.

An operator pastes a token, starts a static-12 run from the page, watches the progress bar
move with the event stream, sees the results (|g| check, residuals, Allan curve, diagnosis),
downloads the certificate (JSON and PDF), opens the unit's history with its trend plots;
then the same pages at phone size. No console errors anywhere. Screenshots go to
``test-artifacts/screenshots/``.
"""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest

from api.plots.colours import CHANNEL_COLOURS
from tests.browser.conftest import BROWSER
from tests.browser.live_server import live_service
from tests.support.service_helpers import OP, OPERATOR, VIEW, VIEWER, service_settings

expect = pytest.importorskip("playwright.sync_api").expect

SHOTS = Path(__file__).resolve().parents[2] / "test-artifacts" / "screenshots"
DESK = {"width": 1440, "height": 900}
PHONE = {"width": 390, "height": 844}
RUN_TIMEOUT_S = 240.0

pytestmark = [*BROWSER, pytest.mark.timeout(600)]


def _rgb(hex_colour: str) -> tuple[int, int, int]:
    """``#rrggbb`` as three 0-255 integers."""
    return int(hex_colour[1:3], 16), int(hex_colour[3:5], 16), int(hex_colour[5:7], 16)


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    settings = service_settings(tmp_path_factory.mktemp("dashboard"), sim_speed=20.0, bench_name="bench-ui")
    with live_service(settings) as base:
        yield base


class ConsoleWatch:
    """Collects console errors and uncaught page exceptions of a page."""

    def __init__(self, page: Any) -> None:
        self.errors: list[str] = []
        page.on("console", lambda m: self.errors.append(f"console: {m.text}") if m.type == "error" else None)
        page.on("pageerror", lambda e: self.errors.append(f"pageerror: {e}"))


def open_new_run(
    service: str, browser: Any, serial: str, procedure: str = "static-12", page_path: str | None = None
) -> tuple[str, Any, Any, ConsoleWatch]:
    """Start ``procedure`` for ``serial`` over the API as the operator and open its run page (or
    ``page_path``): the run id, the browser context, the page and its console watch."""
    created = httpx.post(
        f"{service}/api/runs", json={"unit_serial": serial, "procedure": procedure}, headers=OP
    )
    assert created.status_code == 202, created.text
    run_id = created.json()["id"]
    ctx = browser.new_context(viewport=DESK)
    ctx.add_init_script(f"localStorage.setItem('calbench.token', '{OPERATOR}')")
    page = ctx.new_page()
    console = ConsoleWatch(page)
    page.goto(f"{service}{page_path if page_path is not None else f'/#/runs/{run_id}'}")
    return run_id, ctx, page, console


def shot(page: Any, name: str) -> None:
    SHOTS.mkdir(parents=True, exist_ok=True)
    page.screenshot(path=str(SHOTS / f"{name}.png"), full_page=True)


def watch_progress(page: Any, timeout_s: float) -> list[int]:
    """Progress percentages the page showed, sampled until the results are shown."""
    seen: list[int] = []
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if page.locator("#results section").count():
            return seen
        value = page.get_attribute("[role=progressbar][aria-label='run progress']", "aria-valuenow")
        if value is not None and (not seen or seen[-1] != int(value)):
            seen.append(int(value))
        page.wait_for_timeout(150)
    raise AssertionError(f"the run page showed no results within {timeout_s} s; progress seen {seen}")


def test_operator_runs_a_calibration_from_the_dashboard(service: str, browser: Any, tmp_path: Path) -> None:
    ctx = browser.new_context(viewport=DESK, accept_downloads=True)
    page = ctx.new_page()
    console = ConsoleWatch(page)
    page.goto(f"{service}/")
    # without a token the lab's dashboard says what it needs
    page.wait_for_selector("#notice:not([hidden])")
    assert "token" in page.inner_text("#notice")
    assert page.is_disabled("#start-run")
    page.fill("#token-input", OPERATOR)
    page.click("#token-form button[type=submit]")
    # a locator wait, not wait_for_function: its polling evaluates a string, which the CSP forbids
    expect(page.locator("#role")).to_have_text("operator")
    page.wait_for_selector("#start-run:not([disabled])")
    shot(page, "desk-overview-empty")

    page.fill("#start-serial", "SN-UI-0001")
    page.select_option("#start-procedure", "static-12")
    page.click("#start-run")
    page.wait_for_url("**/#/runs/*")
    run_id = page.url.split("#/runs/")[1]
    page.wait_for_selector("#run-step:not(:text('–'))", timeout=60_000)
    shot(page, "desk-run-live")
    seen = watch_progress(page, RUN_TIMEOUT_S)
    moving = [v for v in seen if 0 < v < 100]
    assert len(set(moving)) >= 3, f"the progress bar did not move while the run recorded: {seen}"
    assert moving == sorted(moving), f"progress went backwards: {seen}"
    assert page.locator("#windows tbody tr").count() >= 6  # windows listed as the stream reports them

    # results of the finished run
    assert "completed" in page.inner_text("#run-state"), page.inner_text("#results")
    for sel in ("#g-check svg", "#residuals svg", "#allan svg", "#diagnosis"):
        page.wait_for_selector(sel, timeout=30_000)
    assert page.get_attribute("[role=progressbar][aria-label='run progress']", "aria-valuenow") == "100"
    assert "completed" in page.inner_text("#run-state")
    number = page.inner_text("#certificate strong")
    assert number.startswith("CB-")
    # 12 windows of 3 channels in the residual plot, 12 windows in the |g| plot
    assert page.locator("#residuals svg rect[fill^='var(--c']").count() == 36
    # drawn in the channel colours of api.plots.colours (served as /channel-colours.css)
    fills = page.locator("#residuals svg rect[fill^='var(--c']").evaluate_all(
        "els => els.slice(0, 3).map((e) => getComputedStyle(e).fill)"
    )
    assert fills == [f"rgb({r}, {g}, {b})" for r, g, b in (_rgb(c) for c in CHANNEL_COLOURS)]
    assert page.locator("#g-check svg circle").count() == 12
    # the first run of a V unit has no 'before' until the datasheet values are given
    assert "enter the datasheet values" in page.inner_text("#g-check")
    page.fill("#nominal-sens", "0.174")
    page.fill("#nominal-zero", "1.5")
    page.click("#g-check button[type=submit]")
    page.wait_for_selector("#g-check figure >> nth=1")
    assert "before (nominal scale" in page.inner_text("#g-check")
    assert page.locator("#g-check svg circle").count() == 24
    page.wait_for_timeout(300)
    shot(page, "desk-run-results")

    with page.expect_download() as dl:
        page.click("#download-json")
    path = tmp_path / "certificate.json"
    dl.value.save_as(str(path))
    cert = json.loads(path.read_text())
    assert cert["number"] == number and cert["run_id"] == run_id and len(cert["sha256"]) == 64
    # the PDF link is signed by the service (POST /api/links) after the card is drawn
    page.wait_for_selector("#pdf-link[href*='link=']")
    pdf_href = page.get_attribute("#pdf-link", "href")
    assert pdf_href is not None and OPERATOR not in pdf_href
    assert pdf_href is not None
    pdf = page.request.get(f"{service}/{pdf_href.lstrip('/')}")
    assert pdf.status == 200 and pdf.headers["content-type"] == "application/pdf"
    assert pdf.body().startswith(b"%PDF")

    # a second calibration of the unit (over the API): its |g| 'before' is the first calibration
    body = {"unit_serial": "SN-UI-0001", "procedure": "static-12"}
    second = httpx.post(f"{service}/api/runs", json=body, headers=OP)
    assert second.status_code == 202, second.text
    run2 = second.json()["id"]
    page.goto(f"{service}/#/runs/{run2}")
    watch_progress(page, RUN_TIMEOUT_S)
    page.wait_for_selector("#g-check svg >> nth=1", timeout=30_000)
    assert f"previous calibration ({run_id})" in page.inner_text("#g-check")
    assert page.locator("#g-check svg circle").count() == 24

    # a drift check of the unit against its last certificate (queued over the API)
    queued = httpx.post(f"{service}/api/drift/run", json={"unit_serial": "SN-UI-0001"}, headers=OP)
    assert queued.status_code == 202, queued.text
    checks: list[Any] = []
    deadline = time.monotonic() + RUN_TIMEOUT_S
    while not checks and time.monotonic() < deadline:
        time.sleep(0.5)
        params = {"unit_serial": "SN-UI-0001"}
        checks = httpx.get(f"{service}/api/drift/checks", params=params, headers=VIEW).json()
    assert checks, "the drift check did not finish"

    # the unit's history: trend sparklines with bands over both runs, certificates, the drift check
    page.click("a[href='#/units/SN-UI-0001']")
    page.wait_for_selector("#trends svg")
    assert page.locator("#trends figure").count() == 12
    spark = page.locator("#trends figure >> nth=0").locator("circle")
    assert spark.count() == 3  # two calibrations and the drift check's own fit
    assert spark.nth(2).get_attribute("fill") == "#fff"  # the drift check drawn open
    assert number in page.inner_text("main")
    drift_row = page.locator("section[aria-label='Drift checks'] tbody tr")
    assert drift_row.count() == 1
    assert ("flagged" if checks[0]["flagged"] else "ok") in drift_row.inner_text()
    shot(page, "desk-unit-history")
    assert console.errors == []
    ctx.close()

    # the same pages on a phone, with the viewer token (read-only)
    phone = browser.new_context(viewport=PHONE, device_scale_factor=2, is_mobile=True, has_touch=True)
    phone.add_init_script(f"localStorage.setItem('calbench.token', {json.dumps(VIEWER)})")
    p2 = phone.new_page()
    console2 = ConsoleWatch(p2)
    p2.goto(f"{service}/")
    expect(p2.locator("#role")).to_have_text("viewer")
    assert p2.is_disabled("#start-run")
    p2.wait_for_selector("table")
    shot(p2, "phone-overview")
    p2.goto(f"{service}/#/runs/{run2}")
    p2.wait_for_selector("#allan svg")
    assert p2.is_disabled("#abort-run")
    wide = p2.evaluate("document.documentElement.scrollWidth")
    assert wide <= PHONE["width"] + 1, f"the run page scrolls sideways on a phone ({wide} px)"
    shot(p2, "phone-run-results")
    p2.goto(f"{service}/#/units/SN-UI-0001")
    p2.wait_for_selector("#trends svg")
    shot(p2, "phone-unit-history")
    assert console2.errors == []
    phone.close()

    # what the page showed agrees with the API
    body = httpx.get(f"{service}/api/runs/{run_id}", headers=VIEW).json()
    assert body["certificate_number"] == number and body["state"] == "completed"
