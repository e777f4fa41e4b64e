"""Reading MCAP files that may be cut off or damaged: skip the damage, keep every intact chunk.

An MCAP file is the magic ``\\x89MCAP0\\r\\n``, records ``opcode (u8) | length (u64) | body``,
and the magic again after the footer. Messages live in *chunk* records whose body carries
``message_start_time, message_end_time, uncompressed_size (u64), uncompressed_crc (u32),
compression (string), records (u64-prefixed bytes)``; the CRC-32 of the uncompressed
records proves a chunk intact.

:class:`Scanner` reads the records in file order and checks each one's structure (every
record's fields must fill its length exactly) and each chunk's CRC. At a record that
fails, it scans forward for the next byte offset where a chunk record parses and its
CRC matches, and goes on from there: the bytes in between are a :class:`LostSpan`. The
messages lost there are counted from the per-channel sequence numbers (consecutive in
``thermoskin`` recordings) and, in a finished file whose summary is intact, from its
statistics. A file that ends without its footer (the writer was killed) is *cut off*,
not damaged: everything before the cut is kept and :attr:`RecordingReport.t_end` says
where it ends.
"""

from __future__ import annotations

import dataclasses
import math
import struct
import zlib
from collections.abc import Iterator
from pathlib import Path
from typing import Any

MAGIC = b"\x89MCAP0\r\n"
OP_FOOTER, OP_SCHEMA, OP_CHANNEL, OP_MESSAGE, OP_CHUNK, OP_DATA_END = 0x02, 0x03, 0x04, 0x05, 0x06, 0x0F

_HEAD = struct.Struct("<BQ")  # opcode, body length
_U16, _U32, _U64 = struct.Struct("<H"), struct.Struct("<I"), struct.Struct("<Q")
_MSG = struct.Struct("<HIQQ")  # channel id, sequence, log_time, publish_time
_CHUNK = struct.Struct("<QQQII")  # start, end, uncompressed size, crc, compression length
_FOOTER_BYTES = 9 + 20 + len(MAGIC)

#: Each record's fields (MCAP spec): H u16, I u32, Q u64, B u8, s u32-prefixed bytes
#: (strings, maps, arrays), b u64-prefixed bytes. A valid body holds exactly these.
_LAYOUT = {0x01: "ss", 0x02: "QQI", 0x03: "Hsss", 0x04: "HHsss", 0x06: "QQQIsb", 0x07: "Hs",
           0x08: "QQQQsQsQQ", 0x09: "QQssbI", 0x0A: "QQQQQss", 0x0B: "QHIIIIQQs", 0x0C: "ss",
           0x0D: "QQs", 0x0E: "BQQ", 0x0F: "I"}
_SIZE = {"B": 1, "H": 2, "I": 4, "Q": 8}
_MAX_INFLATE = 1 << 30  # an uncompressed chunk larger than this is taken as damage
RELEASE_BYTES = 8 << 20
"""A mapped file's pages are let go every this many bytes read (:meth:`Scanner._release`)."""
CHECK_BYTES = 4096
"""A mapped file's length is checked before a record this far (or farther) past the last check
(:meth:`Scanner._check_length`): before every chunk of a ``thermoskin`` recording."""


class RecordingError(ValueError):
    """A recording could not be read or exported (the message names the file and why)."""


class ScanError(RecordingError):
    """The file cannot be read as MCAP at all, or no longer (the message says why)."""


@dataclasses.dataclass
class LostSpan:
    """Bytes ``[start, end)`` of the file could not be read.

    The messages lost there have times from ``t_before`` (the last intact message before,
    s; NaN: none) to ``t_after`` (the first after; NaN: the damage runs to the end), both
    included (a sample time's messages may sit on both sides of a chunk boundary).
    ``lost`` counts them by topic; ``known`` is false when a count could not be
    established (a channel never seen again, sequence numbers not consecutive).
    """

    start: int
    end: int
    t_before: float
    t_after: float
    lost: dict[str, int] = dataclasses.field(default_factory=dict)
    known: bool = True
    in_summary: bool = False  # after the data section's end record: only indexes were lost

    @property
    def messages(self) -> int:
        return sum(self.lost.values())

    def describe(self) -> str:
        """One line: where, which times, what was lost."""
        if self.in_summary:
            return (f"damaged bytes {self.start}-{self.end}: in the summary at the end (indexes "
                    "only): no message lost")
        a = "the start" if math.isnan(self.t_before) else f"t = {self.t_before:.3f} s"
        b = "the end of the recording" if math.isnan(self.t_after) else f"t = {self.t_after:.3f} s"
        what = ", ".join(f"{n} {topic}" for topic, n in sorted(self.lost.items()) if n)
        if not self.known:
            lost = f"lost {what + ' and ' if what else ''}an unknown number of messages"
        else:
            lost = f"lost {self.messages} messages ({what})" if what else "no message lost"
        return f"damaged bytes {self.start}-{self.end}: {lost} between {a} and {b}"


