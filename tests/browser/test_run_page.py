"""The run page tells the operator what happened without a reload, and a reload loses nothing.

Against a live simulated service: the start form previews poses, windows and duration; the
page of a run started there ends showing its final state and a prominent PASS with the limit
checks and their decision rule, no "between windows" left over; a reload keeps the completed
windows; the overview lists the outcome; the settings' missing laboratory identity is named on
every page. Over the API, a run that reads ``completed`` already has its certificate.
"""

from __future__ import annotations

import re
import time
from collections.abc import Iterator
from typing import Any

import httpx
import pytest
from playwright.sync_api import expect

from bench.procedures import build_procedure, preview
from tests.browser.conftest import BROWSER
from tests.browser.live_server import live_service
from tests.browser.test_dashboard import DESK, ConsoleWatch, shot
from tests.support.service_helpers import OP, OPERATOR, VIEW, service_settings

RUN_TIMEOUT_S = 240.0
N_POSES = len(preview(build_procedure("static-12", dwell_s=3.0)).poses_deg)

pytestmark = [*BROWSER, pytest.mark.timeout(600)]


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    settings = service_settings(tmp_path_factory.mktemp("runpage"), sim_speed=20.0, bench_name="bench-rp")
    with live_service(settings) as base:
        yield base


def _operator_page(browser: Any, service: str) -> tuple[Any, Any, ConsoleWatch]:
    ctx = browser.new_context(viewport=DESK)
    ctx.add_init_script(f"localStorage.setItem('calbench.token', '{OPERATOR}')")
    page = ctx.new_page()
    console = ConsoleWatch(page)
    page.goto(f"{service}/")
    # locator waits, not wait_for_function: its polling evaluates a string, which the CSP forbids
    expect(page.locator("#role")).to_have_text("operator")
    return ctx, page, console


def test_run_page_ends_with_the_verdict_and_a_reload_keeps_the_windows(service: str, browser: Any) -> None:
    ctx, page, console = _operator_page(browser, service)
    # the missing laboratory identity is named (a simulated bench still issues, marked as such)
    page.wait_for_selector("#config-notice:not([hidden])")
    assert "CALBENCH_LAB_ADDRESS" in page.inner_text("#config-notice")
    # before Start: poses, windows, dwell and duration of the chosen procedure
    expect(page.locator("#start-preview")).to_contain_text("poses")
    text = page.inner_text("#start-preview")
    assert f"{N_POSES} poses" in text and "dwell 3 s per pose (service setting)" in text, text
    assert "about" in text, text
    page.fill("#start-serial", "SN-RP-1")
    page.click("#start-run")
    page.wait_for_url("**/#/runs/*")
    run_id = page.url.split("#/runs/")[1]
    page.wait_for_selector("#verdict:not([hidden])", timeout=RUN_TIMEOUT_S * 1000)
    # the page ends in the final state by itself: no reload
    assert page.inner_text("#verdict-outcome") == "PASS"
    assert "completed" in page.inner_text("#run-state")
    assert page.inner_text("#run-step").startswith("ended completed (PASS)")
    assert "between windows" not in page.inner_text("#run-window")
    page.wait_for_selector("#limit-checks table")
    rows = page.locator("#limit-checks tbody tr")
    assert rows.count() == 13
    assert "simple acceptance" in page.inner_text("#limit-checks caption")
    # the fit in data-sheet units beside the raw form, noise in µg/√Hz and µg
    page.wait_for_selector("#allan table")
    fit = page.inner_text("section[aria-label='Fitted model']")
    assert "S (mV/g)" in fit and "mrad" in fit and "scale matrix K (V per m/s²)" in fit
    assert "density (µg/√Hz)" in page.inner_text("#allan") and "bias instability (µg)" in page.inner_text(
        "#allan"
    )
    # the correction leaves the building from the certificate card
    # the link is signed for the page (POST /api/links): the token never goes into the URL
    link = page.locator("#exports a[data-format='c-header']")
    expect(link).to_have_attribute("href", re.compile(r"\?link="))
    href = link.get_attribute("href")
    assert href is not None
    header = page.request.get(f"{service}/{href.lstrip('/')}")
    assert header.status == 200 and "calbench_correct" in header.text()
    assert page.locator("#exports a").count() == 4
    n_windows = page.locator("#windows tbody tr").count()
    assert n_windows >= 12
    shot(page, "desk-run-verdict")
    # a reload keeps the completed windows and the verdict
    page.reload()
    page.wait_for_selector("#verdict:not([hidden])")
    assert page.locator("#windows tbody tr").count() == n_windows
    assert page.inner_text("#verdict-outcome") == "PASS"
    # the overview has the outcome column
    page.goto(f"{service}/#/")
    page.wait_for_selector(f"a[href='#/runs/{run_id}']")
    row = page.locator("tr", has=page.locator(f"a[href='#/runs/{run_id}']"))
    assert "PASS" in row.inner_text()
    assert "No nightly drift check is scheduled" in page.inner_text("#drift-schedule")
    assert console.errors == []
    ctx.close()


