"""Property-based tests (``hypothesis``, issue 46): the protocol's encoder and decoder round trip
at every length and never raise on garbage; the log readers take CSV and Parquet logs with any
float width and integer type to the float64 values written, or refuse them with one
``LogError`` line, never another exception; the config, skin and sweep loaders give a valid
result or one ``ConfigError`` line for any TOML (and any bytes), never a traceback, a hang or
unbounded memory.

Hypothesis runs derandomized (the same examples on every run, no example database), and each
test's example count is set so that the file takes seconds.
"""

from __future__ import annotations

import copy
import dataclasses
import json
import math
import string
import struct
import tracemalloc
from pathlib import Path
from typing import Any

import numpy as np
import pyarrow as pa
import pyarrow.parquet as pq
import pytest
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from thermoskin.devices import protocol as proto
from thermoskin.logio import LogError, read_log
from thermoskin.params import _SECTION_TYPES, ConfigError, load_config, read_toml
from thermoskin.skin.layout import load_skin
from thermoskin.sweep.spec import load_sweep

ROOT = Path(__file__).resolve().parents[1]
FAST = settings(derandomize=True, database=None, deadline=None, max_examples=150,
                suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


def one_line(e: BaseException) -> None:
    msg = str(e)
    assert (msg and "\n" not in msg.strip()) or len(" ".join(msg.split())) < 2000, msg[:300]


# ----------------------------------------------------------------------------- the protocol

def test_cobs_round_trip_at_every_length() -> None:
    """Every length from 0 to 1100, each with no zero, a zero at its end, zeros every 254 and
    every 255 bytes, and a run of exactly 254 non-zero bytes before a zero (the code 0xFF,
    "254 bytes, no zero follows", must not eat that zero)."""
    for n in range(0, 1101):
        body = bytes((i % 255) + 1 for i in range(n))
        cases = [body]
        if n:
            cases.append(body[:-1] + b"\x00")
            cases.append(bytes(0 if i % 254 == 253 else b for i, b in enumerate(body)))
            cases.append(bytes(0 if i % 255 == 254 else b for i, b in enumerate(body)))
        if n > 255:
            cases.append(body[:254] + b"\x00" + body[255:])
        for data in cases:
            enc = proto.cobs_encode(data)
            assert b"\x00" not in enc
            assert proto.cobs_decode(enc) == data, (n, data.count(0))
            assert len(enc) <= len(data) + len(data) // 254 + 1


@FAST
@given(st.lists(st.tuples(st.integers(0, 600), st.integers(0, 3)), max_size=6))
def test_cobs_round_trip_of_runs(runs: list[tuple[int, int]]) -> None:
    """Runs of non-zero bytes of any length (across the 254 boundary) between runs of zeros."""
    data = b"".join(bytes((i * 7 % 255) + 1 for i in range(r)) + b"\x00" * z for r, z in runs)
    assert proto.cobs_decode(proto.cobs_encode(data)) == data


@FAST
@given(st.binary(max_size=2000))
def test_cobs_round_trip_of_any_bytes(data: bytes) -> None:
    enc = proto.cobs_encode(data)
    assert b"\x00" not in enc and proto.cobs_decode(enc) == data


U32 = st.integers(0, 2**32 - 1)
U16 = st.integers(0, 2**16 - 1)
F32 = st.floats(width=32, allow_nan=False)


MESSAGES = st.one_of(
    st.builds(proto.Hello, U32, U16, U32),
    st.builds(proto.HelloAck, U32, U16, U16, U32, U32, U32),
    st.builds(proto.SampleMsg, U32, st.integers(0, 2**64 - 1), F32, F32, F32, st.integers(0, 255), U16,
              st.tuples(U16, U16, U16), F32, F32, U32),
    st.builds(proto.Command, U32, F32, F32),
    st.builds(proto.Safe, U32, U16),
    st.builds(proto.Fault, U32, U16, st.integers(0, 255), F32),
)


@FAST
@given(st.lists(MESSAGES, min_size=1, max_size=8), st.lists(st.integers(1, 60), max_size=10))
def test_messages_round_trip_in_any_pieces(msgs: list[proto.Message], cuts: list[int]) -> None:
    """Messages encoded, concatenated, fed to the decoder in pieces of any size: the same
    messages (float32 fields exact), nothing counted as damaged."""
    stream = b"".join(proto.encode(m) for m in msgs)
    dec = proto.Decoder(check_seq=False)
    got: list[proto.Message] = []
    i = 0
    for c in [*cuts, len(stream)]:
        got += dec.feed(stream[i:i + c])
        i += c
    got += dec.feed(stream[i:])
    assert got == msgs
    assert dec.stats.corrupted == 0 and dec.stats.frames == len(msgs)


@FAST
@given(st.lists(st.one_of(st.binary(max_size=300), MESSAGES), max_size=12))
def test_decoder_never_raises_and_finds_the_frames_in_garbage(parts: list[bytes | proto.Message]) -> None:
    """Garbage and whole frames interleaved: no exception; every frame that follows a delimiter
    (so that garbage cannot run into it) is decoded."""
    dec = proto.Decoder(check_seq=False)
    stream = b""
    want = []
    for p in parts:
        if isinstance(p, bytes):
            stream += p
        else:
            stream += b"\x00" + proto.encode(p)
            want.append(p)
    got = dec.feed(stream)
    for m in want:
        assert m in got
    s = dec.stats
    assert s.frames == len(got)


# ----------------------------------------------------------------------------- the log readers

INT_TYPES = [np.int8, np.int16, np.int32, np.int64, np.uint8, np.uint16, np.uint32, np.uint64]
FLOAT_TYPES = [np.float16, np.float32, np.float64]


@st.composite
def typed_column(draw: Any, n: int) -> np.ndarray:
    dtype = draw(st.sampled_from([*INT_TYPES, *FLOAT_TYPES, np.bool_]))
    if dtype is np.bool_:
        return np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)), dtype=bool)
    if np.dtype(dtype).kind in "iu":
        info = np.iinfo(dtype)
        return np.array(draw(st.lists(st.integers(int(info.min), int(info.max)), min_size=n, max_size=n)),
                        dtype=dtype)
    width = {np.float16: 16, np.float32: 32, np.float64: 64}[dtype]
    vals = draw(st.lists(st.floats(width=width, allow_nan=True, allow_infinity=True), min_size=n, max_size=n))
    return np.array(vals, dtype=dtype)