@dataclasses.dataclass
class RecordingReport:
    """What reading a recording found: how it ends, what was damaged and lost."""

    path: Path
    size: int = 0
    finished: bool = False  # the writer closed it (closing magic, or the data section's end)
    footer: bool = False  # the footer was read in order after intact data
    spans: list[LostSpan] = dataclasses.field(default_factory=list)
    messages: int = 0  # messages read (every topic)
    t_start: float = math.nan  # first and last message time read, s
    t_end: float = math.nan
    tail: int = 0  # bytes at the end of a cut-off file that are not a whole record
    orphans: int = 0  # messages on a channel whose definition was lost
    error: str = ""  # the first problem met

    @property
    def complete(self) -> bool:
        """Finished by its writer and read to its footer without damage."""
        return self.finished and self.footer and not self.spans and not self.orphans

    @property
    def cut_off(self) -> bool:
        """Ends without a footer: the writer did not finish (killed, power lost)."""
        return not self.finished

    @property
    def damaged(self) -> bool:
        """Some bytes could not be read (each such part is in :attr:`spans`)."""
        return bool(self.spans) or self.orphans > 0

    @property
    def data_lost(self) -> bool:
        """Damage cost messages, or may have (a count could not be established)."""
        return self.orphans > 0 or any(s.messages or not s.known for s in self.spans)

    @property
    def lost_messages(self) -> int:
        return sum(s.messages for s in self.spans) + self.orphans

    def lines(self) -> list[str]:
        """One line per lost span, one for orphaned messages, one for a cut-off end."""
        out = [s.describe() for s in self.spans]
        if self.orphans:
            out.append(f"{self.orphans} messages unreadable: their channel was defined in a damaged part")
        if self.cut_off:
            end = "no message" if math.isnan(self.t_end) else f"t = {self.t_end:.3f} s"
            torn = f"; its last {self.tail} bytes are an unfinished record" if self.tail else ""
            out.append(f"cut off (the recorder did not finish: killed?): it ends at {end}{torn}")
        return out


def _fields(b: bytes, p: int, e: int, layout: str) -> int:
    """Offset after the fields of ``layout`` from ``p``, or -1 if they do not fit in ``e``."""
    for f in layout:
        if f == "s":
            if p + 4 > e:
                return -1
            p += 4 + _U32.unpack_from(b, p)[0]
        elif f == "b":
            if p + 8 > e:
                return -1
            p += 8 + _U64.unpack_from(b, p)[0]
        else:
            p += _SIZE[f]
        if p > e:
            return -1
    return p


def _string(b: bytes, p: int) -> tuple[str, int]:
    n = _U32.unpack_from(b, p)[0]
    return b[p + 4: p + 4 + n].decode("utf-8", "replace"), p + 4 + n


def _inflate(compression: str, data: bytes, size: int) -> bytes:
    """The chunk's records; a frame declaring another size than the chunk's is damage
    (checked first: a damaged header must not make us allocate what it claims)."""
    if compression == "":
        return data
    if compression == "zstd":
        import zstandard

        if zstandard.frame_content_size(data) not in (size, -1):
            raise ValueError("zstd frame size differs from the chunk's")
        return zstandard.ZstdDecompressor().decompress(data, max_output_size=size)
    if compression == "lz4":
        import lz4.frame

        if lz4.frame.get_frame_info(data)["content_size"] not in (size, 0):
            raise ValueError("lz4 frame size differs from the chunk's")
        return lz4.frame.decompress(data)
    raise ValueError(f"unknown compression {compression!r}")


