"""ModbusDaq: the calbench DAQ over Modbus TCP (pymodbus sync client + :mod:`drivers.daq_registers`).

Implements :class:`drivers.base.Daq`. The stream is read in buffered block mode: for the
next expected sequence number S the driver writes S to HR 420-421 and reads the window
header and first records in the same transaction (FC23, read/write multiple registers),
then the rest of the window in reads of at most 125 registers. If the window does not
start at S, the samples in between are gone and :class:`DataGap` names them; the driver
continues from the first sample the DAQ still has (a hole the module dropped) or, after a
ring overflow, half a ring behind the newest sample, so one gap names the whole lost range
instead of a gap on every read while the reader chases the oldest sample; nothing is ever
skipped silently.

Errors, each naming the device, the operation and the register range:

* Modbus exception 06 (busy) is retried until the call's deadline, then DeviceTimeout;
* other Modbus exceptions -> :class:`DeviceError` with ``code``;
* no reply within ``timeout_s`` (× ``retries + 1``) -> :class:`DeviceTimeout`;
* connection refused or reset -> :class:`LinkLost`;
* a reply that contradicts the register map -> :class:`ProtocolError`.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from typing import Any
from urllib.parse import urlsplit

import numpy as np
from pymodbus.client import ModbusTcpClient
from pymodbus.exceptions import ConnectionException, ModbusException, ModbusIOException

from drivers import daq_blocks as blk
from drivers import daq_registers as reg
from drivers.base import SampleBlock
from drivers.errors import DataGap, DeviceError, DeviceTimeout, DriverError, LinkLost, ProtocolError

EXCEPTION_NAMES = {
    1: "illegal function",
    2: "illegal data address",
    3: "illegal data value",
    4: "server device failure",
    5: "acknowledge",
    6: "server device busy",
    8: "memory parity error",
    10: "gateway path unavailable",
    11: "gateway target failed to respond",
}
BUSY = 6
_FIRST_READ_RECORDS = (reg.MAX_READ_REGS - reg.WINDOW_HEADER_REGS) // reg.RECORD_WORDS


class _Busy(Exception):
    pass


def parse_modbus_url(url: str) -> tuple[str, int]:
    """``modbus-tcp://host[:port]`` -> (host, port); port 502 by default.

    :raises ValueError: another scheme, no host, or a bad port.
    """
    parts = urlsplit(url)
    if parts.scheme != "modbus-tcp":
        raise ValueError(f"DAQ URL must be modbus-tcp://host:port, got {url!r}")
    try:
        port = parts.port or 502
    except ValueError:
        raise ValueError(f"DAQ URL {url!r}: port is not a number in 0..65535") from None
    if not parts.hostname:
        raise ValueError(f"DAQ URL {url!r} names no host")
    return parts.hostname, port


class ModbusDaq:
    """A DAQ speaking the calbench register map over Modbus TCP.

    :param url: ``modbus-tcp://host:port``.
    :param device_id: Modbus unit id.
    :param timeout_s: per-request reply timeout (s); a silent device is reported after
        at most ``timeout_s · (retries + 1)`` past a call's own deadline.
    :param retries: re-sends of an unanswered request.
    :param poll_interval_s: wait between polls while no new sample is available.
    :raises LinkLost: nothing accepts connections at the address.
    :raises ProtocolError: the device is not a calbench/ADAM-6017 DAQ (module id, layout).
    """

    def __init__(
        self,
        url: str,
        *,
        device_id: int = 1,
        timeout_s: float = 1.0,
        retries: int = 1,
        poll_interval_s: float = 0.005,
    ) -> None:
        self.host, self.port = parse_modbus_url(url)
        self.device_id = device_id
        self.timeout_s = timeout_s
        self.poll_interval_s = poll_interval_s
        self._where = f"DAQ modbus-tcp://{self.host}:{self.port} unit {device_id}"
        self._client = ModbusTcpClient(
            self.host, port=self.port, timeout=timeout_s, retries=retries, reconnect_delay=0.0
        )
        if not self._client.connect():  # type: ignore[no-untyped-call]  # pymodbus leaves it unannotated
            raise LinkLost(f"{self._where}: connection refused or unreachable")
        self._next_seq = 0
        self._started = False
        self._pending_gap: DataGap | None = None
        try:
            module_id = self._read(reg.HR_MODULE_ID, 1, self._deadline())[0]
            if module_id != reg.MODULE_ID:
                raise ProtocolError(
                    f"{self._where}: HR {reg.HR_MODULE_ID} module id 0x{module_id:04X}, expected 0x6017"
                )
            self._stream = self._read_stream_status(self._deadline())
        except BaseException:
            self._client.close()  # type: ignore[no-untyped-call]  # pymodbus leaves it unannotated
            raise

    # -- Daq protocol --------------------------------------------------------------
    @property
    def sample_rate_hz(self) -> float:
        """Sample rate (Hz) as the DAQ reports it (HR 404-405)."""
        return self._stream.sample_rate_hz

    @property
    def channel_unit(self) -> str:
        """Unit of the acceleration values (HR 411)."""
        return self._stream.channel_unit.text

    @property
    def full_scale(self) -> float:
        """The stream's channels clip at ± this value, in the channel unit (HR 412-413)."""
        return self._stream.full_scale

    @property
    def n_axes(self) -> int:
        """Table encoder axes latched with each sample (HR 409)."""
        return self._stream.n_axes

    def start(self) -> None:
        """Start the stream (HR 410 := 1); the sample counter restarts at 0."""
        deadline = self._deadline()
        self._write(reg.HR_ACQ_CONTROL, [1], deadline)
        self._stream = self._read_stream_status(deadline)
        self._next_seq = 0
        self._pending_gap = None
        self._started = True

    def stop(self) -> None:
        """Stop the stream (HR 410 := 0); buffered samples stay readable."""
        self._write(reg.HR_ACQ_CONTROL, [0], self._deadline())

    def read_block(self, max_samples: int, timeout_s: float) -> SampleBlock:
        """Samples since the last call, at most ``max_samples``; waits up to ``timeout_s`` for one.

        A call never runs much past ``timeout_s``: with a backlog larger than it can read in
        that time (≈17 round trips per 120 samples) it returns the samples read so far.

        Every returned block is gap-free (``first_seq`` … ``first_seq + n − 1``). A gap met
        after some samples were read ends the block there; the *next* call raises it before
        reading anything, so the caller sees the samples, then the gap, then what follows.
        A call that fails otherwise (timeout, link, protocol) consumes nothing: the next
        call starts again at the same sequence number.

        :raises DataGap: the next expected sample is gone (dropped, or overwritten in the
            ring); the following call continues after the gap.
        :raises DeviceTimeout: no new sample, or no reply, before ``timeout_s``.
        """
        if max_samples < 1:
            raise ValueError(f"max_samples must be >= 1, got {max_samples}")
        if not self._started:
            raise DriverError(f"{self._where}: read_block before start()")
        if self._pending_gap is not None:
            gap, self._pending_gap = self._pending_gap, None
            raise gap
        deadline = time.monotonic() + timeout_s
        parts: list[blk.DecodedRecords] = []
        first_seq = self._next_seq
        got = 0
        try:
            while got < max_samples:
                try:
                    n_valid, records = self._read_window(max_samples - got, deadline)
                except DataGap as gap:
                    if got:
                        self._pending_gap = gap  # raised by the next call, after these samples
                        break
                    raise
                if n_valid == 0:
                    if got:
                        break
                    if time.monotonic() >= deadline:
                        raise DeviceTimeout(
                            f"{self._where}: no new sample within {timeout_s} s "
                            f"(waiting for sequence {self._next_seq})"
                        )
                    time.sleep(max(0.0, min(self.poll_interval_s, deadline - time.monotonic())))
                    continue
                parts.append(records)
                got += records.accel.shape[0]
                self._next_seq += records.accel.shape[0]
                if n_valid < reg.WINDOW_CAPACITY:
                    break  # the window held everything available
                if time.monotonic() >= deadline:
                    break  # a backlog read slowly: hand over what came within the call's time
        except DataGap:
            raise
        except BaseException:
            self._next_seq = first_seq  # nothing delivered, nothing consumed
            raise
        return self._block(first_seq, parts)

    def status(self) -> dict[str, object]:
        """Channel flags by name, temperature (°C), counter, unread samples, ring size."""
        deadline = self._deadline()
        words = self._read(reg.HR_AI_STATUS, 2 * 3, deadline)
        flags = {}
        for c, name in enumerate(reg.CHANNEL_NAMES):
            bits = reg.ChannelStatus(reg.regs_to_u32(words[2 * c : 2 * c + 2]))
            flags[name] = sorted(f.name.lower() for f in reg.ChannelStatus if f in bits and f.name)
        temp_c = reg.regs_to_f32(self._read(reg.HR_TEMPERATURE, 2, deadline))
        stream = self._read_stream_status(deadline)
        counter = reg.unwrap_seq(stream.counter32, self._next_seq)
        return {
            "flags": flags,
            "temp_c": temp_c,
            "running": stream.running,
            "sample_rate_hz": stream.sample_rate_hz,
            "channel_unit": stream.channel_unit.text,
            "sample_counter": counter,
            "next_seq": self._next_seq,
            "buffer_fill": max(0, counter - self._next_seq) if self._started else 0,
            "ring_capacity": stream.ring_capacity,
        }

    def close(self) -> None:
        """Close the TCP connection (idempotent)."""
        self._client.close()  # type: ignore[no-untyped-call]  # pymodbus leaves it unannotated

    def __enter__(self) -> ModbusDaq:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- block reading -------------------------------------------------------------
    def _read_window(self, want: int, deadline: float) -> tuple[int, blk.DecodedRecords]:
        """Window at ``self._next_seq``: (samples available in it, the first ``want`` decoded)."""
        expected = self._next_seq
        n_first = reg.WINDOW_HEADER_REGS + _FIRST_READ_RECORDS * reg.RECORD_WORDS
        regs = self._call(
            lambda: self._client.readwrite_registers(
                read_address=reg.HR_WINDOW,
                read_count=n_first,
                write_address=reg.HR_READ_FROM_SEQ,
                values=reg.u32_to_regs(expected % reg.SEQ_MODULUS),
                device_id=self.device_id,
            ),
            f"FC23 write HR {reg.HR_READ_FROM_SEQ}-{reg.HR_READ_FROM_SEQ + 1}, read",
            reg.HR_WINDOW,
            n_first,
            deadline,
        )
        try:
            header = blk.decode_window_header(regs[: reg.WINDOW_HEADER_REGS])
        except ValueError as exc:
            raise ProtocolError(f"{self._where}: HR {reg.HR_WINDOW}: {exc}", str(regs[:4])) from None
        first = reg.unwrap_seq(header.first_seq32, expected)
        if first < expected:
            raise ProtocolError(
                f"{self._where}: window starts at sequence {first}, before the requested {expected}"
            )
        if first != expected:
            resync = self._resync_point(first, deadline)
            self._next_seq = resync
            raise DataGap(expected, resync, "dropped" if resync == first else "overflow")
        n = min(header.n_valid, want)
        words = regs[reg.WINDOW_HEADER_REGS :]
        need = n * reg.RECORD_WORDS
        start = reg.HR_RECORDS + len(words)
        for address, count in blk.read_spans(start, max(0, need - len(words))):
            words += self._read(address, count, deadline)
        records = blk.decode_records(words[:need], self._stream.n_axes)
        expect16 = (expected + np.arange(n)) & 0xFFFF
        if not np.array_equal(records.seq16, expect16):
            raise ProtocolError(
                f"{self._where}: window records out of sequence from {expected}", str(records.seq16[:8])
            )
        return header.n_valid, records

    def _resync_point(self, first: int, deadline: float) -> int:
        """Where to continue after a gap whose first sample still held is ``first``.

        Samples dropped by the module leave a hole and the ring is not full: continue at
        ``first``. When the ring overflowed (the reader fell behind), ``first`` is the oldest
        sample, about to be overwritten; continuing there would lose the race again on every
        read. Continue half a ring behind the newest sample instead, so one gap names the
        whole lost range and the reader has half the ring as slack to catch up.
        """
        stream = self._read_stream_status(deadline)
        counter = reg.unwrap_seq(stream.counter32, first)
        slack = max(1, stream.ring_capacity // 2)
        return max(first, counter - slack)

    def _block(self, first_seq: int, parts: list[blk.DecodedRecords]) -> SampleBlock:
        n_axes = self._stream.n_axes
        if parts:
            accel = np.concatenate([p.accel for p in parts])
            temp = np.concatenate([p.temp_c for p in parts])
            enc = np.concatenate([p.encoder_deg for p in parts])
            status = int(np.bitwise_or.reduce(np.concatenate([p.status for p in parts])))
        else:
            accel, temp, enc, status = np.zeros((0, 3)), np.zeros(0), np.zeros((0, n_axes)), 0
        n = accel.shape[0]
        t_s = (first_seq + np.arange(n)) / self._stream.sample_rate_hz
        return SampleBlock(
            first_seq=first_seq,
            t_s=t_s,
            accel=accel,
            temp_c=temp,
            table_deg=enc if n_axes else None,
            flags=reg.sample_status_names(status),
        )

    # -- register access -----------------------------------------------------------
    def _deadline(self) -> float:
        return time.monotonic() + self.timeout_s

    def _read_stream_status(self, deadline: float) -> blk.StreamStatus:
        regs = self._read(reg.HR_SAMPLE_COUNTER, reg.STREAM_STATUS_REGS, deadline)
        try:
            return blk.decode_stream_status(regs)
        except ValueError as exc:
            raise ProtocolError(f"{self._where}: stream status HR 400-413: {exc}", str(regs)) from None

    def _read(self, address: int, count: int, deadline: float) -> list[int]:
        return self._call(
            lambda: self._client.read_holding_registers(address, count=count, device_id=self.device_id),
            "read",
            address,
            count,
            deadline,
        )

    def _write(self, address: int, values: list[int], deadline: float) -> None:
        self._call(
            lambda: self._client.write_registers(address, values, device_id=self.device_id),
            "write",
            address,
            len(values),
            deadline,
        )

    def _call(
        self, request: Callable[[], Any], what: str, address: int, count: int, deadline: float
    ) -> list[int]:
        span = f"HR {address}-{address + count - 1}"
        while True:
            try:
                return self._call_once(request, what, span)
            except _Busy:
                if time.monotonic() >= deadline:
                    raise DeviceTimeout(  # noqa: B904 (busy is a state, not a cause)
                        f"{self._where}: still busy (exception 06) at the deadline, {what} {span}"
                    )
                time.sleep(self.poll_interval_s)

    def _call_once(self, request: Callable[[], Any], what: str, span: str) -> list[int]:
        try:
            rr = request()
        except ConnectionException as exc:
            raise LinkLost(f"{self._where}: link lost on {what} {span}: {exc}") from None
        except ModbusIOException as exc:
            if not self._client.connected:
                raise LinkLost(f"{self._where}: link lost on {what} {span}: {exc}") from None
            raise DeviceTimeout(
                f"{self._where}: no reply to {what} {span} within {self.timeout_s} s"
            ) from None
        except ModbusException as exc:
            raise ProtocolError(f"{self._where}: {what} {span}: {exc}") from None
        except OSError as exc:
            raise LinkLost(f"{self._where}: link lost on {what} {span}: {exc}") from None
        if rr.isError():
            code = int(getattr(rr, "exception_code", 0))
            if code == BUSY:
                raise _Busy()
            name = EXCEPTION_NAMES.get(code, "unknown exception")
            raise DeviceError(
                f"{self._where}: Modbus exception {code:02d} ({name}) on {what} {span}", code=code
            )
        registers = getattr(rr, "registers", None)
        if registers is None:
            return []
        return list(registers)
