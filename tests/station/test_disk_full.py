"""A full disk makes the bench agent log one line (then one a minute, and one when it clears),
never a traceback per poll, and poll less often while it lasts (issue 24, item 8)."""

from __future__ import annotations

import errno
import logging
import sqlite3
import threading
import time
from pathlib import Path

import pytest
from sqlalchemy.exc import OperationalError

from station import disk_full
from station.agent.bench_agent import BenchAgent
from station.disk_full import DISK_FULL_LOG_INTERVAL_S, DiskFullWatch
from tests.support.service_helpers import service_settings

pytestmark = pytest.mark.timeout(120)


def _enospc() -> OSError:
    return OSError(errno.ENOSPC, "No space left on device")


def _sqlite_full() -> OperationalError:
    return OperationalError("INSERT INTO run ...", {}, sqlite3.OperationalError("database or disk is full"))


def test_the_watch_logs_once_then_once_an_interval_then_when_it_clears() -> None:
    now = [100.0]
    records: list[logging.LogRecord] = []
    logger = logging.getLogger("test.disk_full.watch")

    class Keep(logging.Handler):
        def emit(self, record: logging.LogRecord) -> None:
            records.append(record)

    handler = Keep()
    logger.addHandler(handler)
    try:
        watch = DiskFullWatch(logger, "agent", clock=lambda: now[0])
        assert not watch.failed(RuntimeError("table stalled"))  # not a full disk: the caller logs it
        # 3 minutes of polls every 0.5 s, the disk full: 360 refused polls
        for i in range(360):
            assert watch.failed(_enospc() if i % 2 else _sqlite_full())
            now[0] += 0.5
        assert watch.full and watch.failures == 360
        # logged at 0, 60, 120 s: ceil(180 / 60) lines, none with a traceback
        assert len(records) == int(180.0 // DISK_FULL_LOG_INTERVAL_S) == 3
        assert all(r.levelno == logging.ERROR and r.exc_info is None for r in records)
        msgs = [r.getMessage() for r in records]
        assert "disk full for 0 s (1 polls refused): database or disk is full" in msgs[0]
        assert "disk full for 60 s (121 polls refused)" in msgs[1]
        assert "disk full for 120 s (241 polls refused)" in msgs[2]
        watch.succeeded()
        assert len(records) == 4 and "accepts writes again after 180 s (360 polls" in records[3].getMessage()
        watch.succeeded()  # nothing more to say
        assert len(records) == 4 and not watch.full
    finally:
        logger.removeHandler(handler)


def test_waits_double_from_the_poll_period_up_to_the_cap() -> None:
    watch = DiskFullWatch(logging.getLogger("test.disk_full.waits"), "agent")
    assert watch.wait_s(0.25) == 0.25
    waits = []
    for _ in range(8):
        watch.failed(_enospc())
        waits.append(watch.wait_s(0.25))
    assert waits == [0.5, 1.0, 2.0, 4.0, 5.0, 5.0, 5.0, 5.0]
    assert disk_full.MAX_WAIT_S == 5.0


def test_the_agent_logs_a_full_disk_once_and_polls_less_often(
    tmp_path: Path, caplog: pytest.LogCaptureFixture, monkeypatch: pytest.MonkeyPatch
) -> None:
    agent = BenchAgent(service_settings(tmp_path), poll_s=0.02)
    full = threading.Event()
    full.set()
    polls = [0, 0]  # while full, after
    real_end_orphans = agent.end_orphans

    def end_orphans() -> list[str]:  # the poll's first write to the database
        if full.is_set():
            polls[0] += 1
            raise _sqlite_full() if polls[0] % 2 else _enospc()
        polls[1] += 1
        return real_end_orphans()

    monkeypatch.setattr(agent, "end_orphans", end_orphans)
    caplog.set_level(logging.INFO, logger="station.agent")
    thread = threading.Thread(target=agent.run_forever, daemon=True)
    try:
        thread.start()
        time.sleep(3.0)
        full_polls = polls[0]
        full.clear()
        deadline = time.monotonic() + 20.0
        while polls[1] < 3 and time.monotonic() < deadline:
            time.sleep(0.05)
    finally:
        agent._stop.set()
        thread.join(15.0)
        agent.close()
    # without the backoff 3 s at 0.02 s is ~150 polls; with it 0.04+0.08+...+2.56 > 3 s: <= 8
    assert 2 <= full_polls <= 8, full_polls
    assert polls[1] >= 3  # polling went on when the disk cleared
    ours = [r for r in caplog.records if r.name.startswith("station.agent") and r.levelno >= logging.WARNING]
    assert [r.levelno for r in ours] == [logging.ERROR, logging.WARNING], [r.getMessage() for r in ours]
    assert all(r.exc_info is None for r in ours)
    assert "disk full" in ours[0].getMessage() and "accepts writes again" in ours[1].getMessage()
