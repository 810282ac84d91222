"""The run page draws the signal as it comes: the last seconds of the three channels and the
table angles, decimated, updated while a simulated run records (before, only each window's
means were shown).

Against a live simulated service running static-12 (its agent, its event stream)."""

from __future__ import annotations

import re
from collections.abc import Iterator
from typing import Any

import httpx
import pytest
from playwright.sync_api import expect

from bench.live_signal import SignalTail
from station.runs.live import DbLiveObserver
from tests.browser.conftest import BROWSER
from tests.browser.live_server import live_service
from tests.browser.test_dashboard import open_new_run, shot
from tests.support.service_helpers import OP, RATE_HZ, service_settings

pytestmark = [*BROWSER, pytest.mark.timeout(600)]


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    settings = service_settings(tmp_path_factory.mktemp("signal"), sim_speed=10.0, bench_name="bench-sig")
    with live_service(settings) as base:
        yield base


def test_the_run_page_draws_the_live_signal_and_it_moves_on(service: str, browser: Any) -> None:
    run_id, ctx, page, console = open_new_run(service, browser, "SN-SIG-1")
    try:
        card = page.locator("#live-signal")
        expect(card).to_be_visible(timeout=120_000)
        # three channels drawn as lines, and the table's axes in their own plot
        expect(page.locator("#signal-accel svg path[stroke]")).to_have_count(3)
        assert page.locator("#signal-table svg path[stroke]").count() >= 1
        note = page.inner_text("#signal-note")
        match = re.search(r"the mean of (\d+) samples \((\d+) points\)", note)
        assert match is not None, note
        assert int(match[2]) <= DbLiveObserver.signal_points  # decimated: bounded whatever the run's length
        # k as SignalTail works it out for the simulated DAQ's rate: ceil(rate · span / points)
        tail = SignalTail(RATE_HZ, DbLiveObserver.signal_span_s, DbLiveObserver.signal_points)
        assert int(match[1]) == tail.samples_per_point
        first = float(card.get_attribute("data-newest") or "nan")
        # the view moves on with the run: a later signal event redraws it with newer samples
        expect(card).not_to_have_attribute("data-newest", str(first), timeout=60_000)
        assert float(card.get_attribute("data-newest") or "nan") > first
        shot(page, "live-signal")
        assert console.errors == []
    finally:
        httpx.post(f"{service}/api/runs/{run_id}/abort", headers=OP)
        ctx.close()
