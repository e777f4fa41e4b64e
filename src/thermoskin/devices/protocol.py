"""The binary link protocol between the host and a skin device (see ``docs/protocol.md``).

A frame on the wire is ``COBS(packet) + b"\\x00"``; a packet is::

    type u8 | seq u32 | body (fixed length per type) | crc u16

all little-endian, with ``crc`` the CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, no
reflection, no final xor; ``binascii.crc_hqx(data, 0xFFFF)``) of ``type | seq | body``.
Each side numbers the frames it sends with one counter ``seq`` (u32, wrapping); a
receiver drops and counts a repeated or older ``seq`` (serial-number arithmetic), counts
a gap as lost frames, and restarts its sequence tracking on a HELLO or HELLO_ACK.

:class:`Decoder` never raises on bad input: a frame with a bad COBS code, a bad CRC, a
wrong length or an unknown type is counted in :class:`DecoderStats` and skipped.
"""

from __future__ import annotations

import binascii
import struct
from dataclasses import dataclass, field
from typing import ClassVar

PROTOCOL_VERSION = 1
"""Version sent in HELLO and HELLO_ACK; a device answers a version it does not speak with
``HelloAck.status = STATUS_BAD_VERSION``."""

MAX_PACKET = 250
"""Largest packet (type..crc) of this version; longer frames are dropped as oversize."""

SEQ_MOD = 1 << 32

# message types
T_HELLO = 0x01
T_HELLO_ACK = 0x02
T_SAMPLE = 0x10
T_COMMAND = 0x20
T_SAFE = 0x21
T_FAULT = 0x30

# SAMPLE.fresh / stale bits, one per thermocouple channel
CH_W = 0x01
CH_P = 0x02
CH_A = 0x04
CHANNELS = ("T_w", "T_p", "T_a")
CHANNEL_BITS = (CH_W, CH_P, CH_A)

# SAMPLE.status bits
ST_OPEN_W = 0x0001
"""Open thermocouple on T_w (the converter's open-circuit detection)."""
ST_OPEN_P = 0x0002
ST_OPEN_A = 0x0004
ST_SAFE = 0x0010
"""The device is in its safe state (drive 0, pump off), latched by SAFE until the next HELLO."""
ST_WATCHDOG = 0x0020
"""No COMMAND for longer than the device's command timeout: drive 0, pump off until the next."""
ST_OVERRUN = 0x0040
"""The device missed sample deadlines since the last SAMPLE."""
ST_NO_COMMAND = 0x0080
"""No COMMAND received yet since the HELLO."""

# HELLO_ACK.status
STATUS_OK = 0
STATUS_BAD_VERSION = 1
STATUS_BUSY = 2
"""Another host's session is on: this HELLO starts none (docs/protocol.md, Session and timing)."""

# FAULT.code
F_TC_OPEN = 1
F_OVERTEMP = 2
F_INTERNAL = 3
F_TC_RANGE = 4
"""A converter's range or over/under-voltage fault (MAX31856 ``TCRANGE``, ``CJRANGE``, ``OVUV``)."""
F_WATCHDOG = 5
"""No COMMAND within the device's watchdog time: it went to its safe state by itself."""
FAULT_NAMES = {F_TC_OPEN: "tc-open", F_OVERTEMP: "overtemp", F_INTERNAL: "internal",
               F_TC_RANGE: "tc-range", F_WATCHDOG: "watchdog"}

_HEAD = struct.Struct("<BI")


@dataclass(frozen=True, slots=True)
class Hello:
    """Host -> device: start (or restart) a session."""

    seq: int = 0
    version: int = PROTOCOL_VERSION
    t_s_us: int = 1000
    """Requested sample period, µs."""
    TYPE: ClassVar[int] = T_HELLO
    BODY: ClassVar[struct.Struct] = struct.Struct("<HI")

    def body(self) -> bytes:
        return self.BODY.pack(self.version, self.t_s_us)


@dataclass(frozen=True, slots=True)
class HelloAck:
    """Device -> host: answer to HELLO; ``tc_period_us`` is the thermocouple update period."""

    seq: int = 0
    version: int = PROTOCOL_VERSION
    status: int = STATUS_OK
    device_id: int = 0
    t_s_us: int = 1000
    tc_period_us: int = 100_000
    TYPE: ClassVar[int] = T_HELLO_ACK
    BODY: ClassVar[struct.Struct] = struct.Struct("<HHIII")

    def body(self) -> bytes:
        return self.BODY.pack(self.version, self.status, self.device_id, self.t_s_us, self.tc_period_us)


