"""The link protocol's byte work on the device: CRC-16, COBS, fixed-point views of f32 fields.

docs/protocol.md (version 1): a frame is ``COBS(type u8 | seq u32 | body | crc u16) 0x00``,
little-endian, CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF, not reflected, no final xor)
over ``type | seq | body``. Every function works in place on preallocated buffers and
returns small integers, so the 1 kHz path allocates nothing. On MicroPython they compile to
machine code (``@micropython.viper``: the byte loops are a few instructions a byte); under
CPython (the host's tests) they are plain Python with the same results: every value that
could exceed its field is masked explicitly, as viper's machine words would wrap it.
"""

import sys

import micropython

if sys.implementation.name != "micropython":  # viper's casts, for CPython (no-ops there)
    def ptr8(x):
        return x

    def ptr16(x):
        return x

CRC_TABLE = None
"""The 256 entries of the CRC-16/CCITT-FALSE table (``array('H')``), built by :func:`crc_table`."""


def crc_table():
    """The CRC's table: entry ``i`` is the CRC register after shifting byte ``i`` through it."""
    from array import array

    tab = array("H", bytes(512))
    for i in range(256):
        c = i << 8
        for _ in range(8):
            c = ((c << 1) ^ 0x1021) if c & 0x8000 else (c << 1)
        tab[i] = c & 0xFFFF
    return tab


@micropython.viper
def crc16(buf: ptr8, start: int, n: int, tab: ptr16) -> int:
    """CRC-16/CCITT-FALSE of ``buf[start:start + n]`` (``crc16(b"123456789") == 0x29B1``):
    one table look-up, two shifts and two xors a byte."""
    crc = 0xFFFF
    i = start
    end = start + n
    while i < end:
        crc = ((crc << 8) & 0xFFFF) ^ int(tab[((crc >> 8) ^ int(buf[i])) & 0xFF])
        i += 1
    return crc


@micropython.viper
def cobs_encode(src: ptr8, n: int, dst: ptr8) -> int:
    """COBS of ``src[:n]`` into ``dst`` (at least ``n + n // 254 + 1`` bytes, no delimiter);
    its length. Each run of up to 254 non-zero bytes gets a code byte ``len + 1`` in front."""
    code_i = 0
    out = 1
    code = 1
    i = 0
    while i < n:
        b = int(src[i])
        if b == 0:
            dst[code_i] = code
            code_i = out
            out += 1
            code = 1
        else:
            dst[out] = b
            out += 1
            code += 1
            if code == 0xFF:
                dst[code_i] = code
                code_i = out
                out += 1
                code = 1
        i += 1
    dst[code_i] = code
    return out


@micropython.viper
def cobs_decode(src: ptr8, start: int, n: int, dst: ptr8, cap: int) -> int:
    """Inverse of :func:`cobs_encode` for ``src[start:start + n]`` into ``dst`` (``cap``
    bytes); the decoded length, or -1 for an invalid encoding (a zero byte, a code past the
    end, a result longer than ``cap``)."""
    i = start
    end = start + n
    out = 0
    while i < end:
        code = int(src[i])
        if code == 0:
            return -1
        j = i + code
        if j > end:
            return -1
        i += 1
        while i < j:
            if out >= cap:
                return -1
            dst[out] = src[i]
            out += 1
            i += 1
        if code != 0xFF and i < end:
            if out >= cap:
                return -1
            dst[out] = 0
            out += 1
    return out


@micropython.viper
def find_zero(buf: ptr8, start: int, end: int) -> int:
    """Index of the first 0x00 in ``buf[start:end]`` (a frame's delimiter), or -1."""
    i = start
    while i < end:
        if int(buf[i]) == 0:
            return i
        i += 1
    return -1


@micropython.viper
def move(buf: ptr8, src: int, dst: int, n: int):
    """``buf[dst:dst + n] = buf[src:src + n]`` for ``dst <= src`` (the receive buffer's
    unread tail to its front), without a slice."""
    i = 0
    while i < n:
        buf[dst + i] = buf[src + i]
        i += 1


@micropython.viper
def copy(src: ptr8, s: int, dst: ptr8, d: int, n: int):
    """``dst[d:d + n] = src[s:s + n]`` without a slice."""
    i = 0
    while i < n:
        dst[d + i] = src[s + i]
        i += 1


