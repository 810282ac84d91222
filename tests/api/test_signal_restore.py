"""streams_end_on_signal puts back the SIGTERM/SIGINT handlers it found."""

from __future__ import annotations

import asyncio
import signal
from typing import Any, cast

import pytest

from api.main import streams_end_on_signal

SIGNALS = (signal.SIGTERM, signal.SIGINT)


def _run_inside(services: Any) -> None:
    async def body() -> None:
        with streams_end_on_signal(services):
            pass

    asyncio.run(body())


def test_python_handlers_are_restored() -> None:
    before = {s: signal.getsignal(s) for s in SIGNALS}
    _run_inside(cast(Any, None))
    assert {s: signal.getsignal(s) for s in SIGNALS} == before


def test_a_handler_not_installed_from_python_is_restored_as_the_default(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    real_getsignal = signal.getsignal
    saved = {s: real_getsignal(s) for s in SIGNALS}
    monkeypatch.setattr(signal, "getsignal", lambda s: None)  # what getsignal says of a C-installed handler
    try:
        _run_inside(cast(Any, None))
        after = {s: real_getsignal(s) for s in SIGNALS}
    finally:
        for s, h in saved.items():
            signal.signal(s, h)
    assert after == dict.fromkeys(SIGNALS, signal.SIG_DFL)
