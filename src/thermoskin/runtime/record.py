"""Recording to MCAP (JSON-schema channels, viewable in Foxglove), reading back, export, replay.

Topics (messages are JSON objects; signal names and units of ``docs/model.md``)::

    /skin/sample    {t, T_w, T_p, T_a, v, drive, fresh, stale, stuck, status, seq}
    /skin/estimate  {t, q_i_hat, dq_i_hat, contact, gap}
    /control        {t, T_w_cmd, T_p_cmd, drive, v_cmd}
    /sim/truth      {t, q_i, T_g, T_w_true, T_p_true, contact_true, n_fingers}   simulator only
    /loop/timing    {t, late, lag, busy}     the fixed-rate loop's lateness, host lag, step time, s
    /events         {t, kind, detail}        contact onsets/releases, faults, link loss, run end
    /params         {t, config}              the run's configuration, once at the start

Any other topic is accepted with a permissive schema. A message's ``log_time`` and
``publish_time`` are ``t`` in ns (the loop's clock; the wall-clock start of the recording
is in the ``thermoskin`` metadata record). NaN is written as JSON ``null`` (JSON has no
NaN) and read back as NaN.

Crash safety: the writer appends whole chunks (one ``os.write`` each) at least every
``flush_interval`` s (default 0.5 s) of writing, so a process that is killed loses at
most its last second; SIGINT and SIGTERM wait until a write is complete, and SIGTERM
finishes the file before the process ends (:class:`Recorder`). Reading
(:func:`iter_messages`, :mod:`~thermoskin.runtime.mcap_scan`) needs no summary or
footer: it keeps everything up to a cut-off end, skips a damaged part, resumes at the
next intact chunk (its CRC checked) and reports what was lost.
"""

from __future__ import annotations

import contextlib
import dataclasses
import datetime as _dt
import json
import math
import mmap
import os
import signal
import struct
import threading
import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

from mcap.writer import CompressionType, Writer

from thermoskin.atomic import arrow_target, atomic_path
from thermoskin.devices.base import Sample
from thermoskin.runtime.mcap_scan import RecordingError, RecordingReport, ScanError, Scanner

_NUM = {"type": "number"}
_NUM_NULL = {"type": ["number", "null"]}
_INT = {"type": "integer"}

TOPIC_SCHEMAS: dict[str, dict[str, Any]] = {
    "/skin/sample": {
        "title": "thermoskin.Sample",
        "description": "one device sample: temperatures degC, v m/s, drive in [-1, 1]; null = no reading",
        "type": "object",
        "properties": {"t": _NUM, "T_w": _NUM_NULL, "T_p": _NUM_NULL, "T_a": _NUM_NULL, "v": _NUM_NULL,
                       "drive": _NUM_NULL, "fresh": _INT, "stale": _INT, "stuck": _INT, "status": _INT,
                       "seq": _INT},
        "required": ["t"],
    },
    "/skin/estimate": {
        "title": "thermoskin.Estimate",
        "description": "thermal exchange observer (eq. 8) and contact detector: W, W, 0/1",
        "type": "object",
        "properties": {"t": _NUM, "q_i_hat": _NUM_NULL, "dq_i_hat": _NUM_NULL, "contact": _INT,
                       "gap": _INT},
        "required": ["t"],
    },
    "/control": {
        "title": "thermoskin.Control",
        "description": "commands: T_w_cmd, T_p_cmd degC, drive in [-1, 1], v_cmd m/s (the v the "
                       "observer used)",
        "type": "object",
        "properties": {"t": _NUM, "T_w_cmd": _NUM_NULL, "T_p_cmd": _NUM_NULL, "drive": _NUM_NULL,
                       "v_cmd": _NUM_NULL},
        "required": ["t"],
    },
    "/events": {
        "title": "thermoskin.Event",
        "description": "contact events, faults, link loss",
        "type": "object",
        "properties": {"t": _NUM, "kind": {"type": "string"}, "detail": {}},
        "required": ["t", "kind"],
    },
    "/sim/truth": {
        "title": "thermoskin.Truth",
        "description": "the simulator's truth: q_i W, T_g/T_w_true/T_p_true degC, contact_true 0/1",
        "type": "object",
        "properties": {"t": _NUM, "q_i": _NUM_NULL, "T_g": _NUM_NULL, "T_w_true": _NUM_NULL,
                       "T_p_true": _NUM_NULL, "contact_true": _INT, "n_fingers": _INT},
        "required": ["t"],
    },
    "/loop/timing": {
        "title": "thermoskin.LoopTiming",
        "description": "fixed-rate loop: lateness of the step against its deadline, step time (s)",
        "type": "object",
        "properties": {"t": _NUM, "late": _NUM_NULL, "lag": _NUM_NULL, "busy": _NUM_NULL},
        "required": ["t"],
    },
    "/params": {
        "title": "thermoskin.Params",
        "description": "the run's configuration (params.Config as nested objects)",
        "type": "object",
        "properties": {"t": _NUM, "config": {}},
        "required": ["config"],
    },
}
_ANY_SCHEMA: dict[str, Any] = {"type": "object"}

REPLAY_TOL_W = 1e-9
"""A replay agrees with the live run when its estimates are within this (W) and every contact
flag is the same. On the recording's own host and versions they are identical; elsewhere the
compiled kernel's fused multiply-adds (a CPU, numba or LLVM that fuses otherwise) can move
them by about 1e-12 W."""


