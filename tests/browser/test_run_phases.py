"""The run page shows the run's phases (recording → analysing → certificate), the time left from
the pace so far while recording, and controls that match the phase: no Pause or Abort once every
window is recorded and the fit, diagnosis and certificate run.

Against a live simulated service running static-12.
"""

from __future__ import annotations

import math
import re
import time
from collections.abc import Iterator
from typing import Any

import httpx
import pytest
from playwright.sync_api import expect

from station.certificates.rounding import format_with_uncertainty
from tests.browser.conftest import BROWSER
from tests.browser.live_server import live_service
from tests.browser.test_dashboard import open_new_run
from tests.support.service_helpers import OP, VIEW, service_settings

RUN_TIMEOUT_S = 300.0

pytestmark = [*BROWSER, pytest.mark.timeout(600)]


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    settings = service_settings(tmp_path_factory.mktemp("phases"), sim_speed=20.0, bench_name="bench-ph")
    with live_service(settings) as base:
        yield base


def test_phases_time_left_and_controls_follow_the_run(service: str, browser: Any) -> None:
    run_id, ctx, page, console = open_new_run(service, browser, "SN-PH-1")
    # recording: its phase current, Pause and Abort offered, a time left from the pace
    expect(page.locator('#run-phases li[data-phase="recording"]')).to_have_class("current", timeout=60_000)
    expect(page.locator("#pause-run")).to_be_visible()
    expect(page.locator("#abort-run")).to_be_visible()
    expect(page.locator("#run-eta")).to_contain_text("of recording", timeout=60_000)
    # each window's values as it completes: its channel means, while the run records
    expect(page.locator("#windows .window-means").first).to_contain_text("ax", timeout=120_000)
    # every window recorded: analysing (or already the certificate), no Pause or Abort
    after = page.locator(
        '#run-phases li[data-phase="analysing"].current, #run-phases li[data-phase="certificate"].current'
    )
    expect(after).to_have_count(1, timeout=RUN_TIMEOUT_S * 1000)
    assert page.locator('#run-phases li[data-phase="recording"]').get_attribute("class") == "done"
    expect(page.locator("#pause-run")).to_be_hidden()
    expect(page.locator("#abort-run")).to_be_hidden()
    expect(page.locator("#analysing-note")).to_be_visible()
    assert page.inner_text("#run-eta").startswith("recording done; analysing")  # first run: no time known
    # over the API the same phase, while the run is still live
    run = httpx.get(f"{service}/api/runs/{run_id}", headers=VIEW).json()
    assert run["phase"] in ("analysing", "certificate", None), run
    # the end: every phase done, the verdict shown
    expect(page.locator("#verdict-outcome")).to_have_text("PASS", timeout=RUN_TIMEOUT_S * 1000)
    assert page.locator("#run-phases li.done").count() == 3
    deadline = time.monotonic() + 10
    while httpx.get(f"{service}/api/runs/{run_id}", headers=VIEW).json()["phase"] is not None:
        assert time.monotonic() < deadline, "a final run still reports a phase"
        time.sleep(0.2)
    # values with their uncertainty by the certificate's rule, cross-axis in mrad
    run = httpx.get(f"{service}/api/runs/{run_id}", headers=VIEW).json()
    cal = run["calibration"]
    fit = page.locator('section[aria-label="Fitted model"]')
    expect(fit).to_be_visible()
    text = fit.inner_text()
    for b, s in zip(cal["bias"], cal["bias_sigma"], strict=True):
        assert format_with_uncertainty(b, 2 * s) in text
    k, ks = cal["scale_matrix"], cal["scale_matrix_sigma"]
    assert format_with_uncertainty(k[0][0], 2 * ks[0][0]) in text
    assert "from y (mrad)" in text
    # one U per check: the certificate's, on the page and over the API
    content = httpx.get(f"{service}/api/runs/{run_id}/certificate", headers=VIEW).json()["content"]
    stated = {r["quantity"]: r["expanded_uncertainty"] for r in content["conformity"]["checks"]}
    assert stated and {c["name"]: c["expanded_uncertainty"] for c in run["limit_checks"]} == stated
    for row in page.locator("#limit-checks tbody tr").all():
        cells = row.locator("td").all_inner_texts()
        value, u = cells[1], cells[2]
        assert len(value.partition(".")[2]) == len(u.partition(".")[2]), cells
    # the raw recording: the page's signed link gives the stored samples
    link = page.locator('#raw-recording a[data-part="csv"]')
    expect(link).to_have_attribute("href", re.compile(rf"/api/runs/{run_id}/recording/csv\?link="))
    href = link.get_attribute("href")
    assert href is not None
    got = page.request.get(f"{service}/{href.lstrip('/')}")
    stored = httpx.get(f"{service}/api/runs/{run_id}/recording/csv", headers=VIEW)
    assert got.status == 200 and got.body() == stored.content
    assert stored.content.count(b"\n") > run["n_samples"]  # the header and every sample
    # the windows' means on the page are the stored ones
    stored_means = {w["index"] + 1: w["means"] for w in run["windows"]}
    for row in page.locator("#windows tbody tr").all():
        cells = row.locator("td").all_inner_texts()
        shown = cells[5].split()
        means = stored_means[int(cells[0])]
        assert shown[0::2] == list(means), cells
        for text, ch in zip(shown[1::2], means, strict=True):
            assert float(text) == pytest.approx(means[ch], rel=1e-5, abs=1e-9), (cells, means)
    # bias instability only where the Allan curve has its minimum inside the τ measured
    al = httpx.get(f"{service}/api/runs/{run_id}/plots/allan", headers=VIEW).json()
    noise = page.locator("#allan table tbody tr")
    expect(noise.first).to_be_visible()
    for k, row in enumerate(noise.all()):
        adev = [v for v in al["adev"][k] if v is not None and math.isfinite(v)]
        reached = min(range(len(adev)), key=adev.__getitem__) < len(adev) - 1
        cell = row.locator("td").nth(2).inner_text()
        assert ("not reached" not in cell) == reached, (cell, adev[-3:])
    # the unit's trends: dated, and a y range whose two ends print differently
    page.goto(f"{service}/#/units/SN-PH-1")
    axis = page.locator("#trends .spark-axis").first
    expect(axis).to_contain_text("UTC")
    y_range = axis.locator("span").first.inner_text()
    lo, _, hi = y_range.removeprefix("y ").rpartition(" ")[0].partition(" … ")
    assert lo != hi, y_range
    assert console.errors == []
    ctx.close()


def test_runs_are_searched_and_filtered_on_the_overview(service: str, browser: Any) -> None:
    run_id, ctx, page, console = open_new_run(service, browser, "SN-PH-2", page_path="/")
    runs = page.locator('section[aria-label="Runs"] tbody tr')
    expect(runs.first).to_be_visible(timeout=30_000)
    page.fill("#runs-search", "sn-ph-2")  # the serial, any case
    expect(runs).to_have_count(1)
    assert run_id in runs.first.inner_text()
    page.fill("#runs-search", "no-such-run")
    expect(page.locator('section[aria-label="Runs"]')).to_contain_text("No run matches.")
    page.fill("#runs-search", "")
    page.select_option("#runs-state", "aborted")
    expect(page.locator('section[aria-label="Runs"]')).to_contain_text("No run matches.")
    page.select_option("#runs-state", "")
    expect(runs.first).to_be_visible()
    expect(page.locator("#runs-page")).to_contain_text("runs 1–")
    assert page.locator("#runs-prev").is_disabled()
    assert page.locator("#runs-next").is_disabled() == (runs.count() <= 20)
    httpx.post(f"{service}/api/runs/{run_id}/abort", headers=OP)
    assert console.errors == []
    ctx.close()
