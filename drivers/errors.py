"""Errors raised by table and DAQ drivers.

One root, :class:`DriverError`; each subclass also inherits the builtin a caller would
naturally catch (ophyd's ``LimitError(ValueError, OpException)`` pattern), so
``except TimeoutError`` catches a :class:`DeviceTimeout` too.
"""

from __future__ import annotations


class DriverError(Exception):
    """Root of every error a driver raises."""


class DeviceTimeout(DriverError, TimeoutError):
    """A device did not answer, or did not finish an operation, before its deadline."""


class LinkLost(DriverError, ConnectionError):
    """The transport to the device is gone (port closed, socket reset, TCP connect refused)."""


class ProtocolError(DriverError):
    """A reply could not be understood.

    :param message: what was wrong.
    :param line: the offending reply exactly as received (``None`` if there was none).
    """

    def __init__(self, message: str, line: str | bytes | None = None) -> None:
        self.line = line
        super().__init__(f"{message}: {line!r}" if line is not None else message)


class DeviceError(DriverError):
    """The device answered with an error of its own (error queue entry, Modbus exception code).

    :param message: the device's error text, prefixed with what was asked.
    :param code: the device's numeric error code, when it gives one.
    """

    def __init__(self, message: str, code: int | None = None) -> None:
        self.code = code
        super().__init__(message)


class InterlockOpen(DriverError, RuntimeError):
    """The table's interlock or emergency stop is open: no motion is possible."""


class LimitError(DriverError, ValueError):
    """A demand lies outside a device limit (angle, rate, acceleration, channel range)."""


class DataGap(DriverError):
    """Samples were lost between two blocks: the sample counter jumped.

    The samples ``expected_seq … got_seq − 1`` were produced by the DAQ and will never be
    delivered; ``got_seq`` is the next sample the reader delivers.

    :param expected_seq: sequence number that should have come next.
    :param got_seq: sequence number that came.
    :param cause: why, one word: ``"dropped"`` (the module never kept them),
        ``"overflow"`` (the ring overwrote them before the host read them) or ``""``.
    """

    def __init__(self, expected_seq: int, got_seq: int, cause: str = "") -> None:
        self.expected_seq = expected_seq
        self.got_seq = got_seq
        self.cause = cause
        why = f", {cause}" if cause else ""
        super().__init__(
            f"DAQ sample gap: expected sequence {expected_seq}, got {got_seq} "
            f"({got_seq - expected_seq} samples lost{why})"
        )

    @property
    def n_lost(self) -> int:
        """Samples lost (``got_seq − expected_seq``)."""
        return self.got_seq - self.expected_seq