def _clean(value: Any) -> Any:
    """NaN and infinities to ``None`` (JSON has none of them)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def _config_object(config: Any) -> Any:
    if config is None:
        return {}
    if dataclasses.is_dataclass(config) and not isinstance(config, type):
        return dataclasses.asdict(config)
    if isinstance(config, str | bytes):
        try:
            return json.loads(config)
        except ValueError:
            return {"text": config if isinstance(config, str) else config.decode("utf-8", "replace")}
    return config


class _SignalGuard:
    """Defers SIGINT and SIGTERM while a recorder writes, so no signal tears a record.

    Python runs signal handlers in the main thread between bytecodes; the default SIGINT
    handler raises ``KeyboardInterrupt`` there, which inside the MCAP writer would leave a
    half-built record in its buffers (written out, torn, at the next flush or at close).
    While any :class:`Recorder` of this process is open, this guard's handler takes
    SIGINT and SIGTERM: inside a write (``with _GUARD:``, main thread) it only notes the
    signal and delivers it when the outermost write ends; outside, at once. Delivery calls
    the handler that was there before (``KeyboardInterrupt`` for SIGINT); where that was
    the default action (SIGTERM), the open recordings are finished first (summary, footer),
    then the process ends by the signal as it would have. Forked children forget the
    recorders (they never write their parent's file).
    """

    SIGNALS = (signal.SIGINT, signal.SIGTERM)

    def __init__(self) -> None:
        self.depth = 0
        self.pending: list[int] = []
        self.previous: dict[int, Any] = {}
        self.recorders: list[Recorder] = []
        self.main = threading.main_thread().ident

    def __enter__(self) -> None:
        if threading.get_ident() == self.main:
            self.depth += 1

    def __exit__(self, *exc: object) -> None:
        if threading.get_ident() == self.main:
            self.depth -= 1  # first: a signal from here on is delivered at once
            if self.pending and not self.depth:
                sigs, self.pending = self.pending, []
                for sig in sigs:
                    self._deliver(sig, None)

    def add(self, rec: Recorder) -> None:
        """Guard ``rec`` (created in the main thread; elsewhere signals cannot be handled)."""
        if threading.get_ident() != self.main:
            return
        if not self.recorders:
            for sig in self.SIGNALS:
                prev = signal.getsignal(sig)
                if prev in (signal.SIG_IGN, None) or prev == self._handle:
                    continue
                self.previous[sig] = prev
                signal.signal(sig, self._handle)
        self.recorders.append(rec)

    def remove(self, rec: Recorder) -> None:
        if rec not in self.recorders:
            return
        self.recorders.remove(rec)
        if not self.recorders and threading.get_ident() == self.main:
            for sig, prev in self.previous.items():
                if signal.getsignal(sig) == self._handle:
                    signal.signal(sig, prev)
            self.previous.clear()

    def forget(self) -> None:
        """In a forked child: the recorders are the parent's."""
        self.recorders.clear()
        self.pending.clear()
        self.depth = 0
        self.main = threading.main_thread().ident

    def _handle(self, sig: int, frame: Any) -> None:
        if self.depth:
            if sig not in self.pending:
                self.pending.append(sig)
            return
        self._deliver(sig, frame)

    def _deliver(self, sig: int, frame: Any) -> None:
        prev = self.previous.get(sig, signal.SIG_DFL)
        if callable(prev):
            prev(sig, frame)  # SIGINT: raises KeyboardInterrupt, outside any write
            return
        if prev == signal.SIG_IGN:
            return
        self.depth += 1  # the default action ends the process: finish the recordings first
        try:
            for rec in list(self.recorders):
                with contextlib.suppress(Exception):
                    rec.close()
        finally:
            signal.signal(sig, signal.SIG_DFL)
            os.kill(os.getpid(), sig)


_GUARD = _SignalGuard()
os.register_at_fork(after_in_child=_GUARD.forget)


class _Appender:
    """The MCAP writer's output: bytes gather in memory; :meth:`commit` appends them to the
    file with ``os.write`` (one call for a chunk and its index, short writes resumed), so
    the file only ever grows by whole records."""

    def __init__(self, fd: int, path: str | os.PathLike[str] | None = None) -> None:
        self.fd = fd
        self.path = path  # named by an error
        self.pos = 0  # bytes in the file
        self.buf = bytearray()

    def write(self, data: bytes) -> int:
        self.buf += data
        return len(data)

    def tell(self) -> int:
        return self.pos + len(self.buf)

    def flush(self) -> None:
        """Nothing: the recorder commits when a chunk is complete."""

    def commit(self) -> None:
        while self.buf:
            try:
                n = os.write(self.fd, self.buf)
            except OSError as e:  # a full disk: the file keeps its whole records so far
                raise OSError(e.errno, e.strerror, self.path) from None
            del self.buf[:n]
            self.pos += n


#: DataEnd (no CRC) and a footer without summary: what ends a file whose writer was torn.
_BARE_END = (struct.pack("<BQI", 0x0F, 4, 0) + struct.pack("<BQQQI", 0x02, 20, 0, 0, 0)
             + b"\x89MCAP0\r\n")


class Recorder:
    """Write topics to an MCAP file with JSON-schema channels; safe against kills and signals.

    ``config`` (a :class:`~thermoskin.params.Config`, a JSON string or a mapping) is
    written once on ``/params``. Use as a context manager or call :meth:`close`.

    A chunk is closed and appended to the file (one ``os.write``) every ``flush_interval``
    s of writing, when it reaches ``chunk_size`` bytes, and after the first message of a
    new topic (so a channel's definition sits in a small chunk of its own). A killed
    process therefore loses at most its last ``flush_interval``, and a damaged part of
    the file costs at most the chunks it touches. With ``guard_signals`` (and when made in
    the main thread) SIGINT and SIGTERM wait until a write is complete and SIGTERM
    finishes the file before it ends the process (see :class:`_SignalGuard`). Use a
    recorder from the thread that made it.

    ``schemas`` (topic: schema) adds topics to :data:`TOPIC_SCHEMAS` (a skin's,
    :mod:`~thermoskin.live.skin_topics`): a JSON schema (a dict), or a ``foxglove.Schema``
    (``name``, ``encoding``, ``data``) whose messages are written as the bytes given (protobuf).
    ``params``: more fields of the ``/params`` message (a skin's layout).
    """

    def __init__(self, path: str | os.PathLike[str], config: Any = None, *,
                 flush_interval: float = 0.5, fsync: bool = False,
                 compression: str = "zstd", chunk_size: int = 64 * 1024,
                 guard_signals: bool = True, schemas: Mapping[str, Any] | None = None,
                 params: Mapping[str, Any] | None = None) -> None:
        self.path = Path(path)
        self.schemas: dict[str, Any] = {**TOPIC_SCHEMAS, **(schemas or {})}
        self.flush_interval = float(flush_interval)
        self.fsync = bool(fsync)
        comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                "none": CompressionType.NONE}.get(compression)
        if comp is None:
            raise ValueError(f"Recorder: compression {compression!r} must be zstd, lz4 or none")
        self._channels: dict[str, int] = {}
        self._seq: dict[str, int] = {}
        self._t_flush = time.monotonic()
        self._busy = False  # inside the MCAP writer (still true after an exception there: torn)
        self.closed = False
        self.messages = 0
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            if (self.path.is_file() and not self.path.is_symlink()
                    and os.access(self.path, os.W_OK)):
                # a new file, not the old one cut to nothing: a reader of the old recording
                # (`replay`, `export`: mapped) reads it to its end instead of faulting (a
                # folder that lets us write the file but not remove it: cut in place, below;
                # a file we may not write is refused below, as before, not replaced)
                with contextlib.suppress(OSError):
                    os.unlink(self.path)
            self._fd = os.open(self.path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC, 0o644)
        except OSError as e:
            self.closed = True
            raise RecordingError(f"cannot record to {self.path}: {e.strerror or e}") from None
        self._out = _Appender(self._fd, self.path)
        self._writer: Writer | None = None
        if guard_signals:
            _GUARD.add(self)
        try:
            with _GUARD:  # a signal meanwhile is delivered once the file has its /params
                self._writer = Writer(self._out, compression=comp, chunk_size=int(chunk_size))  # type: ignore[arg-type]
                self._writer.start(profile="", library="thermoskin")
                self._writer.add_metadata("thermoskin", {
                    "started": _dt.datetime.now(_dt.UTC).isoformat(),
                    "time": "log_time = t (s) of the loop clock, in ns",
                })
                self.write("/params", 0.0, {"config": _config_object(config), **(params or {})})
        except BaseException:
            self.close()  # the caller gets no recorder to close: a finished file all the same
            raise

    def _channel(self, topic: str) -> int:
        schema = self.schemas.get(topic, _ANY_SCHEMA)
        if isinstance(schema, dict):
            name = schema.get("title", topic.strip("/").replace("/", "."))
            sid = self._writer.register_schema(name=name, encoding="jsonschema",
                                               data=json.dumps(schema).encode())
            enc = "json"
        else:
            sid = self._writer.register_schema(name=schema.name, encoding=schema.encoding,
                                               data=bytes(schema.data))
            enc = schema.encoding
        cid = self._writer.register_channel(topic=topic, message_encoding=enc, schema_id=sid)
        self._channels[topic] = cid
        self._seq[topic] = 0
        return cid

    def write(self, topic: str, t: float, data: Mapping[str, Any] | bytes) -> None:
        """Record ``data`` (a flat mapping; ``t`` is added if absent; or bytes, an encoded message of
        the topic's schema) on ``topic`` at time ``t`` s."""
        if self.closed:
            raise RecordingError(f"{self.path}: write after close")
        if self._busy:
            raise RecordingError(f"{self.path}: the MCAP writer was interrupted inside a record; "
                                 "the recording holds what was written before")
        if not math.isfinite(t):
            raise RecordingError(f"{self.path}: time t = {t} on {topic} is not finite")
        if isinstance(data, bytes):
            payload = data
        else:
            obj = {"t": t}
            for k, v in data.items():
                obj[k] = _clean(v)
            payload = json.dumps(obj, separators=(",", ":")).encode()
        ns = max(0, round(t * 1e9))
        with _GUARD:
            self._busy = True
            cid = self._channels.get(topic)
            new = cid is None
            if new:
                cid = self._channel(topic)
            seq = self._seq[topic] = self._seq[topic] + 1
            self._writer.add_message(cid, ns, payload, ns, seq)  # type: ignore[union-attr]
            self._busy = False
            self.messages += 1
            now = time.monotonic()
            if new or now - self._t_flush >= self.flush_interval:
                self.flush(now)
            elif self._out.buf:  # a chunk reached chunk_size
                self._out.commit()

    def write_sample(self, s: Sample) -> None:
        """Record a device :class:`~thermoskin.devices.base.Sample` on ``/skin/sample``."""
        self.write("/skin/sample", s.t, s.as_dict())

    def event(self, t: float, kind: str, **detail: Any) -> None:
        """Record an event (``contact-on``, ``fault``, ``link-lost``, ...) on ``/events``."""
        self.write("/events", t, {"kind": kind, "detail": {k: _clean(v) for k, v in detail.items()}})

    def flush(self, now: float | None = None) -> None:
        """Close the chunk in progress and append it to the file (and the disk, with ``fsync``)."""
        with _GUARD:
            if not self._busy:
                self._busy = True
                self._writer.flush()  # type: ignore[union-attr]
                self._busy = False
            self._out.commit()
            if self.fsync:
                os.fsync(self._fd)
        self._t_flush = time.monotonic() if now is None else now

    def close(self) -> None:
        """Write the summary and footer, close the file.

        If the MCAP writer was interrupted inside a record (an exception raised in it),
        what it had completed is kept and the file is ended without a summary.
        """
        if self.closed:
            return
        with _GUARD:
            self.closed = True
            try:
                if self._writer is not None and not self._busy:
                    self._busy = True
                    self._writer.finish()
                    self._busy = False
                    self._out.commit()
                elif self._writer is not None:
                    self._out.commit()
                    os.write(self._fd, _BARE_END)
                if self.fsync:
                    os.fsync(self._fd)
            finally:
                os.close(self._fd)
                _GUARD.remove(self)

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# ----------------------------------------------------------------------------- reading

