"""Simulated DAQ: a pymodbus TCP server on loopback whose registers follow a :class:`DaqEngine`.

The register map is :mod:`drivers.daq_registers`. The server runs its own asyncio loop in
a daemon thread (pymodbus servers must be built inside a running loop). A request that
touches HR 0-413 first brings the engine up to the simulated now and refreshes the
instantaneous and stream-status registers; a write of HR 420-421 copies a window of the ring into
HR 500...; a write of HR 410 starts (1) or stops (0) the stream; type codes (HR 200-207)
accept only known codes, anything else is answered with exception 03.

Faults injected at run time (thread-safe):

* :meth:`DaqServer.inject_exception` — answer the next requests with Modbus exception
  02 (illegal address), 04 (device failure), 06 (busy) or any other code;
* :meth:`DaqServer.set_silent` — read requests but never answer (a hung device);
* :meth:`DaqServer.drop_replies` — handle the next requests but lose their replies (a
  flaky link: the request took effect, the answer never came);
* :meth:`DaqServer.drop_samples` / :meth:`DaqServer.set_open_circuit` — see the engine;
* :meth:`DaqServer.close` — stop listening: new connections are refused.
"""

from __future__ import annotations

import asyncio
import contextlib
import socket
import threading

from pymodbus.constants import ExcCodes
from pymodbus.server import ModbusTcpServer
from pymodbus.simulator import DataType, SimData, SimDevice

from drivers import daq_blocks as blk
from drivers import daq_registers as reg
from drivers.sim.daq_engine import DaqEngine

_WRITABLE = {reg.HR_ACQ_CONTROL, reg.HR_READ_FROM_SEQ, reg.HR_READ_FROM_SEQ + 1} | set(
    range(reg.HR_TYPE_CODE, reg.HR_TYPE_CODE + reg.N_CHANNELS)
)


def free_tcp_port(host: str = "127.0.0.1") -> int:
    """An ephemeral TCP port that was free a moment ago."""
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind((host, 0))
        return int(s.getsockname()[1])


def _regs(address: int, count: int, value: int = 0, readonly: bool = True) -> SimData:
    return SimData(address, count=count, values=value, datatype=DataType.REGISTERS, readonly=readonly)


