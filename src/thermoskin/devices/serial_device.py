"""The host side of the link over pyserial (real hardware, or the emulator's pseudo-terminal).

:meth:`SerialDevice.open` opens the port (``serial.serial_for_url``, so ``loop://`` and
``socket://`` URLs work too), drops whatever was waiting in the input buffer, and
sends HELLO every ``retry`` s until a HELLO_ACK of the same protocol version comes
back or ``handshake_timeout`` runs out. Reading is non-blocking: bytes are taken as
they come and decoded with :class:`~thermoskin.devices.protocol.Decoder` (damaged
frames counted and skipped); waiting uses ``select`` on the port's file descriptor.
The link counts as lost when no sample arrived for ``link_timeout`` s; any error on the
open port (a read or write that fails: the device unplugged, its emulator killed, EIO)
raises :class:`LinkError`, which the loop takes as a link fault at once.

**Sessions.** The port is opened for this host alone (an advisory lock, ``flock``, as
pyserial's ``exclusive``): a second ``thermoskin run`` on the same port is told so at once.
Each :meth:`open` starts a session of its own: its HELLOs carry a random session id in their
``seq``, so that the device answers a repeated HELLO of this session without restarting it,
starts a fresh session (clock at zero) for a new id, and refuses another host's HELLO while
a session is on (``HELLO_ACK`` status ``STATUS_BUSY``: :class:`DeviceError`, one line).
"""

from __future__ import annotations

import collections
import contextlib
import math
import os
import select
import time

import serial

from thermoskin.devices import protocol as proto
from thermoskin.devices.base import ChannelTracker, DeviceError, Sample

WRITE_TIMEOUT_S = 0.5
"""Longest wait for room in the port before a write is a link fault, s."""


class LinkError(DeviceError):
    """The link failed while in use (closed port, unplugged device, I/O error, a failed write).

    The loop takes it as a ``link`` fault, like a silent line (see ``runtime.supervisor``)."""


def _reason(e: BaseException) -> str:
    """An OS error's own words (``[Errno 5] Input/output error``), else the exception's text."""
    if isinstance(e, OSError) and e.errno is not None:
        return f"[Errno {e.errno}] {e.strerror}"
    return str(e) or type(e).__name__