def _load(path: str | os.PathLike[str]) -> tuple[Path, bytes]:
    p = Path(path)
    if p.is_dir():
        raise RecordingError(f"recording {p} is a directory, not an MCAP file")
    if not p.exists():
        raise RecordingError(f"recording {p} does not exist")
    try:
        with open(p, "rb") as fh:  # mapped, not read: the scanner lets go of what it has read
            if os.fstat(fh.fileno()).st_size == 0:
                return p, b""
            return p, mmap.mmap(fh.fileno(), 0, access=mmap.ACCESS_READ)  # type: ignore[return-value]
    except OSError as e:
        raise RecordingError(f"cannot read recording {p}: {e.strerror or e}") from None


def scan_messages(path: str | os.PathLike[str], publish_time: bool = False) -> Scanner:
    """A :class:`~thermoskin.runtime.mcap_scan.Scanner` of the recording at ``path``
    (its messages with their publish time last if ``publish_time``)."""
    p, data = _load(path)
    try:
        return Scanner(p, data, publish_time)
    except ScanError as e:
        raise RecordingError(str(e)) from None


def check(path: str | os.PathLike[str]) -> RecordingReport:
    """Read the whole recording without decoding it: how it ends, what is damaged or lost."""
    sc = scan_messages(path)
    for _ in sc.batches():
        pass
    return sc.report


