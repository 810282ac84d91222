"""A recording analysed from the page: the CSV and its sidecar chosen in the overview's form,
fitted and diagnosed by the service; the page shows the fit the service computed."""

from __future__ import annotations

from collections.abc import Iterator
from typing import Any

import pytest
from playwright.sync_api import expect

from bench.calibration import calibrate_recording
from bench.recording import read_recording
from tests.browser.conftest import BROWSER
from tests.browser.live_server import live_service
from tests.browser.test_dashboard import DESK, ConsoleWatch
from tests.conftest import EXAMPLES, STATIC_EXAMPLE
from tests.support.service_helpers import OPERATOR, VIEWER, service_settings

pytestmark = [*BROWSER, pytest.mark.timeout(300)]


@pytest.fixture(scope="module")
def service(tmp_path_factory: pytest.TempPathFactory) -> Iterator[str]:
    settings = service_settings(tmp_path_factory.mktemp("upload"), agent="external", bench_name="bench-up")
    with live_service(settings) as base:
        yield base


def _page(browser: Any, base: str, token: str) -> tuple[Any, Any, ConsoleWatch]:
    ctx = browser.new_context(viewport=DESK)
    ctx.add_init_script(f"localStorage.setItem('calbench.token', '{token}')")
    page = ctx.new_page()
    console = ConsoleWatch(page)
    page.goto(f"{base}/")
    return ctx, page, console


def _numbers(text: str) -> list[float]:
    return [float(x) for x in text.split()]


def test_a_recording_uploaded_from_the_page_shows_its_fit(browser: Any, service: str) -> None:
    csv = EXAMPLES / f"{STATIC_EXAMPLE}.csv"
    fit = calibrate_recording(read_recording(csv)).fitted_model()  # the same file, fitted here
    ctx, page, console = _page(browser, service, OPERATOR)
    page.set_input_files("#upload-csv", str(csv))
    page.set_input_files("#upload-sidecar", str(csv.with_suffix(".json")))
    page.click("#upload-run")
    expect(page.locator("#upload-bias")).not_to_be_empty(timeout=120_000)
    assert _numbers(page.inner_text("#upload-bias")) == pytest.approx(fit.bias.tolist(), rel=1e-5)
    diag = [fit.K[i, i] for i in range(3)]
    assert _numbers(page.inner_text("#upload-scale")) == pytest.approx(diag, rel=1e-5)
    expect(page.locator("#upload-result")).to_contain_text("Diagnosis:")
    # a file that is not a recording is refused with the service's reason
    page.set_input_files("#upload-csv", str(csv.with_suffix(".json")))
    page.click("#upload-run")
    expect(page.locator("#upload-result")).to_contain_text("Not analysed: 422")
    assert console.errors == [] or all("422" in e for e in console.errors), console.errors
    ctx.close()


def test_a_viewer_cannot_upload(browser: Any, service: str) -> None:
    ctx, page, _ = _page(browser, service, VIEWER)
    expect(page.locator("#upload-result")).to_contain_text("needs an operator token")
    expect(page.locator("#upload-run")).to_be_disabled()
    ctx.close()