def test_completed_run_has_its_certificate_at_once(service: str) -> None:
    created = httpx.post(
        f"{service}/api/runs", json={"unit_serial": "SN-RP-2", "procedure": "static-12"}, headers=OP
    )
    assert created.status_code == 202, created.text
    run_id = created.json()["id"]
    deadline = time.monotonic() + RUN_TIMEOUT_S
    states: list[str] = []
    while time.monotonic() < deadline:
        run = httpx.get(f"{service}/api/runs/{run_id}", headers=VIEW).json()
        states.append(run["state"])
        if run["state"] not in ("queued", "running", "paused", "suspended"):
            break
        time.sleep(0.05)
    assert run["state"] == "completed", states[-5:]
    # the first answer that says completed already carries the certificate
    assert run["certificate_number"] is not None
    cert = httpx.get(f"{service}/api/runs/{run_id}/certificate", headers=VIEW)
    assert cert.status_code == 200
    assert cert.json()["content"]["conformity"]["outcome"] == run["outcome"] == "PASS"


def _calibrated(service: str, serial: str) -> dict[str, Any]:
    """Run static-12 for ``serial`` over the API and return the finished run."""
    created = httpx.post(
        f"{service}/api/runs", json={"unit_serial": serial, "procedure": "static-12"}, headers=OP
    )
    assert created.status_code == 202, created.text
    run_id = created.json()["id"]
    deadline = time.monotonic() + RUN_TIMEOUT_S
    while time.monotonic() < deadline:
        run = httpx.get(f"{service}/api/runs/{run_id}", headers=VIEW).json()
        if run["state"] not in ("queued", "running", "paused", "suspended"):
            return run
        time.sleep(0.2)
    raise AssertionError(f"run {run_id} did not finish within {RUN_TIMEOUT_S} s")


def test_a_unit_registered_from_the_page_is_stated_on_its_certificate(service: str, browser: Any) -> None:
    ctx, page, console = _operator_page(browser, service)
    page.fill("#start-serial", "SN-RP-3")
    page.click("#unit-details")
    page.wait_for_selector("#registration")
    assert "not registered yet" in page.inner_text("main")
    page.fill("#reg-model", "ADXL325")
    page.fill("#reg-customer", "Acme Sensors Ltd")
    page.fill("#reg-address", "7 Works Lane, Town")
    page.fill("#reg-received", "2026-11-02")
    page.fill("#reg-sensitivity", "174")
    page.fill("#reg-zero", "1.5")
    page.fill("#reg-condition", "no visible damage")
    page.click("#reg-save")
    expect(page.locator("#reg-status")).to_contain_text("Saved")
    unit = httpx.get(f"{service}/api/units", headers=VIEW).json()
    got = next(u for u in unit if u["serial"] == "SN-RP-3")
    assert got["customer_name"] == "Acme Sensors Ltd" and got["received_on"] == "2026-11-02"
    assert got["nominal_scale"] == pytest.approx(0.174 / 9.80665, rel=1e-12)
    created = httpx.post(
        f"{service}/api/runs", json={"unit_serial": "SN-RP-3", "procedure": "static-12"}, headers=OP
    )
    run_id = created.json()["id"]
    deadline = time.monotonic() + RUN_TIMEOUT_S
    while time.monotonic() < deadline:
        run = httpx.get(f"{service}/api/runs/{run_id}", headers=VIEW).json()
        if run["state"] not in ("queued", "running", "paused", "suspended"):
            break
        time.sleep(0.2)
    c = httpx.get(f"{service}/api/runs/{run_id}/certificate", headers=VIEW).json()["content"]
    assert c["customer"] == {
        "name": "Acme Sensors Ltd",
        "address": "7 Works Lane, Town",
        "source": "unit registration",
    }
    assert c["dates"]["received"] == "2026-11-02" and c["item"]["model"] == "ADXL325"
    assert c["item"]["nominal_scale"]["unit"] == "V/(m/s2)"
    # the page of the registered unit shows the saved values again
    page.goto(f"{service}/#/units/SN-RP-3")
    page.wait_for_selector("#registration")
    assert page.input_value("#reg-sensitivity") == "174"
    assert console.errors == []
    ctx.close()


def test_drift_check_started_from_the_unit_page_shows_its_deltas(service: str, browser: Any) -> None:
    _calibrated(service, "SN-RP-4")
    ctx, page, console = _operator_page(browser, service)
    page.goto(f"{service}/#/units/SN-RP-4")
    page.wait_for_selector("#drift-run")
    assert page.is_enabled("#drift-run"), page.inner_text("main")
    assert "No nightly drift check is scheduled" in page.inner_text("#drift-next")  # drift_time = ""
    # the trend plots state their y range and dates
    assert page.locator("#trends .spark-axis").count() == page.locator("#trends figure").count() > 0
    assert " … " in page.inner_text("#trends .spark-axis >> nth=0")
    page.click("#drift-run")
    expect(page.locator("#drift-status")).to_contain_text("Drift check queued")
    deadline = time.monotonic() + RUN_TIMEOUT_S
    checks: list[Any] = []
    while not checks and time.monotonic() < deadline:
        time.sleep(0.5)
        checks = httpx.get(
            f"{service}/api/drift/checks", params={"unit_serial": "SN-RP-4"}, headers=VIEW
        ).json()
    assert checks, "the drift check did not finish"
    page.goto(f"{service}/#/runs/{checks[0]['run_id']}")
    page.wait_for_selector("#drift-result table")
    assert page.inner_text("h1").startswith("Drift check")
    assert page.locator("#drift-result tbody tr").count() == 12
    assert ("flagged" if checks[0]["flagged"] else "ok") in page.inner_text("#drift-result h2")
    assert page.locator("#verdict").is_hidden() and page.locator("#certificate").count() == 0
    assert console.errors == []
    ctx.close()