def recording_channels(path: str | os.PathLike[str]) -> dict[str, tuple[str, str, str, bytes]]:
    """Every channel of a recording: ``topic -> (message encoding, schema name, schema
    encoding, schema data)``, from the summary of a finished file, else from its chunks."""
    sc = scan_messages(path)
    if not sc.channel_info:  # cut off (no summary): read the data for its channel records
        for _ in sc.batches():
            pass
    out = {}
    for topic, sid, enc in sc.channel_info.values():
        name, s_enc, data = sc.schemas.get(sid, ("", "", b""))
        out[topic] = (enc, name, s_enc, data)
    return out


def _fill(info: dict[str, Any] | None, rep: RecordingReport) -> None:
    if info is not None:
        info.update(complete=rep.complete, truncated=not rep.complete, error=rep.error, report=rep)


def iter_messages(path: str | os.PathLike[str], topics: Sequence[str] | None = None,
                  info: dict[str, Any] | None = None) -> Iterator[tuple[str, float, dict[str, Any]]]:
    """``(topic, t, message)`` in file order, past a cut-off end and damaged parts.

    Every intact chunk is read, also after damage (see :mod:`~thermoskin.runtime.mcap_scan`).
    JSON ``null`` values come back as NaN. ``info`` (if given) receives, once the
    messages are exhausted, ``report`` (a :class:`~thermoskin.runtime.mcap_scan.RecordingReport`:
    lost spans, where a cut-off file ends), ``complete`` (finished and undamaged),
    ``truncated`` (not complete) and ``error`` (the first problem met).
    """
    sc = scan_messages(path)
    wanted = set(topics) if topics is not None else None
    if info is not None:
        info.update(complete=False, truncated=False, error="", report=sc.report)
    nan = math.nan
    loads = json.loads
    for batch in sc.batches():
        if wanted is not None:
            batch = [m for m in batch if m[0] in wanted]
        if not batch:
            continue
        try:  # a chunk's messages in one call; one by one if any is not one JSON value
            objs = loads(b"[" + b",".join([m[3] for m in batch]) + b"]")
            if len(objs) != len(batch):
                raise ValueError("not one value per message")
        except ValueError:
            objs = [_loads_or_none(m[3]) for m in batch]
        for (topic, _, log_time, _), obj in zip(batch, objs, strict=True):
            if isinstance(obj, dict):
                for k, v in obj.items():
                    if v is None:
                        obj[k] = nan
                t = obj.get("t")
                yield topic, float(t) if isinstance(t, int | float) else log_time * 1e-9, obj
    _fill(info, sc.report)


def _loads_or_none(payload: bytes) -> Any:
    try:
        return json.loads(payload)
    except ValueError:
        return None


def read_mcap(path: str | os.PathLike[str], topics: Sequence[str] | None = None,
              info: dict[str, Any] | None = None) -> dict[str, list[dict[str, Any]]]:
    """Every message by topic, in file order (past damage; see :func:`iter_messages`)."""
    out: dict[str, list[dict[str, Any]]] = {}
    for topic, _, obj in iter_messages(path, topics, info):
        out.setdefault(topic, []).append(obj)
    return out


# ----------------------------------------------------------------------------- export

MERGE_TOPICS = ("/skin/estimate", "/control", "/sim/truth", "/loop/timing")

#: A column: floats (NaN where a sample has no value) or, if any value is not a number,
#: text (``None`` where a sample has no value; objects and lists as JSON).
Column = list[float] | list[str | None]


def _is_number(v: Any) -> bool:
    return isinstance(v, int | float)


def _text(v: Any) -> str | None:
    if v is None or (isinstance(v, float) and math.isnan(v)):
        return None
    if isinstance(v, str):
        return v
    return json.dumps(v, separators=(",", ":"))


class SchemaChangeError(RecordingError):
    """A streamed table met a column after its first block, or a text value in a column of
    numbers: the caller starts again on the whole table (:func:`to_columns`)."""


BLOCK_ROWS = 16_384
"""Rows of a block of :func:`iter_columns`."""
_HOLD_ROWS = 1_024  # the newest rows, held back for merged messages that come late


def to_columns(path: str | os.PathLike[str], sample_topic: str = "/skin/sample",
               merge: Sequence[str] = MERGE_TOPICS,
               info: dict[str, Any] | None = None) -> dict[str, Column]:
    """One row per sample of ``sample_topic``; the fields of ``merge`` topics joined by ``t``.

    A merged message belongs to the sample with the same ``t`` (to the µs); samples without
    one get NaN. A merged field whose name is already taken is named ``<topic leaf>.<field>``
    (``control.drive``: the commanded drive, next to ``drive``, the one the device applied).
    A field with any value that is not a number (text, an object) is a text column
    (see :data:`Column`). ``info`` as in :func:`iter_messages`.

    A recording cut off while its last sample was being recorded (a killed run) ends with
    samples whose other messages were never written: those trailing rows are left out, so
    that the table ends at its last whole sample (where ``info`` says it is not complete),
    and the report's end (``info["report"].t_end``, in its cut-off warning) says so.
    The whole table at once: :func:`iter_columns` in one block.
    """
    return next(iter_columns(path, sample_topic, merge, info, block=None))


