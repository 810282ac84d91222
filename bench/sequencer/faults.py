"""Which faults end a run for good and which the bench recovers from.

A calibration bench in a lab meets faults that pass: a controller that stalls for seconds or
resets, a serial line or TCP link that drops, a burst of noise on the line, a DAQ whose reads
time out, a disk that fills up and is cleared. A run ended by one of them is *resumable*: its
recording is whole up to its last durable chunk, and it continues from the window after its
last complete one once the bench answers again (:mod:`station.execution.fault_retry`). A fault the
device reports itself (an axis following error, a Modbus exception code), a limit, a window
rejected after losing samples again and again, or a database that refuses the run's writes
says something about the bench or the run, not the link, and ends it as ERROR.
"""

from __future__ import annotations

from bench.sequencer.observers import ObserverError
from drivers.errors import DeviceTimeout, DriverError, LinkLost, ProtocolError


def resumable_fault(exc: BaseException) -> bool:
    """Whether a run ended by ``exc`` can continue once the bench is back: a device that did not
    answer in time (:class:`DeviceTimeout`: a stalled or resetting controller, a DAQ that sent
    nothing), a link that dropped (:class:`LinkLost`, any ``ConnectionError``), a reply that
    could not be read (:class:`ProtocolError`: a noisy line), or a recording write the system
    refused (an ``OSError`` such as a full disk; the recording is cut at its last durable
    chunk). Not: a device's own error report, a limit, a rejected window, a database refusal."""
    if isinstance(exc, ObserverError):
        return False
    if isinstance(exc, DeviceTimeout | LinkLost | ProtocolError | ConnectionError | TimeoutError):
        return True
    return isinstance(exc, OSError) and not isinstance(exc, DriverError)
