"""Debian's chromium driven by Playwright through ``executable_path`` (no downloaded browser)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

CHROMIUM = Path("/usr/bin/chromium")
CHROMIUM_ARGS = [
    "--headless",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--no-first-run",
    "--disable-sync",
]
BROWSER = [
    pytest.mark.browser,
    pytest.mark.skipif(
        not CHROMIUM.exists(),
        reason="Debian's chromium is not installed at /usr/bin/chromium (`make browser` installs it)",
    ),
]
"""The marks of every browser test module: the marker, and a skip where chromium is missing."""


def start_form(browser: Any, base: str, token: str) -> tuple[Any, list[str]]:
    """A new page on the dashboard at ``base`` signed in with ``token``, once its start form is
    ready, and the list its uncaught page errors are appended to."""
    page = browser.new_page()
    errors: list[str] = []
    page.on("pageerror", lambda e: errors.append(str(e)))
    page.add_init_script(f"localStorage.setItem('calbench.token', '{token}')")
    page.goto(f"{base}/")
    page.wait_for_selector("#start-run:not([disabled])")
    return page, errors


@pytest.fixture(scope="module")
def browser() -> Iterator[Any]:
    """A headless chromium for the module's tests."""
    sync_api = pytest.importorskip("playwright.sync_api")
    with sync_api.sync_playwright() as p:
        b = p.chromium.launch(executable_path=str(CHROMIUM), args=CHROMIUM_ARGS, headless=True)
        yield b
        b.close()