def iter_columns(path: str | os.PathLike[str], sample_topic: str = "/skin/sample",
                 merge: Sequence[str] = MERGE_TOPICS, info: dict[str, Any] | None = None,
                 block: int | None = BLOCK_ROWS) -> Iterator[dict[str, Column]]:
    """:func:`to_columns`, ``block`` rows at a time (None: the whole table in one), in memory
    that does not grow with the recording: the messages are read as they come and the rows
    of a block given once the newest :data:`_HOLD_ROWS` rows have come after them (a
    sample's merged messages follow it closely). Every block has the first block's columns,
    each numbers throughout or text throughout; a recording where that does not hold (a field
    first met later, a text value in a column of numbers) raises :class:`SchemaChangeError` at the
    block that shows it."""
    info = {} if info is None else info
    nan = math.nan
    leaves = {m: m.rstrip("/").rsplit("/", 1)[-1] for m in merge}
    base: dict[str, None] = {}  # the samples' fields, in order
    merged: dict[str, None] = {}  # the merged fields' names
    order: dict[str, list[str]] = {m: [] for m in merge}  # each merged topic's, as first met
    rows: list[dict[str, Any]] = []  # the rows not given yet
    index: dict[int, int] = {}  # a pending sample's time (µs) -> its place in rows
    given: list[str] | None = None  # the columns of the first block given
    text: set[str] = set()
    seen: set[str] = set()  # merged fields with a value in a row already given
    last_given = -(1 << 62)  # the time (µs) of the last row given out

    def give(m: int) -> dict[str, Column]:
        nonlocal given, rows, index, last_given
        names = [*base, *(k for m in merge for k in order[m])]
        out = {k: [r.get(k, nan) for r in rows[:m]] for k in names}
        for k in merged:
            if k not in seen and any(not (isinstance(v, float) and v != v) for v in out[k]):
                seen.add(k)
        for name, col in out.items():
            is_text = not {type(v) for v in col} <= {float, int, bool}
            if given is not None and is_text != (name in text):
                raise SchemaChangeError(f"{path}: column {name!r} changes type after its first block")
            if is_text:
                text.add(name)
                out[name] = [_text(v) for v in col]
            else:
                out[name] = [float(v) for v in col]
        if given is None:
            given = names
        elif names != given:
            raise SchemaChangeError(f"{path}: columns {sorted(set(names) - set(given))} first met after "
                                "the first block")
        if m and given is not None:
            t_m = rows[m - 1].get("t", nan)
            if _is_number(t_m) and math.isfinite(t_m):
                last_given = max(last_given, round(t_m * 1e6))
        rows = rows[m:]
        index = {k: i - m for k, i in index.items() if i >= m}
        return out

    for topic, _, msg in iter_messages(path, [sample_topic, *merge], info):
        if topic == sample_topic:
            for k in msg:
                base.setdefault(k)
            t = msg.get("t", nan)
            if _is_number(t) and math.isfinite(t):
                index[round(t * 1e6)] = len(rows)
            rows.append(dict(msg))
            if block is not None and len(rows) >= block + _HOLD_ROWS:
                yield give(block)
            continue
        t = msg.get("t", nan)
        key = round(t * 1e6) if _is_number(t) and math.isfinite(t) else None
        i = index.get(key) if key is not None else None
        if i is None:
            if key is not None and key <= last_given:  # for a row given out already: read whole
                raise SchemaChangeError(f"{path}: a {topic} message {len(rows)} rows after its sample")
            continue
        row = rows[i]
        for k, v in msg.items():
            if k != "t":
                name = f"{leaves[topic]}.{k}" if k in base else k
                if name not in merged:
                    merged[name] = None
                    order[topic].append(name)
                row[name] = v
    if given is None and not rows:
        raise RecordingError(f"{path}: no messages on {sample_topic}")
    n = len(rows)
    if not info.get("complete", True) and n:
        tail = {k: [r.get(k, nan) for r in rows] for k in merged}
        n_whole = _whole_rows(tail, set(merged), n, seen)
        if given is not None and n_whole == n and not all(
                not (isinstance(v, float) and v != v) for k, v in ((k, tail[k][-1]) for k in seen)):
            # no whole row among those held: the last whole one was given out already
            raise SchemaChangeError(f"{path}: its last whole sample is before the rows held")
        if n_whole < n:
            rows = rows[:n_whole]
            n = n_whole
            rep = info.get("report")
            if rep is not None and getattr(rep, "cut_off", False) and n:
                rep.t_end = float(rows[-1]["t"])  # where the readable recording ends, as said
    if n or given is None:
        yield give(n)


def skin_columns(path: str | os.PathLike[str],
                 info: dict[str, Any] | None = None) -> dict[str, Column] | None:
    """A skin's recording (``run --skin --record``: ``/patch/NAME/sample``, ``estimate``,
    ``truth``) as one long table, one row per sample and patch (sample-major, patches in the
    skin's order, ``patch`` their index, as the skin's log): each patch's topics joined as
    :func:`to_columns` joins a single patch's. None if the recording is not a skin's.
    A cut-off recording ends at the last sample every patch has whole. The whole table at
    once: :func:`iter_skin_columns` in one block."""
    blocks = iter_skin_columns(path, info, block=None)
    return None if blocks is None else next(blocks)