def expect(cols: dict[str, np.ndarray]) -> str | None:
    """Why the reader must refuse these columns, or None: the rules of the logio module doc
    (NaN only in T_* and v; nothing infinite; t finite and uniform, strictly increasing)."""
    for name, c in cols.items():
        f = c.astype(np.float64)
        if np.isinf(f).any():
            return "inf"
        if np.isnan(f).any() and not (name.startswith("T_") or name == "v"):
            return "nan"
    return None


@st.composite
def log_columns(draw: Any) -> dict[str, np.ndarray]:
    n = draw(st.integers(2, 40))
    step = draw(st.sampled_from([1e-3, 1e-2, 0.02]))
    t_dtype = draw(st.sampled_from([np.float64, np.float32]))
    t = np.arange(n) * step
    fault = draw(st.sampled_from(["none", "none", "none", "repeat", "jump"]))
    if fault != "none":
        k = draw(st.integers(1, n - 1))
        t[k:] += -step if fault == "repeat" else 0.5 * step  # a repeated time, or a late row
    cols = {"t": t.astype(t_dtype)}
    for name in ("T_w", "T_p", "v", "T_a", draw(st.sampled_from(["drive", "contact", "T_w2"]))):
        cols[name] = draw(typed_column(n))
    return cols


def uniform_t(t: np.ndarray) -> bool:
    d = np.diff(t.astype(np.float64))
    return bool(np.all(d > 0) and np.all(np.abs(d - np.median(d)) <= 0.01 * np.median(d)))


