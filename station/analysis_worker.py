"""Calibration and diagnosis of uploaded recordings, off the event loop.

``POST /api/recordings`` fits and diagnoses a recording: seconds of numpy/scipy work for a
long one. Done inside the ``async`` route it stalled every other request of the process
(``/api/health`` took 11 s during an 11 s upload). :class:`AnalysisPool` runs that work in
worker processes (``CALBENCH_UPLOAD_WORKERS``, default 1; spawned, so they share nothing
with the server but the file path they are given) or, with 0 workers, in a thread of the
server's thread pool. The event loop only awaits the result.
"""

from __future__ import annotations

import asyncio
import concurrent.futures
import multiprocessing
import os
import threading
import time
from pathlib import Path
from typing import Any

from starlette.concurrency import run_in_threadpool

AnalysisResult = tuple[dict[str, Any], dict[str, Any] | None, str | None]
"""``(calibration, diagnosis, diagnosis_note)``: the ``calbench calibrate --json`` object, the
``calbench diagnose --json`` object or ``None``, and why there is no diagnosis."""


def analyse_upload(csv_path: str) -> AnalysisResult:
    """Read, calibrate and diagnose the recording at ``csv_path`` (its sidecar beside it).

    Paths in error messages are made relative to the recording's directory (a temporary
    directory the client must not see).

    :raises ValueError: the recording cannot be read or fitted (message names file and row).
    """
    from bench.calibration.analysis import analyse
    from bench.recording import read_recording
    from station.certificates.issue import DIAGNOSIS_AVAILABLE, diagnose

    path = Path(csv_path)
    prefix = str(path.parent) + "/"
    try:
        rec = read_recording(path)
        calibration = dict(analyse(rec).contract())
    except ValueError as exc:
        raise ValueError(str(exc).replace(prefix, "")) from None
    if not DIAGNOSIS_AVAILABLE:
        return calibration, None, "the diagnosis module is not installed"
    try:
        return calibration, dict(diagnose(rec).to_contract()), None
    except ValueError as exc:
        return calibration, None, str(exc).replace(prefix, "")


def _end_with_parent(parent_pid: int, poll_s: float = 1.0) -> None:
    """Worker initializer: the worker ends when the server that started it is gone (killed:
    the pool never told it to stop), instead of staying behind as an orphan."""

    def watch() -> None:
        while os.getppid() == parent_pid:
            time.sleep(poll_s)
        os._exit(0)

    threading.Thread(target=watch, name="parent-watch", daemon=True).start()


def _import_analysis() -> None:
    """Import what :func:`analyse_upload` needs (run in a fresh worker)."""
    import bench.calibration
    import bench.recording  # noqa: F401
    import station.certificates.issue  # noqa: F401


class AnalysisPool:
    """Where upload analyses run: ``workers`` spawned processes, or the thread pool (0).

    The process pool is started on first use and lives until :meth:`close`. A worker that
    died (killed, out of memory) breaks the pool; the next call starts a new one.

    :param workers: worker processes; 0 runs the work in a thread instead.
    """

    def __init__(self, workers: int = 1) -> None:
        if workers < 0:
            raise ValueError(f"upload workers {workers}: expected 0 (threads) or more processes")
        self.workers = workers
        self._pool: concurrent.futures.ProcessPoolExecutor | None = None
        self._lock = threading.Lock()

    def _executor(self) -> concurrent.futures.ProcessPoolExecutor:
        with self._lock:
            if self._pool is None:
                self._pool = concurrent.futures.ProcessPoolExecutor(
                    self.workers,
                    mp_context=multiprocessing.get_context("spawn"),
                    initializer=_end_with_parent,
                    initargs=(os.getpid(),),
                )
            return self._pool

    def warm(self) -> None:
        """Start the worker processes now and let them import the analysis (seconds on a busy
        machine), so the first upload does not wait for it; nothing with 0 workers."""
        if self.workers > 0:
            for _ in range(self.workers):
                self._executor().submit(_import_analysis)

    async def analyse(self, csv_path: Path) -> AnalysisResult:
        """:func:`analyse_upload` of ``csv_path`` in a worker; the event loop stays free.

        :raises ValueError: as :func:`analyse_upload`.
        """
        if self.workers == 0:
            return await run_in_threadpool(analyse_upload, str(csv_path))
        loop = asyncio.get_running_loop()
        try:
            return await loop.run_in_executor(self._executor(), analyse_upload, str(csv_path))
        except concurrent.futures.process.BrokenProcessPool:
            with self._lock:
                broken, self._pool = self._pool, None
            if broken is not None:
                broken.shutdown(wait=False, cancel_futures=True)
            raise RuntimeError("the upload analysis worker died; the request can be sent again") from None

    def close(self) -> None:
        """Stop the worker processes (pending analyses are cancelled)."""
        with self._lock:
            pool, self._pool = self._pool, None
        if pool is not None:
            pool.shutdown(wait=False, cancel_futures=True)
