"""A recording as ROS 2 messages: ``thermoskin export RUN.mcap --ros2 -o OUT.mcap``.

Every message of the JSON recording (:mod:`~thermoskin.runtime.record`) is re-encoded as
a ROS 2 message: CDR payloads (``message_encoding = "cdr"``), the message definitions in
``.msg`` text embedded as the channels' schemas (``encoding = "ros2msg"``, with their
dependencies, as ``rosbag2`` writes them), the MCAP ``ros2`` profile; no ROS install
needed. Foxglove and Lichtblick decode it from the embedded schemas, as ``rosbags`` does
(tested); ``ros2 bag play`` publishes the ``thermoskin_msgs`` types where a package built
from :func:`msg_text` is installed.

**The encoder.** CDR is written by one precompiled :class:`struct.Struct` per type
(:class:`RosType`), the file by the ``mcap`` library's writer. ``mcap-ros2-support``'s
generic encoder writes the same bytes (the tests check it) but made the export of a 60 s
recording 2.5-3.5x slower (6.0-8.7 s against 2.2-2.4 s, ``benchmarks/ros2_export.py``); it
is the tests' reference, with its decoder and ``rosbags``'.

**The message types.** The signal topics are custom types whose fields mirror the JSON
schemas of :data:`~thermoskin.runtime.record.TOPIC_SCHEMAS` one for one, so a plot path
reads as the model's names (``/skin/estimate.q_i_hat``) and one JSON message is one ROS 2
message. No standard type fits these records: ``std_msgs/Float64MultiArray`` loses the
names, ``sensor_msgs/Temperature`` carries one reading. ``/events`` is
``thermoskin_msgs/msg/Event``: ``kind`` a field of its own (a message-path filter selects
``/events{kind=="contact"}``), ``detail`` (an object whose keys depend on the kind) as JSON
text. ``/params`` (a nested document that follows every change of ``params.py``) and any
topic not listed here are ``std_msgs/msg/String`` holding the recorded JSON message
verbatim.

**The mapping.**

- Field names are the JSON names in lower case (ROS 2 allows no capitals): ``T_w`` is
  ``t_w``, ``T_w_cmd`` ``t_w_cmd``. No two names of a message collide.
- Every custom message starts with a ``std_msgs/Header``: ``stamp`` is the message's log
  time (the loop clock, 0 at the run's start: stamps and log times lie in 1970, as in the
  recording), ``frame_id`` empty. ``float64 t`` keeps the recorded ``t`` exactly.
- Numbers are ``float64``; a JSON ``null`` (the recording's NaN) or an absent field is NaN.
- Integers: channel bit masks and 0/1 flags ``uint8``; ``status`` ``uint16`` and ``seq``
  ``uint32``, the serial protocol's widths (``docs/protocol.md``). An absent or null integer
  is 0, as the replay reads it.
- Each message keeps its log time, publish time and sequence number; the order is the
  recording's.

A damaged or cut-off recording is exported from every intact part, as
:func:`~thermoskin.runtime.record.export` does (``info`` receives the report).
"""

from __future__ import annotations

import json
import math
import os
import struct
from collections.abc import Mapping
from pathlib import Path
from typing import Any

from thermoskin.runtime.record import RecordingError, scan_messages

#: A field: (JSON key, ROS field name, type, comment). Type ``json`` is a ``string`` holding
#: the JSON value as text.
Field = tuple[str, str, str, str]

_TIME = "float64", "s, loop clock: the recorded t (the stamp is the log time, in ns)"

