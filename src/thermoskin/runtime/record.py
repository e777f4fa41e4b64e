"""Recording to MCAP (JSON-schema channels, viewable in Foxglove), reading back, export, replay.

Topics (messages are JSON objects; signal names and units of ``MODEL.md``)::

    /skin/sample    {t, T_w, T_p, T_a, v, drive, fresh, stale, stuck, status, seq}
    /skin/estimate  {t, q_i_hat, dq_i_hat, contact}
    /control        {t, T_p_cmd, drive, v_cmd}
    /events         {t, kind, detail}        contact onsets/releases, faults, link loss
    /params         {t, config}              the run's configuration, once at the start

Any other topic is accepted with a permissive schema. A message's ``log_time`` and
``publish_time`` are ``t`` in ns (the loop's clock; the wall-clock start of the recording
is in the ``thermoskin`` metadata record). NaN is written as JSON ``null`` (JSON has no
NaN) and read back as NaN.

Crash safety: the writer closes its chunk and hands it to the OS at least every
``flush_interval`` s (default 0.5 s) of writing, so a process that is killed loses at
most its last second. :func:`read_mcap` reads such a file without its summary and
footer (sequentially, with :class:`mcap.stream_reader.StreamReader`) and stops quietly
at the damaged tail.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import math
import os
import time
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import IO, Any

from mcap.records import Channel, Message, Schema
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer

from thermoskin.devices.base import Sample

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
        "properties": {"t": _NUM, "q_i_hat": _NUM_NULL, "dq_i_hat": _NUM_NULL, "contact": _INT},
        "required": ["t"],
    },
    "/control": {
        "title": "thermoskin.Control",
        "description": "controller outputs: T_p_cmd degC, drive in [-1, 1], v_cmd m/s",
        "type": "object",
        "properties": {"t": _NUM, "T_p_cmd": _NUM_NULL, "drive": _NUM_NULL, "v_cmd": _NUM_NULL},
        "required": ["t"],
    },
    "/events": {
        "title": "thermoskin.Event",
        "description": "contact events, faults, link loss",
        "type": "object",
        "properties": {"t": _NUM, "kind": {"type": "string"}, "detail": {}},
        "required": ["t", "kind"],
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


class RecordingError(ValueError):
    """A recording could not be read or exported (the message names the file and why)."""


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


class Recorder:
    """Write topics to an MCAP file with JSON-schema channels; crash-safe to ``flush_interval``.

    ``config`` (a :class:`~thermoskin.params.Config`, a JSON string or a mapping) is
    written once on ``/params``. Use as a context manager or call :meth:`close`.
    """

    def __init__(self, path: str | os.PathLike[str], config: Any = None, *,
                 flush_interval: float = 0.5, fsync: bool = False,
                 compression: str = "zstd") -> None:
        self.path = Path(path)
        self.flush_interval = float(flush_interval)
        self.fsync = bool(fsync)
        self.path.parent.mkdir(parents=True, exist_ok=True)
        comp = {"zstd": CompressionType.ZSTD, "lz4": CompressionType.LZ4,
                "none": CompressionType.NONE}.get(compression)
        if comp is None:
            raise ValueError(f"Recorder: compression {compression!r} must be zstd, lz4 or none")
        self._fh: IO[bytes] = open(self.path, "wb")  # noqa: SIM115 (closed in close())
        self._writer = Writer(self._fh, compression=comp)
        self._writer.start(profile="", library="thermoskin")
        self._writer.add_metadata("thermoskin", {
            "started": _dt.datetime.now(_dt.UTC).isoformat(),
            "time": "log_time = t (s) of the loop clock, in ns",
        })
        self._channels: dict[str, int] = {}
        self._seq: dict[str, int] = {}
        self._t_flush = time.monotonic()
        self.closed = False
        self.messages = 0
        self.write("/params", 0.0, {"config": _config_object(config)})
        self.flush()

    def _channel(self, topic: str) -> int:
        schema = TOPIC_SCHEMAS.get(topic, _ANY_SCHEMA)
        name = schema.get("title", topic.strip("/").replace("/", "."))
        sid = self._writer.register_schema(name=name, encoding="jsonschema",
                                           data=json.dumps(schema).encode())
        cid = self._writer.register_channel(topic=topic, message_encoding="json", schema_id=sid)
        self._channels[topic] = cid
        self._seq[topic] = 0
        return cid

    def write(self, topic: str, t: float, data: Mapping[str, Any]) -> None:
        """Record ``data`` (a flat mapping; ``t`` is added if absent) on ``topic`` at time ``t`` s."""
        if self.closed:
            raise RecordingError(f"{self.path}: write after close")
        cid = self._channels.get(topic)
        if cid is None:
            cid = self._channel(topic)
        obj = {"t": t}
        for k, v in data.items():
            obj[k] = _clean(v)
        if not math.isfinite(t):
            raise RecordingError(f"{self.path}: time t = {t} on {topic} is not finite")
        ns = max(0, round(t * 1e9))
        seq = self._seq[topic] = self._seq[topic] + 1
        self._writer.add_message(cid, ns, json.dumps(obj, separators=(",", ":")).encode(), ns, seq)
        self.messages += 1
        now = time.monotonic()
        if now - self._t_flush >= self.flush_interval:
            self.flush(now)

    def write_sample(self, s: Sample) -> None:
        """Record a device :class:`~thermoskin.devices.base.Sample` on ``/skin/sample``."""
        self.write("/skin/sample", s.t, s.as_dict())

    def event(self, t: float, kind: str, **detail: Any) -> None:
        """Record an event (``contact-on``, ``fault``, ``link-lost``, ...) on ``/events``."""
        self.write("/events", t, {"kind": kind, "detail": {k: _clean(v) for k, v in detail.items()}})

    def flush(self, now: float | None = None) -> None:
        """Close the chunk in progress and hand it to the OS (and the disk, with ``fsync``)."""
        self._writer.flush()
        if self.fsync:
            os.fsync(self._fh.fileno())
        self._t_flush = time.monotonic() if now is None else now

    def close(self) -> None:
        """Write the summary and footer, close the file."""
        if self.closed:
            return
        self.closed = True
        try:
            self._writer.finish()
        finally:
            self._fh.close()

    def __enter__(self) -> Recorder:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


# ----------------------------------------------------------------------------- reading

def iter_messages(path: str | os.PathLike[str], topics: Sequence[str] | None = None,
                  info: dict[str, Any] | None = None) -> Iterator[tuple[str, float, dict[str, Any]]]:
    """``(topic, t, message)`` in file order, tolerant to a truncated file.

    JSON ``null`` values come back as NaN. ``info`` (if given) receives ``complete``
    (footer read), ``truncated`` and ``error`` (why reading stopped).
    """
    p = Path(path)
    if not p.is_file():
        raise RecordingError(f"recording {p} does not exist")
    wanted = set(topics) if topics is not None else None
    if info is not None:
        info.update(complete=False, truncated=False, error="")
    schemas: dict[int, Schema] = {}
    channels: dict[int, Channel] = {}
    nan = math.nan
    with open(p, "rb") as fh:
        reader = StreamReader(fh, skip_magic=False)
        records = reader.records
        while True:
            try:
                rec = next(records)
            except StopIteration:
                if info is not None:
                    info["complete"] = True
                return
            except Exception as e:  # a killed writer leaves a partial record: McapError, struct, zstd
                if info is not None:
                    info["truncated"] = True
                    info["error"] = f"{type(e).__name__}: {e}"
                return
            if isinstance(rec, Message):
                ch = channels.get(rec.channel_id)
                if ch is None or (wanted is not None and ch.topic not in wanted):
                    continue
                try:
                    obj = json.loads(rec.data)
                except ValueError:
                    continue
                if isinstance(obj, dict):
                    for k, v in obj.items():
                        if v is None:
                            obj[k] = nan
                    yield ch.topic, float(obj.get("t", rec.log_time * 1e-9)), obj
            elif isinstance(rec, Channel):
                channels[rec.id] = rec
            elif isinstance(rec, Schema):
                schemas[rec.id] = rec


def read_mcap(path: str | os.PathLike[str], topics: Sequence[str] | None = None,
              info: dict[str, Any] | None = None) -> dict[str, list[dict[str, Any]]]:
    """Every message by topic, in file order (tolerant to truncation; see :func:`iter_messages`)."""
    p = Path(path)
    if not p.is_file():
        raise RecordingError(f"recording {p} does not exist")
    with open(p, "rb") as fh:
        if fh.read(8) != b"\x89MCAP0\r\n":
            raise RecordingError(f"{p} is not an MCAP file (bad magic)")
    out: dict[str, list[dict[str, Any]]] = {}
    for topic, _, obj in iter_messages(p, topics, info):
        out.setdefault(topic, []).append(obj)
    return out


# ----------------------------------------------------------------------------- export

MERGE_TOPICS = ("/skin/estimate", "/control")


def to_columns(path: str | os.PathLike[str], sample_topic: str = "/skin/sample",
               merge: Sequence[str] = MERGE_TOPICS) -> dict[str, list[float]]:
    """One row per sample of ``sample_topic``; numeric fields of ``merge`` topics joined by ``t``.

    A merged message belongs to the sample with the same ``t`` (to the µs); samples without
    one get NaN. A merged field whose name is already taken is named ``<topic leaf>.<field>``
    (``control.drive``: the commanded drive, next to ``drive``, the one the device applied).
    """
    data = read_mcap(path, [sample_topic, *merge])
    samples = data.get(sample_topic, [])
    if not samples:
        raise RecordingError(f"{path}: no messages on {sample_topic}")
    index = {round(s["t"] * 1e6): i for i, s in enumerate(samples)}
    n = len(samples)
    cols: dict[str, list[float]] = {}

    def add(name: str, i: int, value: Any) -> None:
        col = cols.get(name)
        if col is None:
            col = cols[name] = [math.nan] * n
        col[i] = float(value)

    for i, s in enumerate(samples):
        for k, v in s.items():
            if isinstance(v, int | float):
                add(k, i, v)
    base = set(cols)
    for topic in merge:
        leaf = topic.rstrip("/").rsplit("/", 1)[-1]
        for m in data.get(topic, []):
            t = m.get("t", math.nan)
            i = index.get(round(t * 1e6)) if isinstance(t, int | float) and math.isfinite(t) else None
            if i is None:
                continue
            for k, v in m.items():
                if k == "t" or not isinstance(v, int | float):
                    continue
                add(f"{leaf}.{k}" if k in base else k, i, v)
    return cols


def export(path_mcap: str | os.PathLike[str], out_path: str | os.PathLike[str], **kw: Any) -> Path:
    """Export a recording to ``.csv`` (:func:`thermoskin.logio.write_log`) or ``.parquet`` (pyarrow)."""
    out = Path(out_path)
    cols = to_columns(path_mcap, **kw)
    suffix = out.suffix.lower()
    if suffix == ".csv":
        from thermoskin.logio import write_log

        return write_log(out, cols)
    if suffix == ".parquet":
        try:
            import pyarrow as pa
            import pyarrow.parquet as pq
        except ImportError:
            raise RecordingError("export to .parquet needs pyarrow (pip install pyarrow); "
                                 "export to .csv works without it") from None
        out.parent.mkdir(parents=True, exist_ok=True)
        table = pa.table({k: pa.array(v, type=pa.float64()) for k, v in cols.items()})
        pq.write_table(table, out)
        return out
    raise RecordingError(f"cannot export to {out}: the extension must be .csv or .parquet")


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
