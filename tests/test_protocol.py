"""The link protocol: framing, CRC, decoding of damaged, repeated and reordered frames."""

from __future__ import annotations

import math
import random
import struct

import pytest

from thermoskin.devices import protocol as proto
from thermoskin.devices.protocol import (
    Command,
    Decoder,
    Fault,
    Hello,
    HelloAck,
    Safe,
    SampleMsg,
    cobs_decode,
    cobs_encode,
    crc16,
    encode,
)


def sample(seq: int, **kw: object) -> SampleMsg:
    base = dict(t_us=seq * 1000, T_w=24.25, T_p=24.5, T_a=20.0, fresh=proto.CH_W, status=proto.ST_SAFE,
                counters=(seq & 0xFFFF, 2, 65535), v=0.140625, drive=-0.5, cmd_seq=seq - 1)
    base.update(kw)
    return SampleMsg(seq, **base)  # type: ignore[arg-type]


MESSAGES = [
    Hello(0, proto.PROTOCOL_VERSION, 1000),
    HelloAck(1, proto.PROTOCOL_VERSION, proto.STATUS_OK, 0xDEADBEEF, 1000, 100_000),
    sample(2),
    Command(3, 0.25, 0.140625),
    Safe(4, 7),
    Fault(5, proto.F_TC_OPEN, 0, 1.5),
]


def test_crc16_ccitt_false_check_value() -> None:
    assert crc16(b"123456789") == 0x29B1


@pytest.mark.parametrize("n", [0, 1, 2, 253, 254, 255, 507, 508, 600])
def test_cobs_round_trip(n: int) -> None:
    rng = random.Random(n)
    for zeros in (0.0, 0.1, 1.0):
        data = bytes(0 if rng.random() < zeros else rng.randrange(1, 256) for _ in range(n))
        enc = cobs_encode(data)
        assert b"\x00" not in enc
        assert cobs_decode(enc) == data
        assert len(enc) <= n + n // 254 + 1


def test_cobs_keeps_the_zero_after_a_run_of_254() -> None:
    """A run of exactly 254 non-zero bytes is one block of code 0xFF ("254 bytes, no zero
    follows"): a zero right after it is a block of its own. The encodings written out by hand
    from the COBS rule (issue 46: a mutant that let the run reach 255 before splitting lost that
    zero, and every test passed)."""
    run = bytes(range(1, 255))  # 254 non-zero bytes
    assert cobs_encode(run + b"\x00" + b"\x07") == b"\xff" + run + b"\x01" + b"\x02\x07"
    assert cobs_encode(run + b"\x00") == b"\xff" + run + b"\x01\x01"
    assert cobs_encode(run) == b"\xff" + run + b"\x01"
    assert cobs_encode(run + b"\x09") == b"\xff" + run + b"\x02\x09"
    for data in (run + b"\x00", run + b"\x00\x07", b"\x00" + run + b"\x00" + run, run + run + b"\x00"):
        assert cobs_decode(cobs_encode(data)) == data
    assert len(cobs_decode(cobs_encode(run + b"\x00"))) == 255


def test_cobs_decode_rejects_bad_codes() -> None:
    assert cobs_decode(b"\x05\x01\x02") is None  # code points past the end
    assert cobs_decode(b"\x02\x00") is None  # zero inside a frame


@pytest.mark.parametrize("msg", MESSAGES, ids=lambda m: type(m).__name__)
def test_round_trip(msg: proto.Message) -> None:
    frame = encode(msg)
    assert frame.endswith(b"\x00") and b"\x00" not in frame[:-1]
    dec = Decoder(check_seq=False)
    assert dec.feed(frame) == [msg]
    assert dec.stats.frames == 1 and dec.stats.corrupted == 0


def test_nan_and_float32_pass_through() -> None:
    m = sample(1, T_w=math.nan, T_p=math.inf)
    (out,) = Decoder().feed(encode(m))
    assert math.isnan(out.T_w) and out.T_p == math.inf  # type: ignore[union-attr]


def test_stream_fed_byte_by_byte_and_in_chunks() -> None:
    stream = b"".join(encode(sample(i)) for i in range(1, 51))
    dec = Decoder()
    got = []
    for b in stream:
        got += dec.feed(bytes([b]))
    assert [m.seq for m in got] == list(range(1, 51))
    dec2 = Decoder()
    rng = random.Random(1)
    got2 = []
    i = 0
    while i < len(stream):
        n = rng.randrange(1, 200)
        got2 += dec2.feed(stream[i:i + n])
        i += n
    assert got2 == got