#: topic -> (ROS 2 type, what a message is, fields after the header)
MESSAGES: dict[str, tuple[str, str, tuple[Field, ...]]] = {
    "/skin/sample": ("thermoskin_msgs/msg/Sample",
                     "One device sample: what the device sent. NaN: no reading.", (
        ("t", "t", *_TIME),
        ("T_w", "t_w", "float64", "degC, water in the pipe (T_w)"),
        ("T_p", "t_p", "float64", "degC, Peltier tank (T_p)"),
        ("T_a", "t_a", "float64", "degC, ambient air (T_a)"),
        ("v", "v", "float64", "m/s, flow speed applied by the device"),
        ("drive", "drive", "float64", "Peltier drive applied by the device, [-1, 1]"),
        ("fresh", "fresh", "uint8", "channels with a new reading: bits 1 T_w, 2 T_p, 4 T_a"),
        ("stale", "stale", "uint8", "channels without a new reading for too long (same bits)"),
        ("stuck", "stuck", "uint8", "channels repeating one reading (same bits)"),
        ("status", "status", "uint16", "the device's ST_* status bits"),
        ("seq", "seq", "uint32", "the device's frame number"),
    )),
    "/skin/estimate": ("thermoskin_msgs/msg/Estimate",
                       "Thermal exchange observer (eq. 8) and contact detector.", (
        ("t", "t", *_TIME),
        ("q_i_hat", "q_i_hat", "float64", "W, estimated heat flow of the touch (eq. 8)"),
        ("dq_i_hat", "dq_i_hat", "float64", "W, its change from the no-touch value"),
        ("contact", "contact", "uint8", "1 while a contact is detected"),
        ("gap", "gap", "uint8", "1 where a NaN sample was held over"),
    )),
    "/control": ("thermoskin_msgs/msg/Control", "Commands of the loop.", (
        ("t", "t", *_TIME),
        ("T_w_cmd", "t_w_cmd", "float64", "degC, set-point of the pipe water"),
        ("T_p_cmd", "t_p_cmd", "float64", "degC, tank temperature commanded by the MPC (eqs. 9-11)"),
        ("drive", "drive", "float64", "Peltier drive commanded by the inner loop, [-1, 1]"),
        ("v_cmd", "v_cmd", "float64", "m/s, pump command (the v the observer used)"),
    )),
    "/sim/truth": ("thermoskin_msgs/msg/Truth", "The simulator's truth (simulated skin only).", (
        ("t", "t", *_TIME),
        ("q_i", "q_i", "float64", "W, true heat flow of the touch"),
        ("T_g", "t_g", "float64", "degC, graphite sheet (T_g)"),
        ("T_w_true", "t_w_true", "float64", "degC, pipe water, true (no sensor)"),
        ("T_p_true", "t_p_true", "float64", "degC, tank, true (no sensor)"),
        ("contact_true", "contact_true", "uint8", "1 while a finger touches"),
        ("n_fingers", "n_fingers", "uint8", "fingers touching"),
    )),
    "/loop/timing": ("thermoskin_msgs/msg/LoopTiming", "The fixed-rate loop's timing of one step.", (
        ("t", "t", *_TIME),
        ("late", "late", "float64", "s, lateness of the step against its deadline"),
        ("lag", "lag", "float64", "s, the host's part of the lateness"),
        ("busy", "busy", "float64", "s, time the step took"),
    )),
    "/events": ("thermoskin_msgs/msg/Event", "A run event: start, contact, fault, link loss, end.", (
        ("t", "t", *_TIME),
        ("kind", "kind", "string", "run-start, contact-on, contact-off, contact, fault, run-end, ..."),
        ("detail", "detail", "json", "the event's figures, a JSON object (empty: none)"),
    )),
}
STRING_TYPE = "std_msgs/msg/String"  # /params and any other topic: the recorded JSON, verbatim

_SEP = "=" * 80
_HEADER_DEFS = (f"{_SEP}\nMSG: std_msgs/Header\n# Standard metadata for higher-level stamped data types.\n"
                f"builtin_interfaces/Time stamp\nstring frame_id\n"
                f"{_SEP}\nMSG: builtin_interfaces/Time\nint32 sec\nuint32 nanosec\n")
_INT_MAX = {"uint8": 0xFF, "uint16": 0xFFFF, "uint32": 0xFFFF_FFFF}
_PRIM = {"float64": "d", "int32": "i", "uint32": "I", "uint16": "H", "uint8": "B"}  # struct codes
_CDR_LE = b"\x00\x01\x00\x00"  # CDR encapsulation header: plain CDR, little-endian
_NS = 1_000_000_000
_FLOAT_MAX = 1.7976931348623157e308


def msg_text(datatype: str) -> str:
    """The ``.msg`` file of one of our types (``thermoskin_msgs/msg/Sample``, ...)."""
    for dt, doc, fields in MESSAGES.values():
        if dt == datatype:
            lines = [f"# {doc}", "", "std_msgs/Header header  # stamp: the log time"]
            for _, name, typ, comment in fields:
                lines.append(f"{'string' if typ == 'json' else typ} {name}  # {comment}")
            return "\n".join(lines) + "\n"
    if datatype == STRING_TYPE:
        return "string data\n"
    raise KeyError(datatype)


def schema_text(datatype: str) -> str:
    """The ``ros2msg`` schema of ``datatype``: its ``.msg`` text and its dependencies'."""
    text = msg_text(datatype)
    return text if datatype == STRING_TYPE else text + _HEADER_DEFS