class Scanner:
    """Messages of an MCAP file in file order, past cut-offs and damage (see the module doc).

    :meth:`messages` yields ``(topic, sequence, log_time_ns, payload)`` (with
    ``publish_time=True``, ``publish_time_ns`` last); :attr:`report` is complete once it
    is exhausted.
    """

    def __init__(self, path: str | Path, data: bytes, publish_time: bool = False) -> None:
        """``data``: the file's bytes, or the file mapped (``mmap``)."""
        self.b = data
        self._madvise = getattr(data, "madvise", None)  # a mapped file: pages read are let go
        self._released = 0
        self._length = getattr(data, "size", None)  # a mapped file: its length now (fstat)
        self._checked = -CHECK_BYTES
        self.publish_time = publish_time  # messages carry their publish time last
        self.n = len(data)
        self.report = RecordingReport(Path(path), size=self.n)
        self.topics: dict[int, str] = {}  # channel id -> topic
        self.schemas: dict[int, tuple[str, str, bytes]] = {}  # schema id -> name, encoding, data
        self.channel_info: dict[int, tuple[str, int, str]] = {}  # channel -> topic, schema id, encoding
        self._last_seq: dict[int, int] = {}  # channel -> last sequence number read
        self._read: dict[int, int] = {}  # channel -> messages read
        self._gap: dict[int, int] = {}  # channel -> messages counted lost from sequence gaps
        self._open: list[tuple[LostSpan, set[int], set[int]]] = []  # span, channels not seen
        # since, channels of the chunk before it
        self._need_after: list[LostSpan] = []  # spans waiting for their first message after
        self._recent: set[int] = set()  # channels of the last chunk read
        self._data_end = False  # the data section's end record was read: the summary follows
        if data[:8] != MAGIC:
            if MAGIC.startswith(data[:8]):
                raise ScanError(f"{path}: cut off before its first record ({self.n} bytes): "
                                "nothing was recorded")
            raise ScanError(f"{path} is not an MCAP file (bad magic)")
        self.report.finished = self.n >= 8 + _FOOTER_BYTES and data[-8:] == MAGIC
        self.expected: dict[int, int] | None = None
        if self.report.finished:
            self._read_summary()

    # --------------------------------------------------------------- records

    def _register(self, b: bytes, op: int, r: int) -> None:
        """Keep a (structurally valid) schema or channel record starting at body offset ``r``."""
        if op == OP_SCHEMA:
            sid = _U16.unpack_from(b, r)[0]
            name, q = _string(b, r + 2)
            enc, q = _string(b, q)
            n = _U32.unpack_from(b, q)[0]
            self.schemas[sid] = (name, enc, bytes(b[q + 4: q + 4 + n]))
        elif op == OP_CHANNEL:
            ch, sid = _U16.unpack_from(b, r)[0], _U16.unpack_from(b, r + 2)[0]
            topic, q = _string(b, r + 4)
            self.topics[ch] = topic
            self.channel_info[ch] = (topic, sid, _string(b, q)[0])

    def _record(self, o: int) -> tuple[int, int, int] | None:
        """``(opcode, body start, body end)`` of a structurally valid record at ``o``."""
        if o + 9 > self.n:
            return None
        op, length = _HEAD.unpack_from(self.b, o)
        s, e = o + 9, o + 9 + length
        if e > self.n:
            return None
        if op == OP_MESSAGE:
            return (op, s, e) if length >= _MSG.size else None
        layout = _LAYOUT.get(op)
        if layout is None or _fields(self.b, s, e, layout) != e:
            return None
        return op, s, e

    def _chunk(self, s: int, e: int) -> list[tuple[int, int, int, bytes, int]] | None:
        """The messages of the chunk body ``[s, e)`` if it inflates, its CRC matches and
        its records parse; the channels it defines are registered."""
        b = self.b
        _, _, usize, crc, clen = _CHUNK.unpack_from(b, s)
        p = s + _CHUNK.size
        comp = b[p: p + clen].decode("ascii", "replace")
        p += clen
        rlen = _U64.unpack_from(b, p)[0]
        p += 8
        if usize > _MAX_INFLATE:
            return None
        try:
            raw = _inflate(comp, b[p: p + rlen], usize)
        except Exception:  # any codec error is damage
            return None
        if len(raw) != usize or (crc and zlib.crc32(raw) != crc):
            return None
        msgs: list[tuple[int, int, int, bytes, int]] = []
        records: list[tuple[int, int]] = []  # schemas and channels, kept once the chunk is whole
        q, n = 0, len(raw)
        while q < n:
            if q + 9 > n:
                return None
            op, length = _HEAD.unpack_from(raw, q)
            r, end = q + 9, q + 9 + length
            if end > n:
                return None
            if op == OP_MESSAGE:
                if length < _MSG.size:
                    return None
                ch, seq, t, pub = _MSG.unpack_from(raw, r)
                msgs.append((ch, seq, t, raw[r + _MSG.size: end], pub))
            elif op in (OP_CHANNEL, OP_SCHEMA):
                if _fields(raw, r, end, _LAYOUT[op]) != end:
                    return None
                records.append((op, r))
            q = end
        for op, r in records:
            self._register(raw, op, r)
        return msgs

    def _check_length(self, o: int) -> None:
        """Stop with an error if the mapped file was cut short in place since it was opened
        (another program writing over it: ``cp`` onto it, a writer that truncates): the next
        read of a page past its new end would end the process (SIGBUS). Checked before each
        record :data:`CHECK_BYTES` past the last check (an ``fstat``); the check and the read
        after it are microseconds apart, the reader's work on a batch is not."""
        self._checked = o
        if self._length is not None and (now := self._length()) < self.n:
            raise ScanError(f"{self.report.path}: cut short to {now} bytes while it was read (at byte "
                            f"{o} of {self.n}): another program wrote over it; read it again once "
                            "that program is done")

    def _resync(self, o: int) -> tuple[int, list[tuple[int, int, int, bytes, int]]] | None:
        """The next offset after ``o`` holding an intact chunk, and its messages."""
        self._check_length(o)
        find, p = self.b.find, o
        while True:
            p = find(b"\x06", p + 1)
            if p < 0:
                return None
            rec = self._record(p)
            if rec is None or rec[0] != OP_CHUNK:
                continue
            msgs = self._chunk(rec[1], rec[2])
            if msgs is not None:
                return p, msgs

    def _read_summary(self) -> None:
        """Channels and per-channel message counts from the summary of a finished file."""
        b, fo = self.b, self.n - _FOOTER_BYTES
        rec = self._record(fo)
        if rec is None or rec[0] != OP_FOOTER:
            return
        start = _U64.unpack_from(b, rec[1])[0]
        if not 8 <= start <= fo:
            return
        topics: dict[int, str] = {}
        recs: list[tuple[int, int]] = []
        counts: dict[int, int] | None = None
        o = start
        while o < fo:
            rec = self._record(o)
            if rec is None:
                return
            op, s, e = rec
            if op == OP_CHANNEL:
                topics[_U16.unpack_from(b, s)[0]] = _string(b, s + 4)[0]
                recs.append((op, s))
            elif op == OP_SCHEMA:
                recs.append((op, s))
            elif op == 0x0B:  # statistics: channel_message_counts map<u16, u64>
                p = s + 8 + 2 + 4 * 4 + 8 + 8
                m = _U32.unpack_from(b, p)[0]
                if m % 10:
                    return
                counts = {}
                for i in range(p + 4, p + 4 + m, 10):
                    counts[_U16.unpack_from(b, i)[0]] = _U64.unpack_from(b, i + 2)[0]
            o = e
        for op, r in recs:
            self._register(b, op, r)
        self.topics.update(topics)
        self.expected = counts

    # --------------------------------------------------------------- messages

    def _lost(self, o: int, end: int) -> None:
        """Open a lost span over bytes ``[o, end)``."""
        span = LostSpan(o, end, self.report.t_end, math.nan, in_summary=self._data_end)
        self.report.spans.append(span)
        if not self.report.error:
            self.report.error = f"damaged record at byte {o}"
        if span.in_summary:
            return
        self._open.append((span, set(self._last_seq), self._recent))
        self._need_after.append(span)

    def _emit(self, msgs: list[tuple[int, int, int, bytes, int]]) -> list[tuple[Any, ...]]:
        rep, topics, out = self.report, self.topics, []
        pub_too = self.publish_time
        for ch, seq, t, payload, pub in msgs:
            topic = topics.get(ch)
            if topic is None:
                rep.orphans += 1
                continue
            if self._need_after:
                for span in self._need_after:
                    span.t_after = t * 1e-9
                self._need_after = []
            if self._open:
                self._account(ch, seq, topic)
            self._last_seq[ch] = seq
            self._read[ch] = self._read.get(ch, 0) + 1
            out.append((topic, seq, t, payload, pub) if pub_too else (topic, seq, t, payload))
        if out:
            self._recent = {m[0] for m in msgs}
            if rep.messages == 0:
                rep.t_start = out[0][2] * 1e-9
            rep.t_end = out[-1][2] * 1e-9
            rep.messages += len(out)
        return out

    def _account(self, ch: int, seq: int, topic: str) -> None:
        """The first message of ``ch`` after a span: its sequence gap is what the span lost."""
        for span, chans, _ in self._open:
            if ch in chans:
                last = self._last_seq[ch]
                gap = seq - last - 1
                if gap < 0 or seq == last == 0:  # no consecutive sequence numbers: cannot count
                    span.known = False
                elif gap:
                    span.lost[topic] = span.lost.get(topic, 0) + gap
                    self._gap[ch] = self._gap.get(ch, 0) + gap
                break
        else:
            return
        for _, chans, _ in self._open:
            chans.discard(ch)
        self._open = [x for x in self._open if x[1]]

    def messages(self) -> Iterator[tuple[Any, ...]]:
        """``(topic, sequence, log_time_ns, payload)`` of every intact message, in file order
        (``publish_time_ns`` last if the scanner was made with ``publish_time=True``)."""
        for batch in self.batches():
            yield from batch

    def batches(self) -> Iterator[list[tuple[Any, ...]]]:
        """The messages of :meth:`messages`, one list per chunk (or top-level message)."""
        rep, o, n = self.report, 8, self.n
        while o < n:
            if self._length is not None and o - self._checked >= CHECK_BYTES:
                self._check_length(o)
            rec = self._record(o)
            msgs: list[tuple[int, int, int, bytes, int]] | None = None
            if rec is not None:
                op, s, e = rec
                if op == OP_CHUNK:
                    msgs = self._chunk(s, e)
                    if msgs is None:
                        rec = None
                elif op == OP_MESSAGE:
                    ch, seq, t, pub = _MSG.unpack_from(self.b, s)
                    msgs = [(ch, seq, t, self.b[s + _MSG.size: e], pub)]
                elif op in (OP_CHANNEL, OP_SCHEMA):
                    self._register(self.b, op, s)
                elif op == OP_DATA_END:  # the data is complete; the summary follows
                    self._data_end = rep.finished = True
                elif op == OP_FOOTER:
                    rep.footer = e + 8 == n and self.b[e:] == MAGIC
                    if not rep.footer:
                        rec = None
                    else:
                        break
            if rec is None:  # damage or a cut-off end: go on at the next intact chunk
                found = self._resync(o)
                if found is None:
                    if rep.finished:
                        self._lost(o, n)
                    else:
                        rep.tail = n - o
                        if not rep.error:
                            rep.error = f"unfinished record at byte {o} (cut off)"
                    break
                p, msgs = found
                self._lost(o, p)
                e = p + 9 + _U64.unpack_from(self.b, p + 1)[0]
            if msgs:
                yield self._emit(msgs)
            o = e
            if self._madvise is not None and o - self._released >= RELEASE_BYTES:
                self._release(o)
        self._close_spans()

    def _release(self, o: int) -> None:
        """Let the kernel drop the mapped file's pages before byte ``o`` (read already): the
        scanner's memory does not grow with the file (they are read again if asked for)."""
        import mmap

        end = o - o % mmap.PAGESIZE
        if end > self._released:
            self._madvise(mmap.MADV_DONTNEED, self._released, end - self._released)  # type: ignore[misc]
            self._released = end

    def _close_spans(self) -> None:
        """What sequence gaps could not show: from the summary's counts, else unknown."""
        spans = self.report.spans
        if not spans:
            return
        if self.expected is None:  # channels busy just before a span and not seen since: unknown
            for span, chans, active in self._open:
                if chans & active:
                    span.known = False
            for span in spans:
                if math.isnan(span.t_after) and not span.in_summary:  # nothing after it to compare
                    span.known = False
            return
        where = {ch: span for span, chans, _ in reversed(self._open) for ch in chans}  # the earliest
        for ch, count in self.expected.items():
            left = count - self._read.get(ch, 0) - self._gap.get(ch, 0)
            if left > 0:
                span = where.get(ch, spans[0])
                topic = self.topics.get(ch, f"channel {ch}")
                span.lost[topic] = span.lost.get(topic, 0) + left
            elif left < 0:  # more read than the summary counted: its counts are not to be trusted
                for span in spans:
                    span.known = span.in_summary
