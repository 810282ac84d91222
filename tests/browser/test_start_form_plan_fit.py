"""The start form's planner with the fit family chosen: an every-sample plan shows it is working
while it is computed (one request however often Plan is clicked), shows the design and its
predicted U, and Start run sends the plan's start body, so a planned-tumble run appears; a plan
the service refuses shows the service's message. Against a live service whose agent never comes."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import httpx
import pytest

from tests.browser.conftest import BROWSER, start_form
from tests.browser.live_server import live_service
from tests.support.service_helpers import OP, OPERATOR, service_settings

expect = pytest.importorskip("playwright.sync_api").expect

pytestmark = [*BROWSER, pytest.mark.slow, pytest.mark.timeout(300)]

# a quick every-sample case: the ADXL325-like unit, scale U 400 ppm within 3 min
NOISE = {"white_ug_rt_hz": 250, "wander_ug": 40, "wander_tau_s": 200}
TARGETS = {"scale_ppm": 400, "max_minutes": 3}


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    settings = service_settings(tmp_path_factory.mktemp("planfit"), agent="external", bench_name="bench-plan")
    with live_service(settings) as base:
        yield base


def _form(browser: Any, base: str) -> tuple[Any, list[str]]:
    page, errors = start_form(browser, base, OPERATOR)
    page.locator("#start-plan summary").click()
    return page, errors


def test_an_every_sample_plan_is_shown_and_started_as_planned_tumble(browser: Any, service: str) -> None:
    page, errors = _form(browser, service)
    page.fill("#plan-scale", str(TARGETS["scale_ppm"]))
    page.fill("#plan-mis", "")
    page.fill("#plan-minutes", str(TARGETS["max_minutes"]))
    page.select_option("#plan-fit", "every-sample")
    held: list[Any] = []  # the plan request is held until the working state has been seen
    page.route("**/api/plan?*", lambda route: held.append(route))
    page.click("#plan-run")
    out = page.locator("#plan-result")
    expect(out).to_contain_text("Planning")
    expect(page.locator("#plan-run")).to_be_disabled()
    expect(page.locator("#start-plan")).to_have_attribute("aria-busy", "true")
    page.locator("#plan-run").click(force=True)  # a second click while it works sends nothing
    page.fill("#start-serial", "SN-TUMBLE")  # the rest of the form stays usable
    expect(page.locator("#start-serial")).to_have_value("SN-TUMBLE")
    # the route's callback runs while Playwright waits: wait for the first request to be held,
    # then a while longer, in which a second request (from the second click) would be held too
    for _ in range(300):
        if held:
            break
        page.wait_for_timeout(100)
    page.wait_for_timeout(1000)
    assert len(held) == 1
    assert "fit=every-sample" in held[0].request.url
    held[0].continue_()
    page.unroute("**/api/plan?*")

    plan = httpx.get(
        f"{service}/api/plan", params={**NOISE, **TARGETS, "fit": "every-sample"}, headers=OP, timeout=120
    ).json()
    assert plan["start"]["procedure"] == "planned-tumble"
    u = plan["plan"]["predicted_U_k2"]
    expect(out).to_contain_text("planned-tumble: ", timeout=120_000)
    expect(out).to_contain_text("every-sample fit")
    expect(out).to_contain_text(f"scale {u['scale_ppm']:.1f} ppm")
    expect(out).to_contain_text(f"misalignment {u['misalignment_urad']:.1f} µrad")
    expect(out).to_contain_text(f"bias {u['bias_ug']:.0f} µg")
    expect(page.locator("#plan-run")).to_be_enabled()
    expect(page.locator("#start-procedure")).to_have_value("planned-tumble")

    with page.expect_request(lambda r: r.url.endswith("/api/runs") and r.method == "POST") as req:
        page.click("#start-run")
    body = req.value.post_data_json
    assert body == {"unit_serial": "SN-TUMBLE", **plan["start"]}
    page.wait_for_url("**/#/runs/*")
    run_id = page.url.rsplit("/", 1)[1]
    run = httpx.get(f"{service}/api/runs/{run_id}", headers=OP, timeout=30).json()
    assert run["procedure"] == "planned-tumble" and run["unit_serial"] == "SN-TUMBLE"
    page.goto(f"{service}/")
    row = page.locator("tr", has_text=run_id)
    expect(row).to_contain_text("planned-tumble", timeout=30_000)
    expect(row).to_contain_text("SN-TUMBLE")
    assert errors == []
    page.close()


def test_targets_out_of_reach_show_the_problems_and_a_refused_plan_the_message(
    browser: Any, service: str
) -> None:
    page, errors = _form(browser, service)
    page.fill("#plan-scale", "1")
    page.fill("#plan-mis", "")
    page.fill("#plan-minutes", "3")
    page.select_option("#plan-fit", "every-sample")
    page.click("#plan-run")
    out = page.locator("#plan-result")
    expect(out).to_contain_text("No plan: no planned design within 3 min meets the targets", timeout=120_000)
    expect(out).to_contain_text("Closest tried: planned-tumble: ")
    page.fill("#plan-white", "0")  # refused by the service: its message is shown
    page.click("#plan-run")
    expect(out).to_contain_text("422", timeout=60_000)
    expect(out).to_contain_text("white_ug_rt_hz")
    assert errors == []
    page.close()


def test_the_preview_of_a_plan_shows_every_pass_it_will_run(browser: Any, service: str) -> None:
    page, errors = _form(browser, service)
    page.fill("#plan-white", "250")
    page.fill("#plan-scale", "40")
    page.fill("#plan-mis", "40")
    page.fill("#plan-minutes", "20")
    page.select_option("#plan-fit", "window")
    params = {**NOISE, "scale_ppm": 40, "misalignment_urad": 40, "max_minutes": 20, "fit": "window"}
    plan = httpx.get(f"{service}/api/plan", params=params, headers=OP, timeout=120).json()
    start = plan["start"]
    repeats = int(start["parameters"]["repeats"])
    assert repeats > 1, plan  # a design of several passes, so one pass would show fewer poses
    with page.expect_request(
        lambda r: "/api/procedures/planned-static/preview" in r.url and "parameters" in r.url
    ):
        page.click("#plan-run")
    preview = page.locator("#start-preview")
    expect(preview).to_contain_text(
        f"{12 * repeats} poses (the plan's {repeats} passes), {12 * repeats} windows"
    )
    # the plan's table time on the bench clock (the simulated bench runs SIM_SPEED times faster)
    expect(preview).to_contain_text(f"({round(plan['plan']['duration_s'] / 60)} min on the bench clock)")
    assert len(page.locator("#start-poses").inner_text().split(" · ")) == 12 * repeats
    page.fill(
        "#start-dwell", str(start["dwell_s"] + 1)
    )  # the plan detached: its procedure's default, one pass
    page.locator("#start-dwell").dispatch_event("change")
    expect(preview).to_contain_text("12 poses, 12 windows")
    assert errors == []
    page.close()
