"""``calbench serve`` keeps its bench's agent running as a child process.

:class:`AgentSupervisor` starts ``calbench agent`` (same interpreter, same environment, the
service's ``--sim``/``--sim-speed``) and starts it again if it dies. If another process
drives the bench (its lock is held, :mod:`station.execution.bench_lock`) — the agent of another live
``calbench serve``, ``calbench run``, or the agent a previous ``calbench serve`` started
before it was killed, still recording its run — none is started until that one is gone: the
run goes on while the API restarts. On :meth:`stop` the agent this supervisor started gets
SIGTERM (it leaves its run ``interrupted``, table safe, recording closed) and up to
``stop_timeout_s`` to end. Of the processes it did not start it stops only an agent whose own
``calbench serve`` is gone (an orphan it adopted); it never touches one a live service or an
operator runs.
"""

from __future__ import annotations

import logging
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

from db.process import process_start_ticks
from station.execution.bench_lock import HELD_EXIT, SUPERVISOR_ENV, lock_path, read_holder
from station.settings import Settings

log = logging.getLogger(__name__)


class AgentSupervisor:
    """Start, watch and stop the bench agent process of ``settings``' bench.

    :param log_path: where the agent's output goes (appended); ``None``: this process's stderr.
    :param restart_s: wait before starting the agent again after it ended, or while another
        agent holds the bench (s).
    """

    def __init__(
        self,
        settings: Settings,
        *,
        sim: bool,
        sim_speed: float | None,
        log_path: Path | None = None,
        restart_s: float = 2.0,
        stop_timeout_s: float = 90.0,
    ) -> None:
        self.settings, self.restart_s, self.stop_timeout_s = settings, restart_s, stop_timeout_s
        self.cmd = [sys.executable, "-m", "api", "agent", "--log-level", "warning"]
        if sim:
            self.cmd.append("--sim")
        if sim_speed is not None:
            self.cmd += ["--sim-speed", repr(sim_speed)]
        self.log_path = log_path
        self.proc: subprocess.Popen[bytes] | None = None
        self.n_starts = 0
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _spawn(self) -> subprocess.Popen[bytes]:
        out = self.log_path.open("ab") if self.log_path is not None else None
        try:
            env = {
                **os.environ,
                "CALBENCH_BENCH_NAME": self.settings.bench_name,
                "CALBENCH_DATA_DIR": str(self.settings.data_dir),
                "CALBENCH_DATABASE_URL": self.settings.effective_database_url,
                SUPERVISOR_ENV: f"{os.getpid()}:{process_start_ticks(os.getpid()) or ''}",
            }
            if self.settings.bench_file is not None:  # the bench file the service was given
                env["CALBENCH_BENCH_FILE"] = str(self.settings.bench_file)
            # its own session: a terminal's Ctrl-C reaches the service, which stops the agent in order
            return subprocess.Popen(
                self.cmd,
                env=env,
                stdout=out,
                stderr=subprocess.STDOUT if out else None,
                start_new_session=True,
            )
        finally:
            if out is not None:
                out.close()

    def _loop(self) -> None:
        while not self._stop.is_set():
            holder = read_holder(lock_path(self.settings))
            if holder is not None:  # another process drives the bench: let it be
                self._stop.wait(self.restart_s)
                continue
            self.proc = self._spawn()
            self.n_starts += 1
            log.info("bench agent started, pid %s", self.proc.pid)
            while not self._stop.is_set() and self.proc.poll() is None:
                self._stop.wait(0.5)
            if self._stop.is_set():
                return
            code = self.proc.returncode
            if code != HELD_EXIT:
                log.error("bench agent %s ended with %s; starting it again", self.proc.pid, code)
            self._stop.wait(self.restart_s)

    def start(self) -> None:
        """Start watching (and starting) the agent in a thread."""
        self._thread = threading.Thread(target=self._loop, name="agent-supervisor", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        """Stop the bench's agent: the one this supervisor started (SIGTERM, then SIGKILL after
        the timeout), or an orphan it found running (a killed service's, adopted: SIGTERM)."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        proc = self.proc
        if proc is None or proc.poll() is not None:
            self._stop_adopted()
            return
        proc.send_signal(signal.SIGTERM)
        try:
            proc.wait(self.stop_timeout_s)
        except subprocess.TimeoutExpired:
            log.error("bench agent %s did not stop within %g s; killed", proc.pid, self.stop_timeout_s)
            proc.kill()
            proc.wait(10)

    def _stop_adopted(self) -> None:
        """SIGTERM to an agent left by a killed ``calbench serve`` (orphaned), and wait for it; any
        other holder of the bench (a live service's agent, ``calbench run``) is left alone."""
        path = lock_path(self.settings)
        holder = read_holder(path)
        if holder is None or holder.pid <= 0 or holder.pid == os.getpid():
            return
        if holder.kind != "calbench agent" or not holder.orphaned():
            return
        try:
            os.kill(holder.pid, signal.SIGTERM)
        except ProcessLookupError:
            return
        deadline = time.monotonic() + self.stop_timeout_s
        while read_holder(path) is not None and time.monotonic() < deadline:
            time.sleep(0.2)