@micropython.viper
def add_le(buf: ptr8, off: int, width: int, inc: int):
    """Add ``inc`` (0 to 65535) to the little-endian unsigned field of ``width`` bytes at
    ``off``, wrapping at its width (the SAMPLE's ``t_us`` u64, a ``seq`` u32)."""
    carry = inc
    i = 0
    while i < width and carry != 0:
        s = int(buf[off + i]) + (carry & 0xFF)
        buf[off + i] = s & 0xFF
        carry = (carry >> 8) + (s >> 8)
        i += 1


@micropython.viper
def seq_newer(a: ptr8, ao: int, b: ptr8, bo: int) -> int:
    """Serial-number order of the u32 fields ``a[ao:]`` and ``b[bo:]``: 1 if ``a`` is newer
    (``(a - b) mod 2^32`` in 1 .. 2^31 - 1), 0 if equal, -1 if older."""
    borrow = 0
    nz = 0
    top = 0
    i = 0
    while i < 4:
        d = int(a[ao + i]) - int(b[bo + i]) - borrow
        borrow = 1 if d < 0 else 0
        d &= 0xFF
        nz |= d
        top = d
        i += 1
    if nz == 0:
        return 0
    return 1 if top < 0x80 else -1


@micropython.viper
def f32_fixed(buf: ptr8, off: int, frac: int) -> int:
    """``|x| * 2^frac`` of the little-endian binary32 ``x`` at ``off``, truncated, clamped to
    ``2^24`` (``frac`` <= 16); NaN and infinities give 0 (a NaN command is no command: off).
    Its sign is ``buf[off + 3] & 0x80``. Integer work only (no float object is made)."""
    b3 = int(buf[off + 3])
    b2 = int(buf[off + 2])
    e = ((b3 & 0x7F) << 1) | (b2 >> 7)
    if e == 0xFF or e == 0:
        return 0  # NaN, infinity; zero and denormals
    m = ((b2 & 0x7F) << 16) | (int(buf[off + 1]) << 8) | int(buf[off]) | 0x800000
    # x = m 2^(e - 150): |x| 2^frac = m 2^(e - 150 + frac)
    s = e - 150 + frac
    if s >= 1:
        return 1 << 24
    if s <= -24:
        return 0
    return m >> (0 - s)


@micropython.viper
def q7_to_f32(raw: int, buf: ptr8, off: int):
    """Write ``raw / 128`` (a signed 19-bit MAX31856 reading, 1/128 K a count) at ``off`` as
    a little-endian binary32, exactly (``|raw| < 2^23``), with integer work only."""
    if raw == 0:
        buf[off] = 0
        buf[off + 1] = 0
        buf[off + 2] = 0
        buf[off + 3] = 0
        return
    sign = 0
    if raw < 0:
        sign = 0x80
        raw = 0 - raw
    p = 0
    while (raw >> (p + 1)) != 0:
        p += 1
    e = 127 + p - 7
    mant = (raw << (23 - p)) & 0x7FFFFF
    buf[off] = mant & 0xFF
    buf[off + 1] = (mant >> 8) & 0xFF
    buf[off + 2] = ((e & 1) << 7) | ((mant >> 16) & 0x7F)
    buf[off + 3] = sign | (e >> 1)


@micropython.viper
def put_nan(buf: ptr8, off: int):
    """Write a quiet NaN (no valid reading) as a little-endian binary32 at ``off``."""
    buf[off] = 0
    buf[off + 1] = 0
    buf[off + 2] = 0xC0
    buf[off + 3] = 0x7F


@micropython.viper
def put_u16(buf: ptr8, off: int, x: int):
    """Write ``x`` (0 .. 65535) little-endian at ``off``."""
    buf[off] = x & 0xFF
    buf[off + 1] = (x >> 8) & 0xFF


@micropython.viper
def scale_duty(q: int, full: int) -> int:
    """A PWM duty (0 .. 65535) for ``q / full`` in 16384 steps (``0 <= q``, ``full < 2^17``;
    ``q >= full``: 65535)."""
    if q >= full or full <= 0:
        return 65535
    return (q * 16384 // full) * 65535 // 16384
