"""A simulated bench in its own process, so that it behaves like hardware.

A :class:`~drivers.sim.bench.SimBench` in the process that also drives it shares that
process's interpreter lock and CPU with the web server, the sequencer and the fit: a busy
host then slows the *simulated instrument* down, which no real table or DAQ would do.
:class:`SimBenchProcess` starts the SimBench in a spawned child process and hands back its
loopback URLs, believed geometry, local g and channel unit; the drivers connect to it over
TCP exactly as to hardware.

SIGUSR1 to the child cuts the table's client connections while the simulated controller runs
on (a lost line, as a test injects it). The child lives while the pipe to its parent is
open: :meth:`SimBenchProcess.close` ends it, and so does the parent's death (the pipe
reaches end of file), so no simulator outlives the
process that owns the bench.
"""

from __future__ import annotations

import contextlib
import multiprocessing
import multiprocessing.connection
import signal
from typing import Any

import numpy as np

from drivers.sim.bench import BenchGeometry, SimBench
from drivers.sim.physics import SensorTruth

START_TIMEOUT_S = 120.0
"""Generous deadline for the child to import numpy/pymodbus and open its ports (loaded host)."""


def _serve(
    conn: multiprocessing.connection.Connection, truth: SensorTruth | None, kwargs: dict[str, Any]
) -> None:
    """Child process: run the SimBench until told to close or until the parent is gone."""
    try:
        bench = SimBench(truth, **kwargs)
    except BaseException as exc:
        conn.send(("error", f"{type(exc).__name__}: {exc}"))
        return
    # SIGUSR1: a lost line; the table's client connections drop, the controller runs on
    signal.signal(signal.SIGUSR1, lambda signum, frame: bench.table_server.drop_connections())
    try:
        geo = bench.geometry
        conn.send(
            (
                "ready",
                {
                    "table_url": bench.table_url,
                    "daq_url": bench.daq_url,
                    "axes": geo.axes.tolist(),
                    "mount_rotation": geo.mount_rotation.tolist(),
                    "lever_arm_m": geo.lever_arm_m.tolist(),
                    "g_local_m_s2": bench.g_local_m_s2,
                    "channel_unit": bench.channel_unit,
                    "sample_rate_hz": bench.sample_rate_hz,
                },
            )
        )
        while True:
            try:
                msg = conn.recv()
            except (EOFError, OSError):  # the parent died or closed the pipe
                return
            if msg == "close":
                return
    finally:
        bench.close()


class SimBenchProcess:
    """A :class:`SimBench` (same keyword arguments) served from a spawned child process.

    :attr:`table_url`, :attr:`daq_url`, :attr:`geometry`, :attr:`g_local_m_s2`,
    :attr:`channel_unit` and :attr:`sample_rate_hz` are those of the SimBench in the child.

    :raises ValueError: the SimBench refused its arguments (the child's message).
    :raises RuntimeError: the child did not start within :data:`START_TIMEOUT_S`.
    """

    def __init__(self, truth: SensorTruth | None = None, **kwargs: Any) -> None:
        ctx = multiprocessing.get_context("spawn")
        self._conn, child = ctx.Pipe()
        self.process = ctx.Process(
            target=_serve, args=(child, truth, kwargs), name="calbench-sim", daemon=True
        )
        self.process.start()
        child.close()
        try:
            if not self._conn.poll(START_TIMEOUT_S):
                raise RuntimeError(
                    f"simulated bench process {self.process.pid} did not start in {START_TIMEOUT_S:g} s"
                )
            kind, info = self._conn.recv()
        except EOFError:
            self.close()
            raise RuntimeError(
                f"simulated bench process {self.process.pid} ended before it was ready (exit code "
                f"{self.process.exitcode})"
            ) from None
        except BaseException:
            self.close()
            raise
        if kind != "ready":
            self.close()
            raise ValueError(f"simulated bench: {info}")
        self.table_url: str = info["table_url"]
        self.daq_url: str = info["daq_url"]
        self.geometry = BenchGeometry(
            np.asarray(info["axes"], dtype=float),
            np.asarray(info["mount_rotation"], dtype=float),
            np.asarray(info["lever_arm_m"], dtype=float),
        )
        self.g_local_m_s2: float = float(info["g_local_m_s2"])
        self.channel_unit: str = str(info["channel_unit"])
        self.sample_rate_hz: float = float(info["sample_rate_hz"])

    @property
    def pid(self) -> int | None:
        """The child's process id."""
        return self.process.pid

    def close(self, timeout_s: float = 10.0) -> None:
        """Stop the servers and the child (idempotent); connected drivers see their links drop."""
        with contextlib.suppress(OSError, ValueError):
            self._conn.send("close")
        self.process.join(timeout_s)
        if self.process.is_alive():
            self.process.terminate()
            self.process.join(timeout_s)
        if self.process.is_alive():  # stopped (SIGSTOP) or hung: SIGTERM waits, SIGKILL does not
            self.process.kill()
            self.process.join(timeout_s)
        self._conn.close()

    def __enter__(self) -> SimBenchProcess:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()