def test_every_single_bit_flip_is_caught() -> None:
    frame = encode(sample(7))
    good = encode(sample(8))
    for i in range(len(frame) - 1):  # the delimiter is not flipped
        for bit in range(8):
            bad = bytearray(frame)
            bad[i] ^= 1 << bit
            dec = Decoder()
            out = dec.feed(bytes(bad) + good)
            assert all(m.seq != 7 or m == sample(7) for m in out), (i, bit)
            assert out[-1] == sample(8)
            if sample(7) not in out:
                assert dec.stats.corrupted >= 1


def test_damaged_frames_counted_and_skipped() -> None:
    good = [encode(sample(i)) for i in range(1, 6)]
    truncated = good[1][:20] + b"\x00"
    packet = bytes(struct.pack("<BI", proto.T_COMMAND, 9)) + b"\x01\x02\x03"  # 3-byte body
    wrong_len = cobs_encode(packet + struct.pack("<H", crc16(packet))) + b"\x00"
    packet = bytes(struct.pack("<BI", 0x77, 9)) + b"abcd"
    unknown = cobs_encode(packet + struct.pack("<H", crc16(packet))) + b"\x00"
    short = cobs_encode(b"\x10\x01") + b"\x00"
    bad_cobs = b"\x09\x01\x02\x00"
    stream = (b"\x00\x00" + good[0] + truncated + wrong_len + good[2] + unknown + short + bad_cobs
              + b"\xff" * 5000 + b"\x00" + good[3] + good[4])
    dec = Decoder()
    out = dec.feed(stream)
    assert [m.seq for m in out] == [1, 3, 4, 5]
    s = dec.stats
    assert s.bad_length == 1 and s.unknown_type == 1 and s.short == 1 and s.oversize == 1
    assert s.bad_cobs + s.crc == 2  # the bad code, and the truncated frame (caught by COBS or CRC)
    assert s.corrupted == 6
    assert s.lost == 1  # seq 2 never arrived intact


def test_oversize_without_delimiter_is_dropped() -> None:
    dec = Decoder()
    assert dec.feed(b"\x01" * 10_000) == []
    assert dec.stats.oversize == 1
    assert dec.feed(encode(sample(1))) == [sample(1)]


def test_repeated_and_reordered_sequence_numbers() -> None:
    frames = {i: encode(sample(i)) for i in range(1, 10)}
    order = [1, 2, 2, 3, 5, 4, 6, 6, 9, 7, 8]
    dec = Decoder()
    out = dec.feed(b"".join(frames[i] for i in order))
    assert [m.seq for m in out] == [1, 2, 3, 5, 6, 9]
    assert dec.stats.repeated == 2
    assert dec.stats.out_of_order == 3  # 4, 7, 8 came after a later frame
    assert dec.stats.lost == 1 + 2  # 4 after 3 -> 5, then 7, 8 after 6 -> 9


def test_sequence_wraps_and_hello_restarts() -> None:
    dec = Decoder()
    seqs = [proto.SEQ_MOD - 2, proto.SEQ_MOD - 1, 0, 1]
    out = dec.feed(b"".join(encode(sample(s, counters=(0, 0, 0))) for s in seqs))
    assert [m.seq for m in out] == seqs and dec.stats.lost == 0
    out = dec.feed(encode(HelloAck(0)) + encode(sample(1, counters=(0, 0, 0))))
    assert [m.TYPE for m in out] == [proto.T_HELLO_ACK, proto.T_SAMPLE]


