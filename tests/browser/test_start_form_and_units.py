"""The start form's dwell and bench choices and its preview of poses and observable terms; the
units list searched and paged. Against a live service whose agent never comes (nothing runs)."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import httpx
import pytest
from playwright.sync_api import expect

from bench.procedures import build_procedure
from bench.procedures.steps import MoveTo
from db.engine import make_session_factory
from db.migrate import open_database
from db.repo.units import get_or_create_bench
from tests.browser.conftest import BROWSER
from tests.browser.live_server import live_service
from tests.browser.test_dashboard import DESK, ConsoleWatch
from tests.support.service_helpers import OP, OPERATOR, service_settings

N_UNITS = 23

pytestmark = [*BROWSER, pytest.mark.timeout(300)]


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    settings = service_settings(
        tmp_path_factory.mktemp("form"), agent="external", bench_name="bench-choice", run_dwell_s=None
    )
    with live_service(settings) as base:
        engine = open_database(settings.effective_database_url)
        with make_session_factory(engine).begin() as s:  # a second bench, offline: the list has both
            get_or_create_bench(s, "bench-other")
        engine.dispose()
        for i in range(N_UNITS):
            body = {"model": "ADXL325" if i % 2 else "ADXL335"}
            r = httpx.put(f"{base}/api/units/UL-{i:02d}", json=body, headers=OP, timeout=30)
            assert r.status_code == 200, r.text
        yield base


def _page(browser: Any, base: str, path: str) -> tuple[Any, Any, ConsoleWatch]:
    ctx = browser.new_context(viewport=DESK)
    ctx.add_init_script(f"localStorage.setItem('calbench.token', '{OPERATOR}')")
    page = ctx.new_page()
    console = ConsoleWatch(page)
    page.goto(f"{base}/{path}")
    return ctx, page, console


def test_the_start_form_sends_the_dwell_and_bench_chosen(browser: Any, service: str) -> None:
    ctx, page, console = _page(browser, service, "")
    page.wait_for_selector("#start-run:not([disabled])")
    preview = page.locator("#start-preview")
    expect(preview).to_contain_text("dwell decided by a noise window")
    page.fill("#start-dwell", "7")
    page.locator("#start-dwell").dispatch_event("change")
    expect(preview).to_contain_text("dwell 7 s per pose (given)")
    # every pose the procedure commands, in order, and the terms its motion determines
    moves = [s.angles_deg for s in build_procedure("static-12", dwell_s=7.0).steps if isinstance(s, MoveTo)]
    poses = page.locator("#start-poses")
    expect(poses).to_contain_text("Poses")
    shown = poses.inner_text().split(": ", 1)[1].split(" · ")
    assert len(shown) == len(moves)
    assert [[float(x.strip("()° ")) for x in p.split(",")] for p in shown] == [
        [round(a, 1) for a in m] for m in moves
    ]
    expect(page.locator("#start-observability")).to_contain_text(
        "Determined by this motion: bias, scale_matrix"
    )
    page.select_option("#start-procedure", "oscillation-2axis")
    expect(page.locator("#start-observability")).to_contain_text("lever_arm", timeout=60_000)
    page.select_option("#start-procedure", "static-12")
    # the bench list comes from the service
    bench = page.locator("#start-bench")
    expect(bench.locator("option")).to_have_count(2, timeout=30_000)  # any free bench, bench-other
    expect(bench.locator("option").nth(1)).to_have_text("bench-other (offline)")
    page.select_option("#start-bench", "bench-other")
    page.fill("#start-serial", "UL-00")
    with page.expect_request(lambda r: r.url.endswith("/api/runs") and r.method == "POST") as req:
        page.click("#start-run")
    body = req.value.post_data_json
    assert body == {"unit_serial": "UL-00", "procedure": "static-12", "dwell_s": 7, "bench": "bench-other"}
    assert console.errors == []
    ctx.close()


def test_the_units_list_is_searched_and_paged(browser: Any, service: str) -> None:
    ctx, page, console = _page(browser, service, "#/units")
    rows = page.locator("#units-list tbody tr")
    expect(rows).to_have_count(20, timeout=30_000)
    expect(page.locator("#units-page")).to_have_text("units 1–20")
    assert rows.first.inner_text().startswith("UL-00")
    page.click("#units-next")
    expect(page.locator("#units-page")).to_have_text(f"units 21–{N_UNITS}")
    expect(rows).to_have_count(N_UNITS - 20)
    expect(page.locator("#units-next")).to_be_disabled()
    page.click("#units-prev")
    expect(page.locator("#units-page")).to_have_text("units 1–20")
    page.fill("#units-search", "ul-1")
    expect(rows).to_have_count(10)  # UL-10 … UL-19
    page.fill("#units-search", "nothing-like-this")
    expect(page.locator("#units-list")).to_contain_text("No unit matches.")
    assert console.errors == []
    ctx.close()
