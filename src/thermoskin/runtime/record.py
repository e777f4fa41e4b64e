"""Recording to MCAP (JSON-schema channels, viewable in Foxglove), reading back, export, replay.

Topics (messages are JSON objects; signal names and units of ``MODEL.md``)::

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

MERGE_TOPICS = ("/skin/estimate", "/control", "/sim/truth", "/loop/timing")


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
        """One block of rows as columns (arrays of equal length)."""
        t = c["t"].tolist()
        n = len(t)
        if not n:
            return
        L = {k: (v.tolist() if hasattr(v, "tolist") else list(v)) for k, v in c.items()}
        nan = [math.nan] * n
        T_w, T_p, T_a = L["T_w"], L["T_p"], L["T_a"]
        v_cmd, drive, T_w_cmd, T_p_cmd = L["v"], L["drive"], L["T_w_cmd"], L["T_p_cmd"]
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


def replay(path: str | os.PathLike[str], config: Any = None) -> tuple[dict[str, Any], dict[str, Any]]:
    """Re-run the observer and the detector on a recording; ``(columns, comparison)``.

    The blocks get the inputs the live loop gave them: ``t, T_w, T_p, T_a`` of
    ``/skin/sample`` and the ``v_cmd`` of ``/control`` (the pump command the observer
    used), on every sample that has an ``/skin/estimate`` (the samples the blocks ran
    on), with the recorded configuration (or ``config``). ``columns`` holds those inputs,
    the replayed ``q_i_hat, dq_i_hat, contact, gap`` and the live ones as ``*_live``;
    ``comparison`` the largest differences and the count of contact mismatches.
    """
    from thermoskin.estimator import TouchEstimator

    if config is None:
        params = read_mcap(path, ["/params"]).get("/params", [])
        if not params:
            raise RecordingError(f"{path}: no /params message; pass the configuration")
        config = config_from_params(params[0].get("config", {}))
    cols = to_columns(path)
    n_all = len(cols["t"])
    c_col = cols.get("contact", [math.nan] * n_all)
    stepped = [i for i in range(n_all) if c_col[i] == c_col[i]]
    if not stepped:
        raise RecordingError(f"{path}: no /skin/estimate messages to compare with")
    need = ("T_w", "T_p", "T_a", "v_cmd")
    for k in need:
        if k not in cols:
            raise RecordingError(f"{path}: the recording has no {k!r} (recorded by an older version?)")
    est = TouchEstimator(config)
    out: dict[str, list[float]] = {k: [] for k in ("t", "T_w", "T_p", "v", "T_a", "q_i_hat", "dq_i_hat",
                                                   "contact", "gap", "q_i_hat_live", "dq_i_hat_live",
                                                   "contact_live")}
    T_w, T_p, T_a, v, t = cols["T_w"], cols["T_p"], cols["T_a"], cols["v_cmd"], cols["t"]
    cmd = cols.get("T_w_cmd", [math.nan] * n_all)
    fresh = [7 if f != f else int(f) for f in cols.get("fresh", [7.0] * n_all)]
    q_live, dq_live, c_live = cols["q_i_hat"], cols["dq_i_hat"], cols["contact"]
    max_q = max_dq = 0.0
    mism = 0

    def diff(a: float, b: float, worst: float) -> float:
        if a == b or (a != a and b != b):
            return worst
        return max(worst, abs(a - b)) if a == a and b == b else math.inf

    for i in stepped:
        c = est.step(t[i], T_w[i], T_p[i], v[i], T_a[i], cmd[i], fresh[i])
        q, dq = est.q_i_hat, est.dq_i_hat
        for k, x in (("t", t[i]), ("T_w", T_w[i]), ("T_p", T_p[i]), ("v", v[i]), ("T_a", T_a[i]),
                     ("q_i_hat", q), ("dq_i_hat", dq), ("contact", c), ("gap", int(est.gap)),
                     ("q_i_hat_live", q_live[i]), ("dq_i_hat_live", dq_live[i]),
                     ("contact_live", c_live[i])):
            out[k].append(x)
        max_q = diff(q, q_live[i], max_q)
        max_dq = diff(dq, dq_live[i], max_dq)
        if c != c_live[i]:
            mism += 1
    est.finish(t[stepped[-1]])
    comparison = {"samples": len(stepped), "q_i_hat_max_abs_diff": max_q,
                  "dq_i_hat_max_abs_diff": max_dq, "contact_mismatches": mism,
                  "exact": max_q == 0.0 and max_dq == 0.0 and mism == 0, "events": list(est.events)}
    return out, comparison