def test_oversize_frames_at_the_limit() -> None:
    """The longest frame a packet of MAX_PACKET bytes makes (250 + 250 // 254 + 2 = 252 bytes) is
    decoded (as garbage here: a bad code or CRC), one byte more is oversize; a buffer that passes
    the limit without a delimiter is dropped and counted, and the next whole frame decodes; every
    drop counted once."""
    limit = proto.MAX_PACKET + proto.MAX_PACKET // 254 + 2
    assert limit == 252
    dec = Decoder(check_seq=False)
    dec.feed(b"\x07" * limit + b"\x00")
    assert dec.stats.oversize == 0 and dec.stats.bad_cobs + dec.stats.crc + dec.stats.bad_length == 1
    dec.feed(b"\x07" * (limit + 1) + b"\x00")
    assert dec.stats.oversize == 1
    dec.feed(b"\x07" * limit)  # no delimiter yet, at the limit: kept
    assert dec.stats.oversize == 1
    dec.feed(b"\x07")  # past it: dropped
    assert dec.stats.oversize == 2
    good = sample(9)
    assert dec.feed(b"\x00" + encode(good)) == [good]  # nothing of the dropped bytes before it
    dec.feed(b"\x05" * 300)  # past the limit with no delimiter at all
    assert dec.stats.oversize == 3
    assert dec.feed(b"\x00" + encode(sample(10))) == [sample(10)]
    assert dec.feed(encode(sample(11)) + b"\x06" * 300) == [sample(11)]  # a long tail after a frame
    assert dec.stats.oversize == 4
    assert dec.feed(b"\x00" + encode(sample(12))) == [sample(12)]  # the tail's bytes are gone
    dec.feed(b"\x07" * (limit + 1) + b"\x00" + b"\x07" * (limit + 5) + b"\x00")  # two oversize frames
    assert dec.stats.oversize == 6


def test_a_packet_of_seven_bytes_is_long_enough_to_be_checked() -> None:
    """7 bytes (type, seq, CRC; no body) pass the length check and fail on their body's length;
    6 are short."""
    packet = bytes([proto.T_SAFE]) + (5).to_bytes(4, "little")
    seven = packet + crc16(packet).to_bytes(2, "little")
    assert proto.decode_packet(seven) == "bad_length"
    assert proto.decode_packet(seven[:6]) == "short"


def test_sequence_half_way_round_is_old() -> None:
    """A seq 2**31 ahead (half the counter's circle) is taken as older (dropped, out of order);
    2**31 - 1 ahead is new (2**31 - 2 frames lost)."""
    dec = Decoder()
    assert dec.feed(encode(sample(1))) == [sample(1)]
    assert dec.feed(encode(sample(1 + 2**31))) == [] and dec.stats.out_of_order == 1
    got = dec.feed(encode(sample(2**31)))
    assert got == [sample(2**31)] and dec.stats.lost == 2**31 - 2


def test_frames_counted_by_type() -> None:
    dec = Decoder(check_seq=False)
    dec.feed(encode(Hello(1)) + encode(sample(2)) + encode(sample(3)) + encode(sample(4)))
    assert dec.stats.by_type == {proto.T_HELLO: 1, proto.T_SAMPLE: 3} and dec.stats.frames == 4


def test_frame_limit_past_one_cobs_block_and_a_tail_at_the_limit() -> None:
    """A decoder for packets of 254 bytes (one whole COBS block, one code byte more): its frames
    reach 254 + 1 + 2 = 257 bytes, decoded (as garbage here), 258 are oversize. A tail after a
    frame exactly at the limit is kept (not counted); the bytes of a tail dropped past it are gone
    (the next frame, fed at once, decodes)."""
    dec = Decoder(check_seq=False, max_packet=254)
    dec.feed(b"\x07" * 257 + b"\x00")
    assert dec.stats.oversize == 0 and dec.stats.bad_cobs + dec.stats.crc + dec.stats.bad_length == 1
    dec.feed(b"\x07" * 258 + b"\x00")
    assert dec.stats.oversize == 1
    dec = Decoder()
    assert dec.feed(encode(sample(1)) + b"\x07" * 252) == [sample(1)]
    assert dec.stats.oversize == 0
    assert dec.feed(b"\x00") == [] and dec.stats.oversize == 0 and dec.stats.corrupted == 1
    assert dec.feed(encode(sample(2)) + b"\x07" * 253) == [sample(2)] and dec.stats.oversize == 1
    assert dec.feed(encode(sample(3))) == [sample(3)]


def test_reset_forgets_the_buffer_and_the_sequence_not_the_counts() -> None:
    """``reset``: half a frame buffered is forgotten (the next whole frame decodes on its own),
    a seq already seen is new again; the counts stay."""
    dec = Decoder()
    assert dec.feed(encode(sample(5))) == [sample(5)]
    dec.feed(encode(sample(6))[:10])
    dec.reset()
    assert dec.feed(encode(sample(5))) == [sample(5)]  # not glued to the half, not a repeat
    assert dec.stats.frames == 2 and dec.stats.repeated == 0 and dec.stats.corrupted == 0
    dec.feed(encode(sample(6))[:10])
    dec.reset()
    assert dec.feed(encode(sample(7))[10:]) == [] and dec.stats.corrupted == 1 and dec.stats.frames == 2
