"""Which faults end a run for good and which the bench recovers from.

A calibration bench in a lab meets faults that pass: a controller that stalls for seconds or
resets, a serial line or TCP link that drops, a burst of noise on the line, a DAQ whose reads
time out, a disk that fills up and is cleared. A run ended by one of them is *resumable*: its
recording is whole up to its last durable chunk, and it continues from the window after its
last complete one once the bench answers again (:mod:`station.execution.fault_retry`). A fault the
device reports itself (an axis following error, a Modbus exception code), a limit, a window
rejected after losing samples again and again, or a database that refuses the run's writes
for another reason than a full disk (a constraint, a lost schema, a lock never released)
says something about the bench or the run, not the link, and ends it as ERROR. A database
that refuses a write because its disk is full (:func:`is_disk_full`: SQLite's ``database or
disk is full``, ``ENOSPC``) is the same full disk the recording meets: the run is resumable.
"""

from __future__ import annotations

import errno

from bench.sequencer.observers import ObserverError
from drivers.errors import DeviceTimeout, DriverError, LinkLost, ProtocolError


def resumable_fault(exc: BaseException) -> bool:
    """Whether a run ended by ``exc`` can continue once the bench is back: a device that did not
    answer in time (:class:`DeviceTimeout`: a stalled or resetting controller, a DAQ that sent
    nothing), a link that dropped (:class:`LinkLost`, any ``ConnectionError``), a reply that
    could not be read (:class:`ProtocolError`: a noisy line), or a recording write the system
    refused (an ``OSError`` such as a full disk; the recording is cut at its last durable
    chunk), or a database write refused because the disk is full (an :class:`ObserverError`
    caused by one, :func:`is_disk_full`). Not: a device's own error report, a limit, a rejected
    window, any other database refusal."""
    if isinstance(exc, ObserverError):
        return is_disk_full(exc)
    if isinstance(exc, DeviceTimeout | LinkLost | ProtocolError | ConnectionError | TimeoutError):
        return True
    return isinstance(exc, OSError) and not isinstance(exc, DriverError)


_DISK_FULL_TEXT = ("database or disk is full", "no space left on device", "could not extend file")


def is_disk_full(exc: BaseException) -> bool:
    """``exc`` says the disk (or the database's file system) is full: ``ENOSPC`` / ``EDQUOT``, or
    SQLite's ``database or disk is full`` (SQLITE_FULL), PostgreSQL's ``could not extend file`` —
    in ``exc`` or anything it was raised from (``__cause__``, ``__context__``, a driver error's
    ``orig``: an :class:`ObserverError` from SQLAlchemy from sqlite3)."""
    todo: list[BaseException] = [exc]
    seen: set[int] = set()
    while todo:
        e = todo.pop()
        if id(e) in seen or len(seen) > 32:
            continue
        seen.add(id(e))
        if isinstance(e, OSError) and e.errno in (errno.ENOSPC, errno.EDQUOT):
            return True
        if any(t in str(e).lower() for t in _DISK_FULL_TEXT):
            return True
        todo.extend(
            x for x in (getattr(e, "orig", None), e.__cause__, e.__context__) if isinstance(x, BaseException)
        )
    return False