@settings(FAST, max_examples=120)
@given(log_columns())
def test_parquet_logs_of_any_width_and_integer_type(tmp_path_factory: pytest.TempPathFactory,
                                                    cols: dict[str, np.ndarray]) -> None:
    """A Parquet log whose columns are any numeric type (and booleans): read as those values in
    float64, or refused with one LogError line (a NaN or an infinite value where not allowed)."""
    path = tmp_path_factory.mktemp("pq") / "x.parquet"
    pq.write_table(pa.table({k: pa.array(v) for k, v in cols.items()}), path)
    why = expect(cols) or (None if uniform_t(cols["t"]) else "t")
    event(f"refused: {why}" if why else "read")
    try:
        got = read_log(path)
    except LogError as e:
        one_line(e)
        assert why is not None, str(e)
        return
    assert why is None
    for k, v in cols.items():
        assert got[k].dtype == np.float64
        np.testing.assert_array_equal(got[k], v.astype(np.float64))


def _field(x: Any) -> str:
    if isinstance(x, np.bool_ | bool):
        return "1" if x else "0"
    if isinstance(x, np.integer):
        return str(int(x))
    f = float(x)
    return "NaN" if math.isnan(f) else repr(x.item() if hasattr(x, "item") else x) if not math.isinf(f) else (
        "inf" if f > 0 else "-inf")


@settings(FAST, max_examples=120)
@given(log_columns(), st.sampled_from(["repr", "%.17g", "%.6e", "spaces"]))
def test_csv_logs_of_any_width_and_integer_type(tmp_path_factory: pytest.TempPathFactory,
                                                cols: dict[str, np.ndarray], style: str) -> None:
    """A CSV log of the same columns, each value written as its own type prints it (float16 and
    float32 values in their shortest form, integers whole, in four styles): the float64 of each
    field's text, or one LogError line."""
    path = tmp_path_factory.mktemp("csv") / "x.csv"
    names = list(cols)
    rows = []
    for i in range(len(cols["t"])):
        fields = []
        for k in names:
            x = cols[k][i]
            text = _field(x)
            if style == "%.17g" and np.asarray(x).dtype.kind == "f" and math.isfinite(float(x)):
                text = f"{float(x):.17g}"
            elif style == "%.6e" and np.asarray(x).dtype.kind == "f" and math.isfinite(float(x)) and k != "t":
                text = f"{float(x):.6e}"
            elif style == "spaces":
                text = f" {text} "
            fields.append(text)
        rows.append(",".join(fields))
    path.write_text(",".join(names) + "\n" + "\n".join(rows) + "\n")
    parsed = {k: np.array([float(r.split(",")[j].strip()) for r in rows]) for j, k in enumerate(names)}
    why = expect(parsed) or (None if uniform_t(parsed["t"]) else "t")
    event(f"refused: {why}" if why else "read")
    try:
        got = read_log(path)
    except LogError as e:
        one_line(e)
        assert why is not None, str(e)
        return
    assert why is None, why
    for k in names:
        np.testing.assert_array_equal(got[k], parsed[k])


@settings(FAST, max_examples=150)
@given(st.binary(max_size=3000), st.sampled_from([".csv", ".parquet"]))
def test_any_bytes_as_a_log(tmp_path_factory: pytest.TempPathFactory, data: bytes, suffix: str) -> None:
    """Any bytes given as a log: a log, or one LogError line; never another exception."""
    path = tmp_path_factory.mktemp("bytes") / f"x{suffix}"
    path.write_bytes(data)
    try:
        read_log(path, required=("t",))
    except LogError as e:
        one_line(e)