class DaqServer:
    """Modbus TCP server for one :class:`DaqEngine`.

    :param engine: the sampling engine.
    :param host: interface to listen on (loopback by default).
    :param port: TCP port; 0 picks a free ephemeral port.
    :param device_id: Modbus unit id answered (pymodbus 3.16 answers other ids with
        exception 04, device failure).
    :param start_timeout_s: how long to wait for the listener.
    """

    def __init__(
        self,
        engine: DaqEngine,
        *,
        host: str = "127.0.0.1",
        port: int = 0,
        device_id: int = 1,
        start_timeout_s: float = 5.0,
    ) -> None:
        self.engine = engine
        self.host = host
        self.port = port or free_tcp_port(host)
        self.device_id = device_id
        self._lock = threading.Lock()
        self._exc_code: int | None = None
        self._exc_left: int | None = None
        self._silent = False
        self._drop_skip = 0
        self._drop_left = 0
        self._type_codes = [0x0143 if engine.unit is reg.ChannelUnit.V else reg.TYPE_CODE_ENGINEERING] * 8
        self._requests = 0
        self._loop: asyncio.AbstractEventLoop | None = None
        self._server: ModbusTcpServer | None = None
        self._stop: asyncio.Event | None = None
        self._ready = threading.Event()
        self._error: BaseException | None = None
        self._thread = threading.Thread(target=self._run, name=f"sim-daq-{self.port}", daemon=True)
        self._thread.start()
        if not self._ready.wait(start_timeout_s):
            raise TimeoutError(
                f"simulated DAQ on {self.host}:{self.port} did not start in {start_timeout_s} s"
            )
        if self._error is not None:
            raise RuntimeError(f"simulated DAQ on {self.host}:{self.port} failed to start") from self._error

    @property
    def url(self) -> str:
        """``modbus-tcp://host:port``."""
        return f"modbus-tcp://{self.host}:{self.port}"

    @property
    def requests(self) -> int:
        """Requests handled so far (answered or not)."""
        return self._requests

    # -- faults --------------------------------------------------------------------
    def inject_exception(self, code: int, n_requests: int | None = 1) -> None:
        """Answer the next ``n_requests`` requests (``None``: all, until cleared) with ``code``."""
        ExcCodes(code)  # rejects codes Modbus does not define
        with self._lock:
            self._exc_code, self._exc_left = code, n_requests

    def set_silent(self, silent: bool) -> None:
        """Stop (or resume) answering: requests are read and dropped."""
        with self._lock:
            self._silent = silent

    def drop_replies(self, n: int, after: int = 0) -> None:
        """Send the next ``after`` replies, then lose ``n`` (their requests still take effect)."""
        if n < 0 or after < 0:
            raise ValueError(f"reply counts must be >= 0, got n={n}, after={after}")
        with self._lock:
            self._drop_skip, self._drop_left = after, n

    def clear_faults(self) -> None:
        """Remove injected exceptions, silence and reply drops (engine faults stay)."""
        with self._lock:
            self._exc_code = self._exc_left = None
            self._silent = False
            self._drop_skip = self._drop_left = 0

    def drop_connections(self) -> int:
        """Close every client's TCP connection from the server's side, as a DAQ that resets its
        network stack or a switch that drops the line does; the server keeps listening, so a
        client may connect again. Returns how many connections were closed."""
        loop, server = self._loop, self._server
        if loop is None or server is None:
            return 0
        done = threading.Event()
        closed = [0]

        def close_all() -> None:
            conns = list(server.active_connections.values())
            for conn in conns:
                conn.close()
            closed[0] = len(conns)
            done.set()

        loop.call_soon_threadsafe(close_all)
        done.wait(5.0)
        return closed[0]

    def drop_samples(self, n: int) -> None:
        """The next ``n`` samples are lost inside the DAQ (see :meth:`DaqEngine.drop_next`)."""
        self.engine.drop_next(n)

    def set_open_circuit(self, channel: int, on: bool = True) -> None:
        """Open (or reconnect) acceleration channel 0-2."""
        self.engine.set_open_circuit(channel, on)

    # -- lifecycle -----------------------------------------------------------------
    def close(self) -> None:
        """Stop the server and its thread; further connections are refused. Idempotent."""
        loop, stop = self._loop, self._stop
        if loop is not None and stop is not None and not loop.is_closed():
            with contextlib.suppress(RuntimeError):  # loop already closed
                loop.call_soon_threadsafe(stop.set)
        self._thread.join(timeout=5.0)

    def __enter__(self) -> DaqServer:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- server thread -------------------------------------------------------------
    def _run(self) -> None:
        try:
            asyncio.run(self._serve())
        except BaseException as exc:  # reported to the constructor, or lost at shutdown
            self._error = exc
            self._ready.set()

    async def _serve(self) -> None:
        self._loop = asyncio.get_running_loop()
        self._stop = asyncio.Event()
        device = SimDevice(
            id=self.device_id,
            simdata=[
                _regs(reg.HR_AI_RAW, reg.N_CHANNELS, 32768),
                _regs(reg.HR_AI_STATUS, 2 * reg.N_CHANNELS),
                _regs(reg.HR_TYPE_CODE, reg.N_CHANNELS, self._type_codes[0], readonly=False),
                _regs(reg.HR_MODULE_ID, 1, reg.MODULE_ID),
                _regs(reg.HR_TEMPERATURE, 2),
                _regs(reg.HR_SAMPLE_COUNTER, reg.HR_ACQ_CONTROL - reg.HR_SAMPLE_COUNTER),
                _regs(reg.HR_ACQ_CONTROL, 1, readonly=False),
                _regs(
                    reg.HR_CHANNEL_UNIT,
                    reg.STREAM_STATUS_REGS - (reg.HR_CHANNEL_UNIT - reg.HR_SAMPLE_COUNTER),
                ),
                _regs(reg.HR_READ_FROM_SEQ, 2, readonly=False),
                _regs(reg.HR_WINDOW, reg.HR_END - reg.HR_WINDOW),
            ],
            action=self._action,
        )
        server = ModbusTcpServer(
            device,
            address=(self.host, self.port),
            trace_packet=self._trace_packet,
            ignore_missing_devices=False,
        )
        self._server = server
        try:
            await server.serve_forever(background=True)
        except BaseException as exc:
            self._error = exc
            self._ready.set()
            return
        self._ready.set()
        try:
            await self._stop.wait()
        finally:
            await server.shutdown()  # type: ignore[no-untyped-call]  # pymodbus leaves it unannotated

    def _trace_packet(self, sending: bool, data: bytes) -> bytes:
        if not sending:
            return data
        if self._silent:
            return b""
        with self._lock:
            if self._drop_left:
                if self._drop_skip:
                    self._drop_skip -= 1
                else:
                    self._drop_left -= 1
                    return b""
        return data

    async def _action(
        self,
        function_code: int,
        start_address: int,
        address: int,
        count: int,
        registers: list[int],
        set_values: list[int] | list[bool] | None,
    ) -> ExcCodes | None:
        with self._lock:
            self._requests += 1
            if self._silent:
                return None
            if self._exc_code is not None:
                code = ExcCodes(self._exc_code)
                if self._exc_left is not None:
                    self._exc_left -= 1
                    if self._exc_left <= 0:
                        self._exc_code = self._exc_left = None
                return code
        if set_values is not None:
            result = self._write(address, [int(v) for v in set_values], registers, start_address)
            if result is not None:
                return result
        if address < reg.HR_READ_FROM_SEQ:
            # Window reads skip this: the window is a snapshot taken at the HR 420 write,
            # and the physics runs once per poll rather than once per request.
            self._refresh(registers, start_address)
        return None

    def _write(self, address: int, values: list[int], registers: list[int], base: int) -> ExcCodes | None:
        span = range(address, address + len(values))
        if any(a not in _WRITABLE for a in span):
            return ExcCodes.ILLEGAL_ADDRESS
        seq_regs = {reg.HR_READ_FROM_SEQ, reg.HR_READ_FROM_SEQ + 1}
        if seq_regs & set(span) and not seq_regs <= set(span):
            return ExcCodes.ILLEGAL_VALUE  # the start sequence is written as one 32-bit value
        for a, v in zip(span, values, strict=True):
            is_type_code = reg.HR_TYPE_CODE <= a < reg.HR_TYPE_CODE + reg.N_CHANNELS
            if is_type_code and v not in reg.TYPE_CODES and v != reg.TYPE_CODE_ENGINEERING:
                return ExcCodes.ILLEGAL_VALUE
            if a == reg.HR_ACQ_CONTROL and v not in (0, 1):
                return ExcCodes.ILLEGAL_VALUE
        for a, v in zip(span, values, strict=True):
            if reg.HR_TYPE_CODE <= a < reg.HR_TYPE_CODE + reg.N_CHANNELS:
                self._type_codes[a - reg.HR_TYPE_CODE] = v
            elif a == reg.HR_ACQ_CONTROL:
                self.engine.start() if v else self.engine.stop()
        if reg.HR_READ_FROM_SEQ in span:
            i = reg.HR_READ_FROM_SEQ - address
            self._fill_window(reg.regs_to_u32(values[i : i + 2]), registers, base)
        return None

    def _fill_window(self, from_seq32: int, registers: list[int], base: int) -> None:
        counter = self.engine.counter
        from_seq = reg.unwrap_seq(from_seq32, counter)
        win = self.engine.window(from_seq)
        header = blk.encode_window_header(win.first_seq, win.n)
        o = reg.HR_WINDOW - base
        registers[o : o + reg.WINDOW_HEADER_REGS] = header
        o = reg.HR_RECORDS - base
        registers[o : o + win.registers.shape[0]] = win.registers.tolist()

    def _refresh(self, registers: list[int], base: int) -> None:
        engine = self.engine
        engine.update()
        latest = engine.latest()
        for c in range(reg.N_CHANNELS):
            code = self._type_codes[c]
            rng = reg.input_range(code, engine.full_scale)
            value = float(latest.accel[c]) if c < 3 else 0.0
            status = 0
            if c < 3:
                if latest.status & reg.sample_status_bit(c, "open"):
                    status |= reg.ChannelStatus.OPEN_CIRCUIT
                if latest.status & reg.sample_status_bit(c, "over"):
                    status |= reg.ChannelStatus.OVER_RANGE
                if latest.status & reg.sample_status_bit(c, "under"):
                    status |= reg.ChannelStatus.UNDER_RANGE
            raw = 0xFFFF if status & reg.ChannelStatus.OPEN_CIRCUIT else reg.value_to_raw(value, rng)
            registers[reg.HR_AI_RAW + c - base] = raw
            o = reg.HR_AI_STATUS + 2 * c - base
            registers[o : o + 2] = reg.u32_to_regs(int(status))
            registers[reg.HR_TYPE_CODE + c - base] = code
        o = reg.HR_TEMPERATURE - base
        registers[o : o + 2] = reg.f32_to_regs(latest.temp_c)
        status_block = blk.encode_stream_status(
            blk.StreamStatus(
                counter32=engine.counter,
                oldest32=engine.oldest_seq,
                sample_rate_hz=engine.sample_rate_hz,
                ring_capacity=engine.capacity,
                n_axes=engine.n_axes,
                running=engine.running,
                channel_unit=engine.unit,
                full_scale=engine.full_scale,
            )
        )
        o = reg.HR_SAMPLE_COUNTER - base
        registers[o : o + reg.STREAM_STATUS_REGS] = status_block