@dataclass(frozen=True, slots=True)
class SampleMsg:
    """Device -> host: one sample of the device clock ``t_us`` (µs since the host connected).

    ``T_w, T_p, T_a`` °C (NaN = no valid reading); ``fresh`` bit ``CH_*`` set when the
    channel's reading is new in this sample; ``counters`` the channels' update counters
    (u16, wrapping); ``v`` (m/s) and ``drive`` as applied by the device; ``cmd_seq`` the
    seq of the last COMMAND applied; ``status`` the ``ST_*`` bits.
    """

    seq: int
    t_us: int
    T_w: float
    T_p: float
    T_a: float
    fresh: int = 0
    status: int = 0
    counters: tuple[int, int, int] = (0, 0, 0)
    v: float = 0.0
    drive: float = 0.0
    cmd_seq: int = 0
    TYPE: ClassVar[int] = T_SAMPLE
    BODY: ClassVar[struct.Struct] = struct.Struct("<QfffBHHHHffI")

    def body(self) -> bytes:
        c = self.counters
        return self.BODY.pack(self.t_us, self.T_w, self.T_p, self.T_a, self.fresh, self.status,
                              c[0] & 0xFFFF, c[1] & 0xFFFF, c[2] & 0xFFFF, self.v, self.drive,
                              self.cmd_seq & 0xFFFFFFFF)


@dataclass(frozen=True, slots=True)
class Command:
    """Host -> device: Peltier ``drive`` in [-1, 1] (> 0 heats), pump velocity ``v`` m/s (0 = off)."""

    seq: int
    drive: float
    v: float
    TYPE: ClassVar[int] = T_COMMAND
    BODY: ClassVar[struct.Struct] = struct.Struct("<ff")

    def body(self) -> bytes:
        return self.BODY.pack(self.drive, self.v)


@dataclass(frozen=True, slots=True)
class Safe:
    """Host -> device: go to the safe state (drive 0, pump off) and stay there until the next HELLO."""

    seq: int = 0
    reason: int = 0
    TYPE: ClassVar[int] = T_SAFE
    BODY: ClassVar[struct.Struct] = struct.Struct("<H")

    def body(self) -> bytes:
        return self.BODY.pack(self.reason)


@dataclass(frozen=True, slots=True)
class Fault:
    """Device -> host: a fault the device itself detected (``F_*`` code, channel index, value)."""

    seq: int
    code: int
    channel: int = 0
    value: float = 0.0
    TYPE: ClassVar[int] = T_FAULT
    BODY: ClassVar[struct.Struct] = struct.Struct("<HBf")

    def body(self) -> bytes:
        return self.BODY.pack(self.code, self.channel, self.value)

    @property
    def name(self) -> str:
        return FAULT_NAMES.get(self.code, f"fault-{self.code}")


Message = Hello | HelloAck | SampleMsg | Command | Safe | Fault

_TYPES: dict[int, type] = {c.TYPE: c for c in (Hello, HelloAck, SampleMsg, Command, Safe, Fault)}
_BODY_LEN = {t: c.BODY.size for t, c in _TYPES.items()}
_SAMPLE_UNPACK = SampleMsg.BODY.unpack_from


# ----------------------------------------------------------------------------- COBS

def cobs_encode(data: bytes) -> bytes:
    """Consistent Overhead Byte Stuffing: ``data`` without zero bytes (the delimiter is added by the caller).

    Each zero-free run of up to 254 bytes is preceded by a code byte ``len(run) + 1``; a
    code of 0xFF means "254 bytes, no zero follows".
    """
    out = bytearray()
    for part in data.split(b"\x00"):
        while len(part) >= 254:
            out.append(0xFF)
            out += part[:254]
            part = part[254:]
        out.append(len(part) + 1)
        out += part
    return bytes(out)


def cobs_decode(data: bytes) -> bytes | None:
    """Inverse of :func:`cobs_encode`; ``None`` for an invalid encoding (a zero byte, a code past the end)."""
    if b"\x00" in data:
        return None
    out = bytearray()
    i = 0
    n = len(data)
    while i < n:
        code = data[i]
        if code == 0:
            return None
        j = i + code
        if j > n:
            return None
        out += data[i + 1:j]
        i = j
        if code != 0xFF and i < n:
            out.append(0)
    return bytes(out)


def crc16(data: bytes) -> int:
    """CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF): ``crc16(b"123456789") == 0x29B1``."""
    return binascii.crc_hqx(data, 0xFFFF)