def _bad(path: Path | str, topic: str, ns: int, what: str) -> RecordingError:
    return RecordingError(f"{path}: {topic} at t = {ns / _NS:.3f} s: {what}")


def _json(v: Any) -> str:
    return json.dumps(v, separators=(",", ":"), ensure_ascii=False)


class RosType:
    """The CDR encoder of one message type of :data:`MESSAGES` (or ``std_msgs/msg/String``).

    CDR (XCDR1, little-endian, as ROS 2's middlewares write it): a 4-byte encapsulation
    header ``00 01 00 00``, then each field at an offset (counted after the header) that
    is a multiple of its size, strings as ``uint32`` length (NUL included), bytes, NUL.
    A type of fixed-size fields (the header's ``frame_id`` is always empty) is one
    precompiled :class:`struct.Struct`; the tests check every encoding byte for byte against
    ``mcap-ros2-support``'s encoder and decode it with its decoder and with ``rosbags``.
    """

    def __init__(self, name: str, fields: tuple[Field, ...], header: bool = True) -> None:
        self.name, self.fields, self.header = name, fields, header
        self.keys = tuple(f[0] for f in fields)
        self.known = frozenset(self.keys)
        kinds = [f[2] for f in fields]
        self.fixed: struct.Struct | None = None
        if header and all(k in _PRIM for k in kinds):  # header (stamp, frame_id ""), then the fields
            fmt, off = ["<4s"], 0
            for code in ("i", "I", "I", "x", *(_PRIM[k] for k in kinds)):
                size = struct.calcsize(code)
                if code != "x" and off % size:
                    fmt.append(f"{size - off % size}x")
                    off += size - off % size
                fmt.append(code)
                off += size
            self.fixed = struct.Struct("".join(fmt))

    def encode(self, obj: Mapping[str, Any], ns: int, where: tuple[Path | str, str] = ("", "")) -> bytes:
        """The CDR payload of the JSON message ``obj`` logged at ``ns`` (the header's stamp).

        ``where`` (file, topic) names the message in an error.
        """
        sec, nsec = divmod(ns, _NS)
        fixed = self.fixed
        if fixed is not None:
            try:  # the JSON values as they are (no NaN, no absent field): most messages
                g = obj.get
                return fixed.pack(_CDR_LE, sec, nsec, 1, *[g(k) for k in self.keys])
            except (struct.error, OverflowError):
                pass
        if self.header and sec > 0x7FFF_FFFF:
            raise _bad(*where, ns, "the log time does not fit a ROS 2 time stamp (int32 s)")
        values = self.values(obj, ns, where)
        if fixed is not None:
            return fixed.pack(_CDR_LE, sec, nsec, 1, *values)
        b = bytearray(_CDR_LE)
        head = (("int32", sec), ("uint32", nsec), ("string", "")) if self.header else ()
        for kind, v in (*head, *zip((f[2] for f in self.fields), values, strict=True)):
            if kind in _PRIM:
                code = _PRIM[kind]
                b += bytes(-(len(b) - 4) % struct.calcsize(code))
                b += struct.pack("<" + code, v)
            else:
                data = v.encode("utf-8") + b"\0"
                b += bytes(-(len(b) - 4) % 4)
                b += struct.pack("<I", len(data))
                b += data
        return bytes(b)

    def values(self, obj: Mapping[str, Any], ns: int, where: tuple[Path | str, str] = ("", "")) -> list[Any]:
        """The fields' values in the message's order: null or absent numbers NaN, integers 0."""
        out: list[Any] = []
        for key, _, kind, _ in self.fields:
            v = obj.get(key)
            if kind == "float64":
                if v is None:
                    v = math.nan
                elif not isinstance(v, int | float) or (isinstance(v, int) and abs(v) > _FLOAT_MAX):
                    raise _bad(*where, ns, f"{key} = {v!r:.40} is not a number (float64)")
                v = float(v)
            elif kind == "string":
                v = "" if v is None else v if isinstance(v, str) else _json(v)
            elif kind == "json":
                v = "" if v is None else _json(v)
            elif v is None or (isinstance(v, float) and math.isnan(v)):
                v = 0
            elif (not isinstance(v, int | float) or not math.isfinite(v) or v != int(v)
                  or not 0 <= v <= _INT_MAX[kind]):
                raise _bad(*where, ns, f"{key} = {v!r} is not an integer in [0, {_INT_MAX[kind]}] ({kind})")
            else:
                v = int(v)
            out.append(v)
        return out