def iter_skin_columns(path: str | os.PathLike[str], info: dict[str, Any] | None = None,
                      block: int | None = BLOCK_ROWS) -> Iterator[dict[str, Column]] | None:
    """:func:`skin_columns`, about ``block`` rows (``block / P`` samples of each of its ``P``
    patches) at a time: each patch's :func:`iter_columns`, in step (None if the recording is
    not a skin's)."""
    samples = [t for t in recording_channels(path) if t.startswith("/patch/") and t.endswith("/sample")]
    if not samples:
        return None
    names = [t[len("/patch/"):-len("/sample")] for t in samples]
    params = read_mcap(path, ["/params"]).get("/params", [])
    layout = params[0].get("skin") if params else None
    if isinstance(layout, dict) and isinstance(layout.get("patches"), list):
        order = [p.get("name") for p in layout["patches"] if isinstance(p, dict)]
        if sorted(order) == sorted(names):
            names = order
    sub: dict[str, Any] = {}
    block = None if block is None else max(1, block // len(names))  # long-format rows a block
    gens = [iter_columns(path, f"/patch/{name}/sample", (f"/patch/{name}/estimate", f"/patch/{name}/truth"),
                         info=sub if i == 0 else None, block=block) for i, name in enumerate(names)]
    return _interleave(gens, sub, info)


def _interleave(gens: list[Iterator[dict[str, Column]]], sub: dict[str, Any],
                info: dict[str, Any] | None) -> Iterator[dict[str, Column]]:
    """The patches' blocks, taken in step, as long-format blocks (:func:`skin_columns`)."""
    nan = math.nan
    P = len(gens)
    for per in zip(*gens, strict=False):
        n = min(len(c["t"]) for c in per)
        keys = list(dict.fromkeys(k for c in per for k in c))
        out: dict[str, Column] = {"t": [x for x in per[0]["t"][:n] for _ in range(P)],
                                  "patch": [float(i) for _ in range(n) for i in range(P)]}
        for k in keys:
            if k == "t":
                continue
            cols = [c.get(k) or [nan] * n for c in per]
            out[k] = [cols[i][r] for r in range(n) for i in range(P)]
        if info is not None:
            info.update(sub)
        yield out
    for g in gens:  # a patch recorded longer than another: read to its end (its report)
        for _ in g:
            pass
    if info is not None:
        info.update(sub)


def _whole_rows(cols: dict[str, list[Any]], merged: set[str], n: int,
                seen: set[str] | frozenset[str] = frozenset()) -> int:
    """Rows up to the last one that has every merged field that began before it (``seen``:
    fields that began before these rows)."""
    def has(v: Any) -> bool:
        return not (isinstance(v, float) and v != v)

    first = {name: -1 if name in seen else next((i for i, v in enumerate(cols[name]) if has(v)), n)
             for name in merged}
    for k in range(n - 1, -1, -1):
        if all(has(cols[name][k]) or first[name] >= k for name in merged):
            return k + 1
    return n


def _is_text(col: Column) -> bool:
    return any(not isinstance(v, float) for v in col)


def _write_csv(out: Path, cols: dict[str, Column]) -> Path:
    """CSV with text columns: numbers at full precision (integers without a point), text
    quoted, an empty field where a value is missing; written to a temporary file, renamed."""
    text = {k for k, c in cols.items() if _is_text(c)}

    def cell(name: str, v: Any) -> str:
        if name in text:
            return "" if v is None else '"' + v.replace('"', '""') + '"'
        if v != v:
            return "nan"
        return str(int(v)) if v.is_integer() and abs(v) < 2 ** 53 else repr(v)

    def head(name: str) -> str:
        return '"' + name.replace('"', '""') + '"' if any(c in name for c in ',"\r\n') else name

    names = list(cols)
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as tmp, open(tmp, "w", encoding="utf-8", newline="") as fh:
        fh.write(",".join(head(k) for k in names) + "\n")
        for row in zip(*(cols[k] for k in names), strict=True):
            fh.write(",".join(cell(k, v) for k, v in zip(names, row, strict=True)) + "\n")
    return out


def export(path_mcap: str | os.PathLike[str], out_path: str | os.PathLike[str],
           info: dict[str, Any] | None = None, **kw: Any) -> Path:
    """Export a recording to ``.csv`` or ``.parquet`` (pyarrow); text fields as text columns.

    A CSV of numbers only is a log (:func:`thermoskin.logio.write_log`); with text columns
    it is written as :func:`_write_csv` says. ``info`` as in :func:`iter_messages`. A single
    patch's recording, or a skin's, is read and written block by block (:func:`iter_columns`,
    :func:`iter_skin_columns`), so memory does not grow with it, unless its columns change
    along it or a CSV needs text (then it is read whole).
    """
    out = Path(out_path)
    suffix = out.suffix.lower()
    if suffix not in (".csv", ".parquet"):
        raise RecordingError(f"cannot export to {out}: the extension must be .csv or .parquet")
    if out.is_dir():
        raise RecordingError(f"cannot export to {out}: it is a directory")
    skin = None if kw else iter_skin_columns(path_mcap, info, block=BLOCK_ROWS)
    try:  # block by block (memory does not grow with the recording) ...
        blocks = iter_columns(path_mcap, info=info, block=BLOCK_ROWS, **kw) if skin is None else skin
        return _export_blocks(blocks, out, path_mcap)
    except SchemaChangeError:  # ... unless its columns change (a text CSV): whole
        whole = to_columns(path_mcap, info=info, **kw) if skin is None else skin_columns(path_mcap, info)
        assert whole is not None
        cols = whole
    if suffix == ".csv":
        if any(_is_text(c) for c in cols.values()):
            return _write_csv(out, cols)
        from thermoskin.logio import write_log

        try:
            return write_log(out, cols)
        except ValueError as e:  # a field name a log cannot carry
            raise RecordingError(f"cannot export to {out}: {e}") from None
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise RecordingError("export to .parquet needs pyarrow (pip install pyarrow); "
                             "export to .csv works without it") from None
    out.parent.mkdir(parents=True, exist_ok=True)
    table = pa.table({k: pa.array(v, type=pa.string() if _is_text(v) else pa.float64())
                      for k, v in cols.items()})
    with arrow_target(out, "wb") as f:
        pq.write_table(table, f)
    return out


def _export_blocks(blocks: Iterator[dict[str, Column]], out: Path, path_mcap: str | os.PathLike[str]) -> Path:
    """:func:`export` of a table of numbers, block by block (:class:`SchemaChangeError`
    otherwise: each output is written whole or not at all)."""
    import numpy as np

    def numbers() -> Iterator[dict[str, Any]]:
        for b in blocks:
            if any(_is_text(c) for c in b.values()):
                raise SchemaChangeError(f"{path_mcap}: text columns")
            yield {k: np.asarray(v, dtype=np.float64) for k, v in b.items()}

    if out.suffix.lower() == ".csv":
        from thermoskin.logio import write_blocks

        try:  # a flag column of integers is written as integers (per 262 144 rows, as write_log)
            write_blocks(out, numbers(), by_rows=True)
        except RecordingError:
            raise
        except ValueError as e:  # a field name a log cannot carry
            raise RecordingError(f"cannot export to {out}: {e}") from None
        return out
    try:
        import pyarrow as pa
        import pyarrow.parquet as pq
    except ImportError:
        raise RecordingError("export to .parquet needs pyarrow (pip install pyarrow); "
                             "export to .csv works without it") from None
    out.parent.mkdir(parents=True, exist_ok=True)
    with atomic_path(out) as tmp, contextlib.ExitStack() as stack:
        writer = None
        for b in numbers():
            table = pa.table({k: pa.array(v, type=pa.float64()) for k, v in b.items()})
            if writer is None:
                target = stack.enter_context(arrow_target(tmp, "wb"))
                writer = stack.enter_context(pq.ParquetWriter(target, table.schema))
            writer.write_table(table)
    return out


# ----------------------------------------------------------------------------- replay

def _int(x: Any) -> int:
    return int(x) if isinstance(x, int | float) and math.isfinite(x) else 0


class ReplayDevice:
    """A recording played back through the device interface (:class:`~thermoskin.devices.base.Device`).

    :meth:`read_sample` returns the recorded ``/skin/sample`` messages in order (paced at
    their recorded times when ``realtime``); commands are kept in :attr:`commands` and
    have no effect. At the end of the recording ``read_sample`` returns ``None`` and
    :attr:`link_lost` becomes true.
    """

    def __init__(self, path: str | os.PathLike[str], realtime: bool = False) -> None:
        self.path = Path(path)
        self.realtime = realtime
        self.commands: list[tuple[float, float, float]] = []
        self.safe_calls = 0
        self._it: Iterator[tuple[str, float, dict[str, Any]]] | None = None
        self._t_last = 0.0
        self._done = False
        self._t0_wall = 0.0
        self._t0 = math.nan

    def open(self) -> None:
        self._it = iter_messages(self.path, ["/skin/sample"])
        self._done = False
        self._t0 = math.nan

    def read_sample(self, timeout: float = 0.0) -> Sample | None:
        if self._it is None:
            raise RecordingError(f"{self.path}: replay is not open")
        try:
            _, t, m = next(self._it)
        except StopIteration:
            self._done = True
            return None
        if self.realtime:
            if math.isnan(self._t0):
                self._t0, self._t0_wall = t, time.monotonic()
            delay = self._t0_wall + (t - self._t0) - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        self._t_last = t
        g = m.get
        return Sample(t, g("T_w", math.nan), g("T_p", math.nan), g("T_a", math.nan),
                      _int(g("fresh", 7)), _int(g("seq", 0)), g("v", math.nan), g("drive", math.nan),
                      _int(g("status", 0)), _int(g("stale", 0)), _int(g("stuck", 0)), time.monotonic())

    def write_command(self, drive: float, v: float) -> None:
        self.commands.append((self._t_last, drive, v))

    def safe(self) -> None:
        self.safe_calls += 1

    def close(self) -> None:
        self._it = None

    @property
    def link_lost(self) -> bool:
        return self._done


# ----------------------------------------------------------------------------- loop recording

def _ints(col: Any, n: int) -> list[int]:
    if col is None:
        return [0] * n
    return [int(x) if x == x else 0 for x in col.tolist()]


class LoopRecorder:
    """Records the closed loop's rows (columns of :data:`~thermoskin.runtime.realtime.ROW` or of
    ``closed_loop.COLUMNS``) on the topics above, block by block, and its events.

    A row whose ``fault`` is non-zero is the sample on which the supervisor tripped: its
    sample and commands are recorded, no estimate (the blocks did not run on it).
    """

    def __init__(self, path: str | os.PathLike[str], config: Any, **kw: Any) -> None:
        self.rec = Recorder(path, config, **kw)
        self.rows = 0
        self._contact = 0

    def write_rows(self, c: Mapping[str, Any]) -> None:
        """One block of rows as columns (arrays of equal length).

        A SIGINT or SIGTERM arriving meanwhile waits for the whole block (no row of a block
        is missing from the recording while the log has it).
        """
        with _GUARD:
            self._write_rows(c)

    def _write_rows(self, c: Mapping[str, Any]) -> None:
        t = c["t"].tolist()
        n = len(t)
        if not n:
            return
        L = {k: (v.tolist() if hasattr(v, "tolist") else list(v)) for k, v in c.items()}
        nan = [math.nan] * n
        T_w, T_p, T_a = L["T_w"], L["T_p"], L["T_a"]
        # the commands (a fixed-rate loop's rows carry them apart from the log's v and drive,
        # which are what the estimator modelled: a serial device's applied ones)
        v_cmd, drive = L.get("v_cmd", L["v"]), L.get("drive_cmd", L["drive"])
        T_w_cmd, T_p_cmd = L["T_w_cmd"], L["T_p_cmd"]
        v_dev, drive_dev = L.get("v_dev", v_cmd), L.get("drive_dev", drive)
        q, dq = L["q_i_hat"], L["dq_i_hat"]
        contact, gap = _ints(c["contact"], n), _ints(c["gap"], n)
        fresh = _ints(c.get("fresh"), n) if "fresh" in c else [7] * n
        stale, stuck = _ints(c.get("stale"), n), _ints(c.get("stuck"), n)
        status = _ints(c.get("status"), n)
        seq = _ints(c.get("seq"), n) if "seq" in c else list(range(self.rows, self.rows + n))
        fault = _ints(c.get("fault"), n)
        q_i = L.get("q_i", nan)
        has_truth = "q_i" in c and any(x == x for x in q_i)
        late, lag, busy = L.get("late"), L.get("lag", nan), L.get("busy")
        w = self.rec.write
        for i in range(n):
            ti = t[i]
            w("/skin/sample", ti, {"T_w": T_w[i], "T_p": T_p[i], "T_a": T_a[i], "v": v_dev[i],
                                   "drive": drive_dev[i], "fresh": fresh[i], "stale": stale[i],
                                   "stuck": stuck[i], "status": status[i], "seq": seq[i]})
            w("/control", ti, {"T_w_cmd": T_w_cmd[i], "T_p_cmd": T_p_cmd[i], "drive": drive[i],
                               "v_cmd": v_cmd[i]})
            if not fault[i]:
                w("/skin/estimate", ti, {"q_i_hat": q[i], "dq_i_hat": dq[i], "contact": contact[i],
                                         "gap": gap[i]})
                if contact[i] != self._contact:
                    self.rec.event(ti, "contact-on" if contact[i] else "contact-off")
                    self._contact = contact[i]
            if has_truth:
                w("/sim/truth", ti, {"q_i": q_i[i], "T_g": L["T_g"][i], "T_w_true": L["T_w_true"][i],
                                     "T_p_true": L["T_p_true"][i],
                                     "contact_true": int(L["contact_true"][i]),
                                     "n_fingers": int(L["n_fingers"][i])})
            if late is not None:
                w("/loop/timing", ti, {"late": late[i], "lag": lag[i], "busy": busy[i]})  # type: ignore[index]
        self.rows += n

    def event(self, t: float, kind: str, **detail: Any) -> None:
        self.rec.event(t, kind, **detail)

    def close(self) -> None:
        self.rec.close()


def config_from_params(obj: Mapping[str, Any]) -> Any:
    """The :class:`~thermoskin.params.Config` recorded on ``/params`` (NaN read back as None)."""
    from thermoskin.params import _SECTION_TYPES, Config

    sections = {}
    for name, cls in _SECTION_TYPES.items():
        d = obj.get(name)
        if isinstance(d, dict):
            known = {f.name for f in dataclasses.fields(cls)}
            vals = {k: (None if isinstance(v, float) and math.isnan(v) else v)
                    for k, v in d.items() if k in known}
            sections[name] = cls(**vals)
    return Config(**sections)


def replay(path: str | os.PathLike[str], config: Any = None,
           info: dict[str, Any] | None = None) -> tuple[dict[str, Any], dict[str, Any]]:
    """Re-run the observer and the detector on a recording; ``(columns, comparison)``.

    The blocks get the inputs the live loop gave them: ``t, T_w, T_p, T_a`` of
    ``/skin/sample`` and the ``v_cmd`` of ``/control`` (the pump command the observer
    used), on every sample that has an ``/skin/estimate`` (the samples the blocks ran
    on), with the recorded configuration (or ``config``). ``columns`` holds those inputs,
    the replayed ``q_i_hat, dq_i_hat, contact, gap`` and the live ones as ``*_live``;
    ``comparison`` the largest differences and the count of contact mismatches. A
    damaged recording is replayed over its intact parts; ``info`` (as in
    :func:`iter_messages`) says what was lost. The whole recording in memory:
    :func:`replay_blocks` joined.
    """
    import numpy as np

    comparison: dict[str, Any] = {}
    blocks = list(replay_blocks(path, config, info, comparison, whole=True))
    return {k: np.concatenate([b[k] for b in blocks]) for k in blocks[0]}, comparison


def replay_blocks(path: str | os.PathLike[str], config: Any = None, info: dict[str, Any] | None = None,
                  comparison: dict[str, Any] | None = None, *, whole: bool = False
                  ) -> Iterator[dict[str, Any]]:
    """:func:`replay`'s columns block by block (:func:`iter_columns`; ``whole``: in one block,
    :func:`to_columns`), the estimator carried from block to block, so memory does not grow
    with the recording; ``comparison`` (a dict) is filled once the blocks are exhausted. A
    recording whose columns change along it raises :class:`SchemaChangeError` (replay it
    ``whole``)."""
    import numpy as np

    from thermoskin.estimation.estimator import TouchEstimator
    from thermoskin.logio.plausible import admit_arrays, limits

    if config is None:
        params = read_mcap(path, ["/params"]).get("/params", [])
        if not params:
            raise RecordingError(f"{path}: no /params message; pass the configuration")
        config = config_from_params(params[0].get("config", {}))
    # a serial run's estimator modelled what the device applied (/skin/sample's v and drive);
    # others (and recordings from before that) the commands (/control's v_cmd and drive)
    start = [e for e in read_mcap(path, ["/events"]).get("/events", []) if e.get("kind") == "run-start"]
    applied = bool(start) and (start[0].get("detail") or {}).get("estimator_inputs") == "device"
    v_name, drive_name = ("v", "drive") if applied else ("v_cmd", "control.drive")
    source = iter_columns(path, info=info, block=None if whole else BLOCK_ROWS)
    lim = limits(config.plausible)
    est = TouchEstimator(config)
    need = ("T_w", "T_p", "T_a", v_name)
    samples = mism = 0
    max_q = max_dq = 0.0
    t_last = math.nan

    def worst(a: Any, b: Any) -> float:
        same = (a == b) | (np.isnan(a) & np.isnan(b))
        if same.all():
            return 0.0
        both = ~same & np.isfinite(a) & np.isfinite(b)
        return math.inf if (~same & ~both).any() else float(np.max(np.abs(a - b)[both]))

    for cols in source:
        n_all = len(cols["t"])
        contact = np.asarray(cols.get("contact", [math.nan] * n_all), dtype=float)
        idx = np.flatnonzero(contact == contact)  # the samples the blocks ran on
        if not idx.size:
            continue
        for k in need:
            if k not in cols:
                if not whole:  # it may come later in the recording: read it whole
                    raise SchemaChangeError(f"{path}: no {k!r} in a block")
                raise RecordingError(f"{path}: the recording has no {k!r} (recorded by an older version?)")

        def col(name: str, fill: float = math.nan, idx: Any = idx, n_all: int = n_all,
                cols: dict[str, Any] = cols) -> Any:
            return np.asarray(cols.get(name, [fill] * n_all), dtype=float)[idx]

        t = col("t")
        inputs = {k: col(k) for k in ("T_w", "T_p", "T_a")}
        v = col(v_name)
        fresh = np.nan_to_num(col("fresh", 7.0), nan=7.0).astype(np.int64)
        # the readings as the loop admitted them
        admitted = dict(zip(("T_w", "T_p", "T_a"), admit_arrays(lim, inputs["T_w"], inputs["T_p"],
                                                                inputs["T_a"]), strict=True))
        # the drive as the loop gave it to the estimator
        res, _ = est.feed(t, admitted["T_w"], admitted["T_p"], v, admitted["T_a"], T_w_cmd=col("T_w_cmd"),
                          fresh=fresh, drive=col(drive_name))
        q_live, dq_live, c_live = col("q_i_hat"), col("dq_i_hat"), col("contact")
        max_q = max(max_q, worst(res["q_i_hat"], q_live))
        max_dq = max(max_dq, worst(res["dq_i_hat"], dq_live))
        mism += int(np.sum(res["contact"] != c_live))
        samples += len(t)
        t_last = float(t[-1])
        yield {"t": t, "T_w": inputs["T_w"], "T_p": inputs["T_p"], "v": v, "T_a": inputs["T_a"],
               "q_i_hat": res["q_i_hat"], "dq_i_hat": res["dq_i_hat"], "contact": res["contact"],
               "gap": res["gap"], "q_i_hat_live": q_live, "dq_i_hat_live": dq_live, "contact_live": c_live}
    if not samples:
        raise RecordingError(f"{path}: no /skin/estimate messages to compare with")
    est.finish(t_last)
    if comparison is not None:
        comparison.update({"samples": samples, "q_i_hat_max_abs_diff": max_q,
                           "dq_i_hat_max_abs_diff": max_dq, "contact_mismatches": mism,
                           "exact": max_q == 0.0 and max_dq == 0.0 and mism == 0,
                           "agrees": max_q <= REPLAY_TOL_W and max_dq <= REPLAY_TOL_W and mism == 0,
                           "events": list(est.events)})