# ----------------------------------------------------------------------------- encode / decode

def encode(msg: Message) -> bytes:
    """One frame: ``COBS(type | seq | body | crc16) + 0x00``."""
    packet = _HEAD.pack(msg.TYPE, msg.seq & 0xFFFFFFFF) + msg.body()
    return cobs_encode(packet + struct.pack("<H", binascii.crc_hqx(packet, 0xFFFF))) + b"\x00"


def decode_packet(packet: bytes) -> Message | str:
    """A message from an un-stuffed packet, or the name of what is wrong with it."""
    if len(packet) < 7:
        return "short"
    if binascii.crc_hqx(packet[:-2], 0xFFFF) != int.from_bytes(packet[-2:], "little"):
        return "crc"
    typ, seq = _HEAD.unpack_from(packet)
    n = _BODY_LEN.get(typ)
    if n is None:
        return "unknown_type"
    if len(packet) != 7 + n:
        return "bad_length"
    if typ == T_SAMPLE:
        t_us, Tw, Tp, Ta, fresh, status, c0, c1, c2, v, drive, cmd_seq = _SAMPLE_UNPACK(packet, 5)
        return SampleMsg(seq, t_us, Tw, Tp, Ta, fresh, status, (c0, c1, c2), v, drive, cmd_seq)
    cls = _TYPES[typ]
    return cls(seq, *cls.BODY.unpack_from(packet, 5))


@dataclass
class DecoderStats:
    """Counts of a :class:`Decoder`: frames accepted, and frames dropped by reason."""

    frames: int = 0
    bad_cobs: int = 0
    crc: int = 0
    short: int = 0
    bad_length: int = 0
    unknown_type: int = 0
    oversize: int = 0
    repeated: int = 0
    out_of_order: int = 0
    lost: int = 0
    """Frames missing from the sequence (gaps), not dropped ones."""
    by_type: dict[int, int] = field(default_factory=dict)

    @property
    def corrupted(self) -> int:
        """Frames dropped because they were damaged."""
        return self.bad_cobs + self.crc + self.short + self.bad_length + self.unknown_type + self.oversize


class Decoder:
    """Streaming frame decoder: :meth:`feed` bytes as they come, get whole messages back.

    Damaged frames are counted in :attr:`stats` and skipped; a repeated or older ``seq``
    is dropped and counted; a HELLO or HELLO_ACK restarts the sequence tracking.
    """

    def __init__(self, check_seq: bool = True, max_packet: int = MAX_PACKET) -> None:
        self.check_seq = check_seq
        self.max_frame = max_packet + max_packet // 254 + 2
        self.stats = DecoderStats()
        self._buf = b""
        self._last: int | None = None

    def reset(self) -> None:
        """Forget buffered bytes and the sequence state (counts are kept)."""
        self._buf = b""
        self._last = None

    def feed(self, data: bytes) -> list[Message]:
        """Decode every complete frame in ``data`` (plus what was buffered); keep the tail."""
        buf = self._buf + data if self._buf else data
        if b"\x00" not in buf:
            if len(buf) > self.max_frame:
                self.stats.oversize += 1
                buf = b""
            self._buf = bytes(buf)
            return []
        *frames, tail = buf.split(b"\x00")
        if len(tail) > self.max_frame:
            self.stats.oversize += 1
            tail = b""
        self._buf = bytes(tail)
        out: list[Message] = []
        stats = self.stats
        for frame in frames:
            if not frame:
                continue  # idle delimiters
            if len(frame) > self.max_frame:
                stats.oversize += 1
                continue
            packet = cobs_decode(frame)
            if packet is None:
                stats.bad_cobs += 1
                continue
            msg = decode_packet(packet)
            if isinstance(msg, str):
                setattr(stats, msg, getattr(stats, msg) + 1)
                continue
            if self.check_seq and not self._accept_seq(msg):
                continue
            stats.frames += 1
            stats.by_type[msg.TYPE] = stats.by_type.get(msg.TYPE, 0) + 1
            out.append(msg)
        return out

    def _accept_seq(self, msg: Message) -> bool:
        seq = msg.seq
        if msg.TYPE in (T_HELLO, T_HELLO_ACK) or self._last is None:
            self._last = seq
            return True
        diff = (seq - self._last) % SEQ_MOD
        if diff == 0:
            self.stats.repeated += 1
            return False
        if diff >= SEQ_MOD // 2:
            self.stats.out_of_order += 1
            return False
        self.stats.lost += diff - 1
        self._last = seq
        return True