#: topic -> its encoder; any other topic is :data:`STRING`
ROS_TYPES: dict[str, RosType] = {topic: RosType(name, fields)
                                 for topic, (name, _, fields) in MESSAGES.items()}
STRING = RosType(STRING_TYPE, (("data", "data", "string", "the recorded JSON message"),), header=False)


def _check_output(src: Path, out: Path) -> None:
    if out.suffix.lower() != ".mcap":
        raise RecordingError(f"cannot export to {out}: with --ros2 the extension must be .mcap")
    if out.is_dir():
        raise RecordingError(f"cannot export to {out}: it is a directory")
    if out.exists() and src.exists() and os.path.samefile(src, out):
        raise RecordingError(f"cannot export to {out}: it is the recording itself")


def export_ros2(path_mcap: str | os.PathLike[str], out_path: str | os.PathLike[str],
                info: dict[str, Any] | None = None) -> Path:
    """Write the recording ``path_mcap`` as ROS 2 messages to ``out_path`` (``.mcap``).

    Written to a temporary file beside ``out_path`` and renamed when complete. ``info``
    (as in :func:`~thermoskin.runtime.record.iter_messages`) receives the reading's
    ``report`` and ``warnings``: one line if some JSON fields have no place in the
    messages (a recording from another version), naming them.
    """
    from mcap.writer import CompressionType, Writer

    src, out = Path(path_mcap), Path(out_path)
    _check_output(src, out)
    sc = scan_messages(src, publish_time=True)
    if info is not None:
        info.update(complete=False, truncated=False, error="", report=sc.report, warnings=[])
    out.parent.mkdir(parents=True, exist_ok=True)
    tmp = out.with_name(f".{out.name}.tmp")
    left_out: set[str] = set()
    n = 0
    try:
        with open(tmp, "wb") as fh:
            w = Writer(fh, chunk_size=1 << 20, compression=CompressionType.ZSTD)
            w.start(profile="ros2", library="thermoskin (mcap-python)")
            w.add_metadata("thermoskin", {
                "source": src.name,
                "time": "log_time = publish_time = header.stamp = t (s) of the loop clock, in ns",
            })
            schemas: dict[str, int] = {}
            channels: dict[str, tuple[int, RosType]] = {}
            for batch in sc.batches():
                try:  # a chunk's messages in one call
                    objs = json.loads(b"[" + b",".join([m[3] for m in batch]) + b"]")
                    if len(objs) != len(batch):
                        raise ValueError("not one value per message")
                except ValueError:
                    objs = [_loads(src, m) for m in batch]
                for (topic, seq, ns, payload, pub), obj in zip(batch, objs, strict=True):
                    ch = channels.get(topic)
                    if ch is None:
                        rt = ROS_TYPES.get(topic, STRING)
                        sid = schemas.get(rt.name)
                        if sid is None:
                            sid = schemas[rt.name] = w.register_schema(
                                rt.name, "ros2msg", schema_text(rt.name).encode())
                        ch = channels[topic] = w.register_channel(topic, "cdr", sid), rt
                    cid, rt = ch
                    if rt is STRING:
                        try:
                            obj = {"data": payload.decode("utf-8")}
                        except UnicodeDecodeError:
                            raise _bad(src, topic, ns, "the message is not UTF-8 JSON") from None
                    elif not isinstance(obj, dict):
                        raise _bad(src, topic, ns, "the message is not a JSON object")
                    elif not obj.keys() <= rt.known:
                        left_out.update(f"{topic}.{k}" for k in obj if k not in rt.known)
                    w.add_message(cid, ns, rt.encode(obj, ns, (src, topic)), pub, seq)
                    n += 1
            w.finish()
        if not n:
            raise RecordingError(f"{src}: no messages to export")
        os.replace(tmp, out)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    rep = sc.report
    if info is not None:
        info.update(complete=rep.complete, truncated=not rep.complete, error=rep.error)
        if left_out:
            info["warnings"].append(f"fields with no place in the ROS 2 messages were left out: "
                                    f"{', '.join(sorted(left_out))}")
    return out


def _loads(src: Path, m: tuple[Any, ...]) -> Any:
    try:
        return json.loads(m[3])
    except ValueError:
        raise _bad(src, m[0], m[2], "the message is not JSON (not a thermoskin recording?)") from None