@settings(FAST, max_examples=80)
@given(st.integers(1, 64), st.integers(0, 40), st.sampled_from([b"1", b"1.5e-3", b"x", b'"a,b"']))
def test_csv_memory_before_an_error_is_bounded(tmp_path_factory: pytest.TempPathFactory, kb: int,
                                               ncols: int, word: bytes) -> None:
    """A data line of up to 64 KiB more than a row can be (any field, any count): its error
    comes with a peak allocation of a few times the line, never the field count times a field
    object (a 40 MB line took 7 GB)."""
    path = tmp_path_factory.mktemp("long") / "x.csv"
    line = b",".join([word] * (kb * 1024 // (len(word) + 1) + ncols + 70_000))
    path.write_bytes(b"t,T_w,T_p,v,T_a\n0,1,1,1,1\n" + line + b"\n")
    tracemalloc.start()
    try:
        with pytest.raises(LogError) as exc:
            read_log(path)
        peak = tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()
    one_line(exc.value)
    assert "longer than a row" in str(exc.value)
    assert peak < 40 * len(line) + (8 << 20), (peak, len(line))


# ----------------------------------------------------------------------------- the TOML loaders

def toml_value(x: Any) -> str:
    if isinstance(x, bool):
        return "true" if x else "false"
    if isinstance(x, int):
        return str(x)
    if isinstance(x, float):
        return "nan" if math.isnan(x) else ("inf" if x > 0 else "-inf") if math.isinf(x) else repr(x)
    if isinstance(x, str):
        return json.dumps(x)
    if isinstance(x, list):
        return "[" + ", ".join(toml_value(v) for v in x) + "]"
    return "{" + ", ".join(f"{json.dumps(k)} = {toml_value(v)}" for k, v in x.items()) + "}"


def toml_text(data: dict[str, Any]) -> str:
    """``data`` as TOML: scalars and lists at the top, then one table per dict (inline below it)."""
    head, tables = [], []
    for k, v in data.items():
        if isinstance(v, dict):
            tables.append(f"[{json.dumps(k)}]")
            tables += [f"{json.dumps(kk)} = {toml_value(vv)}" for kk, vv in v.items()]
        else:
            head.append(f"{json.dumps(k)} = {toml_value(v)}")
    return "\n".join(head + tables) + "\n"


SCALARS = st.one_of(st.booleans(), st.integers(-10**6, 10**6), st.floats(allow_nan=True),
                    st.text(string.printable, max_size=12))
KEYS = st.text(string.ascii_letters, min_size=1, max_size=6)
VALUES = st.recursive(SCALARS, lambda inner: st.one_of(st.lists(inner, max_size=4),
                                                        st.dictionaries(KEYS, inner, max_size=4)),
                      max_leaves=12)

CONFIG_KEYS = {name: [f.name for f in dataclasses.fields(cls)] for name, cls in _SECTION_TYPES.items()}


@st.composite
def configs(draw: Any) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for _ in range(draw(st.integers(0, 4))):
        section = draw(st.sampled_from([*CONFIG_KEYS, "bogus"]))
        keys = CONFIG_KEYS.get(section, ["x"])
        out[section] = {draw(st.sampled_from([*keys, "nope"])): draw(VALUES)
                        for _ in range(draw(st.integers(0, 3)))}
    return out


def loads(tmp: Path, text: str | bytes, loader: Any) -> None:
    f = tmp / "x.toml"
    f.write_bytes(text if isinstance(text, bytes) else text.encode())
    try:
        loader(f)
        event(f"{loader.__name__}: loaded")
    except ConfigError as e:
        one_line(e)
        event(f"{loader.__name__}: refused")


@settings(FAST, max_examples=200)
@given(configs())
def test_config_loader(tmp_path_factory: pytest.TempPathFactory, data: dict[str, Any]) -> None:
    loads(tmp_path_factory.mktemp("cfg"), toml_text(data), load_config)


def _paths(x: Any, prefix: tuple = ()) -> list[tuple]:
    out = [prefix]
    if isinstance(x, dict):
        for k, v in x.items():
            out += _paths(v, (*prefix, k))
    elif isinstance(x, list):
        for i, v in enumerate(x):
            out += _paths(v, (*prefix, i))
    return out


def _mutated(base: dict[str, Any], draw: Any) -> dict[str, Any]:
    """``base`` with up to three of its values (at any depth) replaced by any value, or deleted."""
    data = copy.deepcopy(base)
    for _ in range(draw(st.integers(1, 3))):
        paths = [p for p in _paths(data) if p]
        if not paths:
            break
        path = draw(st.sampled_from(paths))
        parent = data
        for k in path[:-1]:
            parent = parent[k]
        if draw(st.booleans()) and isinstance(parent, dict):
            del parent[path[-1]]
        else:
            parent[path[-1]] = draw(VALUES)
    return data


FOREARM = read_toml(ROOT / "examples" / "forearm.toml", "skin")
SWEEP = read_toml(ROOT / "examples" / "sweep-small.toml", "sweep")


def _nested_text(data: dict[str, Any]) -> str:
    """``data`` (tables of tables) as TOML with dotted table headers where a table holds tables."""
    lines: list[str] = []

    def table(path: list[str], d: dict[str, Any]) -> None:
        scalars = {k: v for k, v in d.items() if not (isinstance(v, dict) and v and all(
            isinstance(x, dict) for x in v.values()))}
        if path:
            lines.append("[" + ".".join(json.dumps(p) for p in path) + "]")
        lines.extend(f"{json.dumps(k)} = {toml_value(v)}" for k, v in scalars.items())
        for k, v in d.items():
            if k not in scalars:
                table([*path, k], v)

    table([], data)
    return "\n".join(lines) + "\n"


@settings(FAST, max_examples=120)
@given(st.data())
def test_skin_loader(tmp_path_factory: pytest.TempPathFactory, data: st.DataObject) -> None:
    """The forearm's description with values replaced by anything, or deleted: a skin or one line."""
    loads(tmp_path_factory.mktemp("skin"), _nested_text(_mutated(FOREARM, data.draw)), load_skin)


@settings(FAST, max_examples=120)
@given(st.data())
def test_sweep_loader(tmp_path_factory: pytest.TempPathFactory, data: st.DataObject) -> None:
    """The small sweep's file with values replaced by anything, or deleted: a sweep or one line
    (points limited where a replaced count would ask for a million configurations)."""
    d = _mutated(SWEEP, data.draw)
    sw = d.get("sweep")
    if isinstance(sw, dict) and isinstance(sw.get("points"), int) and sw["points"] > 1000:
        sw["points"] = 1000
    loads(tmp_path_factory.mktemp("sweep"), _nested_text(d), load_sweep)


@settings(FAST, max_examples=150)
@given(st.binary(max_size=2000))
def test_any_bytes_as_toml(tmp_path_factory: pytest.TempPathFactory, data: bytes) -> None:
    tmp = tmp_path_factory.mktemp("bytes")
    for loader in (load_config, load_skin, load_sweep):
        loads(tmp, data, loader)


@settings(FAST, max_examples=60)
@given(st.integers(33, 3000), st.sampled_from(["[", "{a = "]),
       st.sampled_from(["a = ", '"k" = ', "[t]\nx = "]))
def test_deep_toml_is_one_line(tmp_path_factory: pytest.TempPathFactory, depth: int, opener: str,
                               head: str) -> None:
    closer = {"[": "]", "{a = ": "}"}[opener]
    text = head + opener * depth + "1" + closer * depth + "\n"
    tmp = tmp_path_factory.mktemp("deep")
    for loader in (load_config, load_skin, load_sweep):
        f = tmp / "x.toml"
        f.write_text(text)
        with pytest.raises(ConfigError, match="nested more than 32 deep"):
            loader(f)


def test_struct_sizes_of_the_protocol() -> None:
    """The packet sizes the decoder bounds are the body sizes of the messages (an independent
    count of their fields' bytes: u8 type, u32 seq, body, u16 crc)."""
    sizes = {"Hello": 2 + 4, "HelloAck": 2 + 2 + 4 + 4 + 4, "Command": 4 + 4, "Safe": 2, "Fault": 2 + 1 + 4,
             "SampleMsg": 8 + 3 * 4 + 1 + 2 + 3 * 2 + 4 + 4 + 4}
    for name, n in sizes.items():
        assert getattr(proto, name).BODY.size == n
        assert struct.calcsize("<BI") + n + 2 <= proto.MAX_PACKET
