"""A PASS stored before a unit was judged only by its own model's limits, withdrawn by
migration 0006: the run page shows the note instead of PASS, the certificate card says the
issued certificate's statement was withdrawn, the run's actions list the withdrawal, and the
certificate API gives it beside the unchanged document."""

from __future__ import annotations

import time
from collections.abc import Iterator
from typing import Any

import httpx
import pytest
from playwright.sync_api import expect

from db.migrate import downgrade, upgrade
from tests.browser.conftest import BROWSER
from tests.browser.live_server import live_service
from tests.browser.test_dashboard import DESK, ConsoleWatch
from tests.support.service_helpers import OP, OPERATOR, VIEW, service_settings

RUN_TIMEOUT_S = 240.0

pytestmark = [*BROWSER, pytest.mark.timeout(600)]


@pytest.fixture(scope="module")
def withdrawn_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[tuple[str, str, dict[str, Any]]]:
    """A run of SN-OLD judged PASS against ADXL325's limits and certified, then the unit
    registered as ADXL335 (the limits file lacks it), as a database written before the rule
    holds it; then the database is taken back to 0005 and upgraded again."""
    settings = service_settings(tmp_path_factory.mktemp("withdrawn"), sim_speed=20.0, bench_name="bench-wd")
    with live_service(settings) as base:
        r = httpx.put(f"{base}/api/units/SN-OLD", json={"model": "ADXL325"}, headers=OP, timeout=30)
        assert r.status_code == 200, r.text
        r = httpx.post(
            f"{base}/api/runs", json={"unit_serial": "SN-OLD", "procedure": "static-12"}, headers=OP
        )
        assert r.status_code == 202, r.text
        run_id = r.json()["id"]
        deadline = time.monotonic() + RUN_TIMEOUT_S
        while time.monotonic() < deadline:
            run = httpx.get(f"{base}/api/runs/{run_id}", headers=VIEW, timeout=30).json()
            if run["state"] not in ("queued", "running", "paused", "suspended") and run["certificate_number"]:
                break
            time.sleep(0.2)
        assert (run["state"], run["outcome"]) == ("completed", "PASS"), run
        r = httpx.put(f"{base}/api/units/SN-OLD", json={"model": "ADXL335"}, headers=OP, timeout=30)
        assert r.status_code == 200, r.text
        downgrade(settings.database_url, "0005")
        upgrade(settings.database_url)
        yield base, run_id, run


def test_the_withdrawn_pass_is_shown_everywhere(
    browser: Any, withdrawn_run: tuple[str, str, dict[str, Any]]
) -> None:
    base, run_id, before = withdrawn_run
    day = before["finished_at"][:10]
    note = (
        "no conformity statement: the unit's model ADXL335 has no limits; the PASS recorded on "
        f"{day} against model ADXL325's limits was withdrawn by migration 0006"
    )
    run = httpx.get(f"{base}/api/runs/{run_id}", headers=VIEW, timeout=30).json()
    assert (run["outcome"], run["conformity_note"]) == (None, note)
    assert [(a["actor"], a["action"]) for a in run["audit"]][-1] == ("migration 0006", "withdraw")
    cert = httpx.get(f"{base}/api/runs/{run_id}/certificate", headers=VIEW, timeout=30).json()
    assert cert["content"]["conformity"]["outcome"] == "PASS"  # the issued document is unchanged
    assert cert["conformity_withdrawn"] == note

    ctx = browser.new_context(viewport=DESK)
    ctx.add_init_script(f"localStorage.setItem('calbench.token', '{OPERATOR}')")
    page = ctx.new_page()
    console = ConsoleWatch(page)
    page.goto(f"{base}/#/runs/{run_id}")
    expect(page.locator("#verdict-outcome")).to_have_text(note, timeout=30_000)
    expect(page.locator("#certificate")).to_contain_text(
        f"The statement of conformity on this certificate was withdrawn (PASS withdrawn: judged against "
        f"model ADXL325's limits, the unit's model is ADXL335; certificate {before['certificate_number']}"
    )
    expect(page.locator("#run-audit")).to_contain_text("migration 0006")
    expect(page.locator("#run-audit")).to_contain_text("statement of conformity withdrawn")
    assert console.errors == []
    ctx.close()
