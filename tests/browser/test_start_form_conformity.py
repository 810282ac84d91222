"""The start form tells the operator, before a run starts, that a unit whose model has no
limits will get no statement of conformity; a unit of a model with limits gets no such note."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from tests.browser.conftest import BROWSER, start_form
from tests.browser.live_server import live_service
from tests.support.service_helpers import OP, OPERATOR, service_settings

expect = pytest.importorskip("playwright.sync_api").expect

pytestmark = [*BROWSER, pytest.mark.timeout(300)]


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    # an external agent that never comes: nothing runs, the form is what is tested
    settings = service_settings(tmp_path_factory.mktemp("form"), agent="external", bench_name="bench-form")
    with live_service(settings) as base:
        for serial, model in (("SN-335", "ADXL335"), ("SN-325", "ADXL325")):
            r = httpx.put(f"{base}/api/units/{serial}", json={"model": model}, headers=OP, timeout=30)
            assert r.status_code == 200, r.text
        yield base


def test_the_form_warns_before_a_run_of_a_model_without_limits(browser: Any, service: str) -> None:
    page, errors = start_form(browser, service, OPERATOR)
    warning = page.locator("#start-warning")
    page.fill("#start-serial", "SN-335")
    page.locator("#start-serial").dispatch_event("change")
    expect(warning).to_contain_text("Unit SN-335: no statement of conformity will be made")
    expect(warning).to_contain_text("no limits are configured for model ADXL335")
    page.fill("#start-serial", "SN-325")
    page.locator("#start-serial").dispatch_event("change")
    expect(warning).to_have_text("")
    assert errors == []


def test_the_plan_button_plans_and_the_start_sends_the_plan(browser: Any, service: str) -> None:
    page, errors = start_form(browser, service, OPERATOR)
    page.locator("#start-plan summary").click()
    page.fill("#plan-scale", "80")
    page.fill("#plan-mis", "")
    page.click("#plan-run")
    expect(page.locator("#plan-result")).to_contain_text("planned-static:", timeout=60_000)
    expect(page.locator("#start-procedure")).to_have_value("planned-static")
    plan = httpx.get(
        f"{service}/api/plan",
        params={"white_ug_rt_hz": 250, "wander_ug": 40, "wander_tau_s": 200, "scale_ppm": 80},
        headers=OP,
        timeout=60,
    ).json()
    page.fill("#start-serial", "SN-PLANNED")
    with page.expect_request(lambda r: r.url.endswith("/api/runs") and r.method == "POST") as req:
        page.click("#start-run")
    body = req.value.post_data_json
    assert body["procedure"] == "planned-static" and body["dwell_s"] == plan["start"]["dwell_s"]
    assert body["parameters"] == plan["start"]["parameters"]
    assert errors == []
