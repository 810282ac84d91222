"""Every page of a run's certificate rendered to PNG (pdftoppm) and shown in the browser, each
page's text checked against the stored run: the conformity line, the deviations (a pause by a
named operator) and who started the run."""

from __future__ import annotations

import re
import shutil
import subprocess
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import httpx
import pytest
from playwright.sync_api import expect

from tests.browser.conftest import BROWSER
from tests.browser.live_server import live_service
from tests.browser.test_dashboard import DESK, ConsoleWatch
from tests.support.service_helpers import OPERATOR, VIEW, service_settings

RUN_TIMEOUT_S = 300.0
ADMIN = "admin-secret-0001"
OPERATOR_NAME = "Ada Lovelace"
LIVE = ("queued", "running", "paused", "suspended")

pytestmark = [
    *BROWSER,
    pytest.mark.timeout(600),
    pytest.mark.skipif(
        shutil.which("pdftoppm") is None or shutil.which("pdftotext") is None, reason="poppler-utils"
    ),
]


def _wait(base: str, run_id: str, done: Any) -> dict[str, Any]:
    deadline = time.monotonic() + RUN_TIMEOUT_S
    while time.monotonic() < deadline:
        run = httpx.get(f"{base}/api/runs/{run_id}", headers=VIEW, timeout=30).json()
        if done(run):
            return dict(run)
        time.sleep(0.1)
    raise AssertionError(f"run {run_id}: {run}")


@pytest.fixture(scope="module")
def certified(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, dict[str, Any], Path]]:
    """The service, a completed run of SN-CERT started and paused by a named operator, and its PDF."""
    tmp = tmp_path_factory.mktemp("cert")
    settings = service_settings(
        tmp,
        sim_speed=10.0,
        bench_name="bench-cert",
        tokens=[f"operator:{OPERATOR}", f"admin:{ADMIN}", "viewer:viewer-secret-0001"],
    )
    with live_service(settings) as base:
        made = httpx.post(
            f"{base}/api/tokens",
            json={"role": "operator", "label": "bench desk", "operator": OPERATOR_NAME},
            headers={"Authorization": f"Bearer {ADMIN}"},
            timeout=30,
        )
        assert made.status_code == 201, made.text
        ada = {"Authorization": f"Bearer {made.json()['secret']}"}
        r = httpx.put(f"{base}/api/units/SN-CERT", json={"model": "ADXL325"}, headers=ada, timeout=30)
        assert r.status_code == 200, r.text
        r = httpx.post(
            f"{base}/api/runs", json={"unit_serial": "SN-CERT", "procedure": "static-12"}, headers=ada
        )
        assert r.status_code == 202, r.text
        run_id = r.json()["id"]
        _wait(
            base, run_id, lambda run: run["state"] == "running" and (run["last_complete_window"] or -1) >= 1
        )
        assert httpx.post(f"{base}/api/runs/{run_id}/pause", headers=ada, timeout=30).status_code < 300
        _wait(base, run_id, lambda run: run["state"] == "paused")
        time.sleep(1.0)
        assert httpx.post(f"{base}/api/runs/{run_id}/resume", headers=ada, timeout=30).status_code < 300
        run = _wait(base, run_id, lambda run: run["state"] not in LIVE)
        assert run["state"] == "completed" and run["certificate_number"], run
        run = httpx.get(f"{base}/api/runs/{run_id}", headers=VIEW, timeout=30).json()
        pdf = tmp / "certificate.pdf"
        pdf.write_bytes(
            httpx.get(f"{base}/api/runs/{run_id}/certificate.pdf", headers=VIEW, timeout=60).content
        )
        yield base, run, pdf


def _page_text(pdf: Path, page: int) -> str:
    out = subprocess.run(
        ["pdftotext", "-layout", "-f", str(page), "-l", str(page), str(pdf), "-"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    return " ".join(out.split())


def test_every_certificate_page_renders_and_states_the_stored_run(
    browser: Any, certified: tuple[str, dict[str, Any], Path], tmp_path: Path
) -> None:
    _, run, pdf = certified
    subprocess.run(["pdftoppm", "-png", "-r", "60", str(pdf), str(tmp_path / "page")], check=True)
    pngs = sorted(tmp_path.glob("page-*.png"))
    first = _page_text(pdf, 1)
    n_pages = int(re.search(r"Page 1 of (\d+)", first).group(1))  # type: ignore[union-attr]
    assert len(pngs) == n_pages >= 3
    # what the stored run says: its outcome, who started it, the pause it had
    assert run["outcome"] == "PASS" and run["started_by"].startswith(OPERATOR_NAME)
    actions = [a["action"] for a in run["audit"]]
    assert "pause" in actions and "continue" in actions
    texts = [_page_text(pdf, i) for i in range(1, n_pages + 1)]
    for i, text in enumerate(texts, start=1):
        assert "Conformity: PASS against the limits of unit model ADXL325" in text, (i, text[:300])
        assert run["certificate_number"] in text and f"Page {i} of {n_pages}" in text
    whole = " ".join(texts)
    assert "Deviations from the method" in whole
    deviations = whole.split("Deviations from the method", 1)[1][:400]
    assert "paused" in deviations and "none:" not in deviations, deviations
    assert f"Run started by: {OPERATOR_NAME} at" in whole
    assert f"{OPERATOR_NAME}: pause requested" in whole and f"{OPERATOR_NAME}: continue requested" in whole
    # each PNG is a whole page the browser can show: portrait A4, with ink on it
    ctx = browser.new_context(viewport=DESK)
    page = ctx.new_page()
    console = ConsoleWatch(page)
    for png in pngs:
        page.goto(png.as_uri())
        size = page.evaluate(
            "() => { const i = document.images[0]; return [i.naturalWidth, i.naturalHeight]; }"
        )
        assert size[1] / size[0] == pytest.approx(297 / 210, rel=0.02), (png.name, size)
        ink = page.evaluate(
            """() => { const i = document.images[0]; const c = document.createElement('canvas');
              c.width = i.naturalWidth; c.height = i.naturalHeight; const g = c.getContext('2d');
              g.drawImage(i, 0, 0); const d = g.getImageData(0, 0, c.width, c.height).data; let n = 0;
              for (let k = 0; k < d.length; k += 4) if (d[k] < 128) n++; return n / (d.length / 4); }"""
        )
        assert 0.005 < ink < 0.5, (png.name, ink)
    assert console.errors == []
    ctx.close()


def test_the_run_page_links_the_certificate_it_states(
    browser: Any, certified: tuple[str, dict[str, Any], Path]
) -> None:
    base, run, _ = certified
    ctx = browser.new_context(viewport=DESK)
    ctx.add_init_script(f"localStorage.setItem('calbench.token', '{OPERATOR}')")
    page = ctx.new_page()
    page.goto(f"{base}/#/runs/{run['id']}")
    expect(page.locator("#certificate")).to_contain_text(run["certificate_number"], timeout=30_000)
    expect(page.locator("#verdict-outcome")).to_have_text("PASS")
    ctx.close()