class SerialDevice:
    """A skin device behind a serial port speaking :mod:`~thermoskin.devices.protocol`."""

    def __init__(self, port: str, *, baudrate: int = 2_000_000, t_s: float = 1.0e-3,
                 handshake_timeout: float = 3.0, retry: float = 0.2, link_timeout: float = 0.1,
                 stale_after: float = 0.5, stuck_after: int = 10, max_queue: int = 10_000) -> None:
        self.port = port
        self.baudrate = baudrate
        self.t_s = float(t_s)
        self.handshake_timeout = float(handshake_timeout)
        self.retry = float(retry)
        self.link_timeout = float(link_timeout)
        self.decoder = proto.Decoder()
        self.tracker = ChannelTracker(stale_after, stuck_after)
        self.ack: proto.HelloAck | None = None
        self.faults: list[tuple[float, proto.Fault]] = []
        """``(t_recv, fault)`` for every FAULT the device sent."""
        self.dropped = 0
        """Samples dropped because the queue was full (the host did not read fast enough)."""
        self._queue: collections.deque[Sample] = collections.deque()
        self._max_queue = max_queue
        self._ser: serial.SerialBase | None = None
        self._fd: int | None = None
        self._seq = 0
        self._t_last = math.nan
        self.session_id = 0
        """This host's session id (its HELLOs' ``seq``), new at each :meth:`open`."""
        self.extra_acks = 0
        """HELLO_ACKs after the session's first (a late answer to a repeated HELLO): ignored."""

    # -- connection ------------------------------------------------------------------------
    def open(self) -> None:
        """Open the port and handshake (a new session); :class:`DeviceError` names the port and
        the problem."""
        if self._ser is not None:  # open again: this host's session before ends first
            self.close()
        try:
            self._ser = serial.serial_for_url(self.port, baudrate=self.baudrate, timeout=0,
                                              write_timeout=WRITE_TIMEOUT_S, do_not_open=True)
            if hasattr(self._ser, "exclusive"):
                self._ser.exclusive = True  # one host per port (flock); URLs have no such thing
            self._ser.open()
        except (serial.SerialException, OSError, ValueError) as e:
            self._ser = None
            if "exclusively lock" in str(e):
                raise DeviceError(f"{self.port} is in use by another program (another thermoskin run?): "
                                  "one host at a time") from None
            raise DeviceError(f"cannot open {self.port}: {e}") from None
        try:
            self._fd = self._ser.fileno()
            os.set_blocking(self._fd, False)  # (pyserial opens it so; _write relies on it)
        except (AttributeError, NotImplementedError, OSError, ValueError):
            self._fd = None
        self._ser.reset_input_buffer()
        self.decoder.reset()
        self.tracker.reset()
        self._queue.clear()
        self.ack = None
        self.session_id = int.from_bytes(os.urandom(4), "little") or 1
        deadline = time.monotonic() + self.handshake_timeout
        next_hello = 0.0
        while self.ack is None:
            now = time.monotonic()
            if now >= deadline:
                self._close_port()
                raise DeviceError(f"no HELLO_ACK from {self.port} within {self.handshake_timeout:g} s "
                                  "(is the device or the emulator running?)")
            if now >= next_hello:
                self._send(proto.Hello(self.session_id, proto.PROTOCOL_VERSION, round(self.t_s * 1e6)),
                           leading_zero=True)
                next_hello = now + self.retry
            self._wait(min(next_hello, deadline) - now)
            self._pump_bytes()
        if self.ack.status == proto.STATUS_BUSY:
            self._close_port()
            raise DeviceError(f"the device at {self.port} is in a session with another host and "
                              "refused this one; stop that host first (its session ends a second "
                              "after it goes silent)")
        if self.ack.status != proto.STATUS_OK or self.ack.version != proto.PROTOCOL_VERSION:
            self._close_port()
            raise DeviceError(f"{self.port} speaks protocol version {self.ack.version} "
                              f"(status {self.ack.status}); this host speaks {proto.PROTOCOL_VERSION}")
        self._t_last = time.monotonic()

    def close(self) -> None:
        """Safe state (if the port is open), then close."""
        if self._ser is not None:
            with contextlib.suppress(serial.SerialException, OSError, DeviceError):
                self.safe()
            with contextlib.suppress(serial.SerialException, OSError):
                self._close_port()

    def _close_port(self) -> None:
        if self._ser is not None:
            try:
                self._ser.close()
            finally:
                self._ser = None
                self._fd = None

    def __enter__(self) -> SerialDevice:
        self.open()
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # -- properties ------------------------------------------------------------------------
    @property
    def tc_period(self) -> float:
        """Thermocouple update period announced by the device, s."""
        return self.ack.tc_period_us * 1e-6 if self.ack else math.nan

    @property
    def device_id(self) -> int:
        return self.ack.device_id if self.ack else -1

    @property
    def link_lost(self) -> bool:
        """No sample for longer than ``link_timeout`` s (host clock)."""
        return not time.monotonic() - self._t_last <= self.link_timeout

    def sample_age(self) -> float:
        """Seconds since the last sample arrived (host clock)."""
        return time.monotonic() - self._t_last

    # -- traffic ---------------------------------------------------------------------------
    def read_sample(self, timeout: float = 0.0) -> Sample | None:
        """The oldest unread sample, waiting up to ``timeout`` s for one; ``None`` otherwise."""
        if self._ser is None:
            raise LinkError(f"{self.port} is not open")
        if self._queue:
            return self._queue.popleft()
        self._pump_bytes()
        if self._queue:
            return self._queue.popleft()
        deadline = time.monotonic() + timeout
        while True:
            left = deadline - time.monotonic()
            if left <= 0.0:
                return None
            self._wait(left)
            self._pump_bytes()
            if self._queue:
                return self._queue.popleft()

    def pending(self) -> int:
        """Samples received and not yet read."""
        return len(self._queue)

    def write_command(self, drive: float, v: float) -> None:
        """Send a COMMAND: drive clipped to [-1, 1], ``v`` >= 0 m/s; NaN becomes 0."""
        d = drive if drive == drive else 0.0
        d = -1.0 if d < -1.0 else (1.0 if d > 1.0 else d)
        vv = v if v == v and v > 0.0 else 0.0
        self._seq = (self._seq + 1) % proto.SEQ_MOD
        self._send(proto.Command(self._seq, d, vv))

    def keepalive(self) -> None:
        """This session's HELLO again: a host that sends no COMMAND (it only listens) keeps its
        session on this way (the device ends a session whose host is silent for a second)."""
        self._send(proto.Hello(self.session_id, proto.PROTOCOL_VERSION, round(self.t_s * 1e6)))

    def safe(self) -> None:
        """Send SAFE (drive 0, pump off, latched in the device until the next HELLO)."""
        self._seq = (self._seq + 1) % proto.SEQ_MOD
        self._send(proto.Safe(self._seq))

    # -- internals -------------------------------------------------------------------------
    def _send(self, msg: proto.Message, leading_zero: bool = False) -> None:
        ser = self._ser
        if ser is None:
            raise LinkError(f"{self.port} is not open")
        frame = proto.encode(msg)
        try:
            self._write(ser, b"\x00" + frame if leading_zero else frame)
        except (serial.SerialException, OSError) as e:
            raise LinkError(f"{self.port}: write failed: {_reason(e)}") from None

    def _write(self, ser: serial.SerialBase, data: bytes) -> None:
        """Write all of ``data``, waiting at most :data:`WRITE_TIMEOUT_S` for room in the port.

        pyserial's own ``write`` also raises its "Write timeout" when every byte went out but the
        thread was then held up past the timeout (checked after the write: a process stalled
        half a second, a cold compile in another thread), which is no link fault; here only a
        port that takes no byte for that long is. Ports without a file descriptor (URLs) keep
        pyserial's write."""
        fd = self._fd
        if fd is None:
            ser.write(data)
            return
        view = memoryview(data)
        t_end = time.monotonic() + WRITE_TIMEOUT_S
        while len(view):
            try:
                view = view[os.write(fd, view):]
                continue
            except (BlockingIOError, InterruptedError):
                pass
            left = t_end - time.monotonic()
            if left <= 0.0 or not select.select([], [fd], [], left)[1]:
                raise serial.SerialTimeoutException("Write timeout")

    def _wait(self, timeout: float) -> None:
        if timeout <= 0.0:
            return
        if self._fd is not None:
            try:
                select.select([self._fd], [], [], timeout)
            except (OSError, ValueError) as e:
                raise LinkError(f"{self.port}: {_reason(e)}") from None
        else:
            time.sleep(min(timeout, 0.0005))

    def _pump_bytes(self) -> None:
        """Read what is waiting and turn it into samples, faults and acks."""
        ser = self._ser
        if ser is None:
            raise LinkError(f"{self.port} is not open")
        try:
            data = ser.read(max(ser.in_waiting, 1) if self._fd is None else 65536)
        except (serial.SerialException, OSError) as e:  # the device went away
            raise LinkError(f"{self.port}: read failed: {_reason(e)}") from None
        if not data:
            return
        now = time.monotonic()
        for msg in self.decoder.feed(data):
            t = msg.TYPE
            if t == proto.T_SAMPLE:
                if self.ack is None:
                    continue  # left over from before this session's HELLO_ACK
                self._on_sample(msg, now)  # type: ignore[arg-type]
            elif t == proto.T_HELLO_ACK:
                if self.ack is None:
                    self.ack = msg  # type: ignore[assignment]
                    self._seq = self.session_id  # this side's frames count on from its HELLO's
                else:  # a repeated HELLO's late answer (or one meant for another host)
                    self.extra_acks += 1
            elif t == proto.T_FAULT:
                self.faults.append((now, msg))  # type: ignore[arg-type]

    def _on_sample(self, m: proto.SampleMsg, now: float) -> None:
        t = m.t_us * 1e-6
        fresh, stale, stuck = self.tracker.update(t, (m.T_w, m.T_p, m.T_a), m.counters, m.fresh)
        s = Sample(t, m.T_w, m.T_p, m.T_a, fresh, m.seq, m.v, m.drive, m.status, stale, stuck, now)
        if len(self._queue) >= self._max_queue:
            self._queue.popleft()
            self.dropped += 1
        self._queue.append(s)
        self._t_last = now
