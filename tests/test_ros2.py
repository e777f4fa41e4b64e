"""`thermoskin export --ros2`: a recording as ROS 2 messages (CDR, ros2msg schemas).

The exported files are read back with `mcap-ros2-support`'s decoder and with `rosbags`
(two implementations of ROS 2's CDR and .msg parsing, neither ours) and compared with the
JSON recording as the `mcap` library reads it, message by message.
"""

from __future__ import annotations

import json
import math
import re
from collections import Counter
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from click.testing import CliRunner
from mcap.reader import make_reader
from mcap_ros2.decoder import DecoderFactory

from thermoskin.cli import main
from thermoskin.params import Config
from thermoskin.runtime.realtime import ROW
from thermoskin.runtime.record import TOPIC_SCHEMAS, LoopRecorder, Recorder, read_mcap
from thermoskin.runtime.ros2 import MESSAGES, ROS_TYPES, STRING, export_ros2, schema_text

N = 1500  # rows of the synthetic recording


def invoke(*args: str) -> tuple[int, str, str]:
    res = CliRunner().invoke(main, list(args))
    return res.exit_code, res.stdout, res.stderr


def loop_rows(n: int, seed: int = 3) -> dict[str, np.ndarray]:
    """Every column of the fixed-rate loop's rows, with NaN readings, contacts, a fault row."""
    rng = np.random.default_rng(seed)
    late = ("v_cmd", "drive_cmd")  # fields added later: drawn after the others (the same stream)
    c = {k: rng.normal(24.0, 2.0, n) for k in ROW if k not in late}
    c["t"] = np.arange(n) * 1e-3
    for k in ("contact", "gap", "contact_true"):
        c[k] = (rng.random(n) < 0.3).astype(float)
    c["n_fingers"] = rng.integers(0, 4, n).astype(float)
    c["fresh"] = rng.integers(0, 8, n).astype(float)
    c["stale"] = rng.integers(0, 8, n).astype(float)
    c["stuck"] = rng.integers(0, 8, n).astype(float)
    c["status"] = rng.choice([0, 0x10, 0xFFFF], n).astype(float)
    c["seq"] = (np.arange(n) + 2**32 - 700).astype(float) % 2**32  # wraps through u32's top
    c["fault"] = np.zeros(n)
    c["fault"][-1] = 1.0  # the tripping sample: no estimate
    c["T_w"][100:180] = np.nan  # a loose thermocouple
    extra = np.random.default_rng(seed + 1)
    for k in late:
        c[k] = extra.normal(24.0, 2.0, n)
    c["q_i_hat"][400] = np.nan
    c["late"][7] = math.inf  # becomes null in JSON: NaN
    return c


@pytest.fixture(scope="module")
def synthetic(tmp_path_factory: pytest.TempPathFactory) -> Path:
    path = tmp_path_factory.mktemp("ros2") / "loop.mcap"
    lr = LoopRecorder(path, Config(), chunk_size=16384)
    c = loop_rows(N)
    lr.event(0.0, "run-start", device="sim", scenario="none", realtime=True)
    for a in range(0, N, 250):
        lr.write_rows({k: v[a:a + 250] for k, v in c.items()})
    lr.rec.write("/custom/thing", 0.5, {"list": [1, 2.5, None], "text": "Wärme ✓", "x": math.nan})
    lr.event(1.2345, "fault", name="overtemp", value=math.nan, detail="T_p 41.2 degC")
    lr.close()
    return path


@pytest.fixture(scope="module")
def real_run(tmp_path_factory: pytest.TempPathFactory) -> Path:
    """`thermoskin run --duration 3 --scenario one-finger --record`."""
    d = tmp_path_factory.mktemp("ros2run")
    code, _, err = invoke("run", "--duration", "3", "--scenario", "one-finger", "--record",
                          str(d / "x.mcap"), "--log", str(d / "x.csv"), "--plot", str(d / "x.png"))
    assert code == 0, err
    return d / "x.mcap"


def json_messages(path: Path) -> list[tuple[str, int, int, int, bytes]]:
    """(topic, log_time, publish_time, sequence, payload) in file order, by the `mcap` library."""
    with open(path, "rb") as fh:
        return [(ch.topic, m.log_time, m.publish_time, m.sequence, m.data)
                for _, ch, m in make_reader(fh).iter_messages(log_time_order=False)]


def ros_messages(path: Path) -> list[tuple[str, int, int, int, Any]]:
    """The same, decoded by `mcap-ros2-support`; checks every channel is CDR with a ros2msg schema."""
    with open(path, "rb") as fh:
        reader = make_reader(fh, decoder_factories=[DecoderFactory()])
        assert reader.get_header().profile == "ros2"
        summary = reader.get_summary()
        assert summary is not None
        for ch in summary.channels.values():
            assert ch.message_encoding == "cdr"
            assert summary.schemas[ch.schema_id].encoding == "ros2msg"
        return [(ch.topic, m.log_time, m.publish_time, m.sequence, dec)
                for _, ch, m, dec in reader.iter_decoded_messages(log_time_order=False)]


def same(a: float, b: float) -> bool:
    return a == b or (math.isnan(a) and math.isnan(b))


def check_message(topic: str, obj: Any, payload: bytes, ros: Any, log_time: int) -> None:
    """One decoded ROS 2 message against its JSON message, by the JSON schema's field types."""
    if topic not in MESSAGES:  # /params and unknown topics: the JSON text, verbatim
        assert ros.data == payload.decode()
        return
    assert ros.header.stamp.sec * 10**9 + ros.header.stamp.nanosec == log_time
    assert ros.header.frame_id == ""
    props = TOPIC_SCHEMAS[topic]["properties"]
    for key, spec in props.items():
        got = getattr(ros, key.lower())
        v = obj.get(key)
        if spec == {"type": "integer"}:
            assert isinstance(got, int) and got == (0 if v is None else v), (topic, key)
        elif spec.get("type") in ("number", ["number", "null"]):
            assert isinstance(got, float) and same(got, math.nan if v is None else float(v)), (topic, key)
        elif spec.get("type") == "string":
            assert got == v
        else:  # any JSON value: as JSON text
            assert json.loads(got) == v if got else v is None


def check_export(src: Path, out: Path) -> Counter[str]:
    want = json_messages(src)
    got = ros_messages(out)
    assert [m[:4] for m in got] == [m[:4] for m in want]  # topics, times, sequence numbers, order
    for (topic, log_time, _, _, payload), (_, _, _, _, ros) in zip(want, got, strict=True):
        check_message(topic, json.loads(payload), payload, ros, log_time)
    return Counter(m[0] for m in got)


def test_synthetic_recording_every_topic(synthetic: Path, tmp_path: Path) -> None:
    out = tmp_path / "ros.mcap"
    code, stdout, err = invoke("export", str(synthetic), "--ros2", "-o", str(out))
    assert code == 0 and err == "" and "wrote" in stdout
    counts = check_export(synthetic, out)
    contacts = int(np.abs(np.diff(np.r_[0.0, loop_rows(N)["contact"][:-1]])).sum())
    assert counts == {"/params": 1, "/skin/sample": N, "/control": N, "/skin/estimate": N - 1,
                      "/sim/truth": N, "/loop/timing": N, "/events": 2 + contacts, "/custom/thing": 1}
    got: dict[str, list[Any]] = {}
    for topic, *_, ros in ros_messages(out):
        got.setdefault(topic, []).append(ros)
    # NaN stays NaN; integers at the edges of their types; the fault's detail
    assert all(math.isnan(m.t_w) for m in got["/skin/sample"][100:180])
    assert math.isnan(got["/skin/estimate"][400].q_i_hat) and math.isnan(got["/loop/timing"][7].late)
    assert {m.status for m in got["/skin/sample"]} == {0, 0x10, 0xFFFF}
    assert max(m.seq for m in got["/skin/sample"]) == 2**32 - 1
    fault = next(m for m in got["/events"] if m.kind == "fault")
    assert json.loads(fault.detail) == {"name": "overtemp", "value": None, "detail": "T_p 41.2 degC"}
    assert json.loads(got["/custom/thing"][0].data)["text"] == "Wärme ✓"


def test_real_run(real_run: Path, tmp_path: Path) -> None:
    out = tmp_path / "x_ros2.mcap"
    code, _, err = invoke("export", str(real_run), "--ros2", "-o", str(out))
    assert code == 0, err
    counts = check_export(real_run, out)
    assert counts["/skin/sample"] == counts["/control"] == counts["/skin/estimate"] == 3000
    assert counts["/params"] == 1 and counts["/events"] >= 2
    # the recording's floats survive to the last bit: t and q_i_hat as the JSON reader gives them
    est = read_mcap(real_run, ["/skin/estimate"])["/skin/estimate"]
    ros = [m[4] for m in ros_messages(out) if m[0] == "/skin/estimate"]
    assert len(ros) == len(est)
    assert all(same(m.q_i_hat, e["q_i_hat"]) and m.t == e["t"] for m, e in zip(ros, est, strict=True))


def test_rosbags_reads_it(synthetic: Path, tmp_path: Path) -> None:
    """`rosbags` (pure Python, the rosbag2 layout) opens the file, its types from the
    embedded schemas, and decodes the same values."""
    pytest.importorskip("rosbags")
    from rosbags.highlevel import AnyReader

    out = export_ros2(synthetic, tmp_path / "ros.mcap")
    want = json_messages(synthetic)
    with AnyReader([out]) as reader:
        types = {c.topic: c.msgtype for c in reader.connections}
        assert types["/skin/sample"] == "thermoskin_msgs/msg/Sample"
        assert types["/params"] == "std_msgs/msg/String"
        got = [(c.topic, ts, reader.deserialize(raw, c.msgtype)) for c, ts, raw in reader.messages()]
    assert sorted((m[0], m[1]) for m in got) == sorted((m[0], m[1]) for m in want)
    by_key = {(m[0], m[1]): m[4] for m in want}
    assert len(by_key) == len(want)  # (topic, log time) is unique in this recording
    for topic, ts, ros in got:
        payload = by_key[(topic, ts)]
        check_message(topic, json.loads(payload), payload, ros, ts)


def test_encoder_bytes_equal_mcap_ros2s(tmp_path: Path) -> None:
    """Our struct-compiled CDR is byte for byte what `mcap-ros2-support` encodes, for
    values at the types' edges and strings of every length modulo 4 (alignment)."""
    from mcap_ros2._dynamic import serialize_dynamic

    rng = np.random.default_rng(7)
    edges = {"uint8": [0, 1, 255], "uint16": [0, 0x10, 0xFFFF], "uint32": [0, 2**31, 2**32 - 1]}
    floats = [0.0, -0.0, 1e-300, -2.5, 1e308, math.inf, -math.inf, math.nan]
    for topic, rt in [*ROS_TYPES.items(), ("/params", STRING)]:
        ref = serialize_dynamic(rt.name, schema_text(rt.name))[rt.name]
        for i in range(40):
            obj: dict[str, Any] = {}
            for key, _, kind, _ in rt.fields:
                if kind == "float64":
                    obj[key] = floats[i % len(floats)] if i < 16 else float(rng.normal())
                elif kind in edges:
                    obj[key] = edges[kind][i % 3]
                else:
                    obj[key] = "é" * (i % 5) + "x" * (i % 4)
            ns = [0, 1, 999_999_999, 10**9, 1_700_000_000_123_456_789][i % 5]
            if topic == "/params":
                ros = {"data": obj["data"]}
            else:
                ros = {"header": {"stamp": {"sec": ns // 10**9, "nanosec": ns % 10**9}, "frame_id": ""}}
                ros.update({name: (json.dumps(obj[key], ensure_ascii=False) if kind == "json" else obj[key])
                            for key, name, kind, _ in rt.fields})
            assert rt.encode(obj, ns) == ref(ros), (topic, i)


def test_message_definitions_mirror_the_json_schemas() -> None:
    """Every JSON field has its ROS 2 field (name in lower case, type of its kind) and no
    other; names are valid ROS 2 field names; the definitions parse as ROS 2 .msg."""
    from mcap_ros2._dynamic import generate_dynamic

    name_ok = re.compile(r"^(?!.*__)(?!.*_$)[a-z][a-z0-9_]*$")  # rosidl's rule
    for topic, (dt, _, fields) in MESSAGES.items():
        props = TOPIC_SCHEMAS[topic]["properties"]
        assert [f[0] for f in fields] == list(props), topic
        for key, name, kind, _ in fields:
            assert name == key.lower() and name_ok.match(name)
            t = props[key].get("type")
            if t == "integer":
                assert kind in ("uint8", "uint16", "uint32"), (topic, key)
            elif t in ("number", ["number", "null"]):
                assert kind == "float64", (topic, key)
            else:
                assert kind == ("string" if t == "string" else "json"), (topic, key)
        assert set(generate_dynamic(dt, schema_text(dt))) >= {dt, "std_msgs/Header"}
    assert set(TOPIC_SCHEMAS) - set(MESSAGES) == {"/params"}


def test_missing_and_extra_fields(tmp_path: Path) -> None:
    """An absent number is NaN, an absent integer 0; a field unknown to the message type is
    left out with one warning line (exit 0)."""
    src, out = tmp_path / "odd.mcap", tmp_path / "odd_ros.mcap"
    with Recorder(src, {}) as rec:
        rec.write("/skin/sample", 0.25, {"T_w": 24.5, "new_field": 3})
        rec.write("/skin/estimate", 0.25, {"q_i_hat": 1})  # an int in a number field
    code, _, err = invoke("export", str(src), "--ros2", "-o", str(out))
    assert code == 0
    assert err.strip() == (f"thermoskin: warning: {src}: fields with no place in the ROS 2 messages "
                           "were left out: /skin/sample.new_field")
    msgs = {m[0]: m[4] for m in ros_messages(out)}
    s = msgs["/skin/sample"]
    assert s.t == 0.25 and s.t_w == 24.5 and math.isnan(s.t_p) and s.seq == 0 and s.fresh == 0
    assert (s.header.stamp.sec, s.header.stamp.nanosec) == (0, 250_000_000)
    assert msgs["/skin/estimate"].q_i_hat == 1.0 and math.isnan(msgs["/skin/estimate"].dq_i_hat)


@pytest.mark.parametrize(("topic", "data", "what"), [
    ("/skin/sample", {"seq": -1}, "/skin/sample at t = 0.250 s: seq = -1 is not an integer in [0, 4294967295]"
                                  " (uint32)"),
    ("/skin/sample", {"fresh": 256}, "fresh = 256 is not an integer in [0, 255] (uint8)"),
    ("/skin/estimate", {"contact": 0.5}, "contact = 0.5 is not an integer"),
    ("/control", {"drive": "full"}, "/control at t = 0.250 s: drive = 'full' is not a number"),
    ("/control", {"drive": 10**400}, "drive = 1000000000000000000000000000000000000000 is not a number"),
])
def test_values_that_do_not_fit(tmp_path: Path, topic: str, data: dict[str, Any], what: str) -> None:
    src, out = tmp_path / "bad.mcap", tmp_path / "bad_ros.mcap"
    out.write_bytes(b"earlier")
    with Recorder(src, {}) as rec:
        rec.write(topic, 0.25, data)
    code, _, err = invoke("export", str(src), "--ros2", "-o", str(out))
    assert code == 2 and err.count("\n") == 1 and what in err, err
    assert out.read_bytes() == b"earlier"  # an earlier output is left as it was, no temporary file
    assert sorted(p.name for p in tmp_path.iterdir()) == ["bad.mcap", "bad_ros.mcap"]


def test_user_errors(synthetic: Path, tmp_path: Path) -> None:
    (tmp_path / "dir.mcap").mkdir()
    (tmp_path / "text.mcap").write_text("hello")
    ros = export_ros2(synthetic, tmp_path / "ros.mcap")
    y = str(tmp_path / "y.mcap")
    cases = [
        ([str(synthetic), "--ros2", "-o", str(tmp_path / "x.csv")], "the output name must end in .mcap"),
        ([str(synthetic), "-o", str(tmp_path / "x.mcap")], "needs --ros2"),
        ([str(synthetic), "--ros2", "-o", str(tmp_path / "dir.mcap")], "is a directory"),
        ([str(synthetic), "--ros2", "-o", str(synthetic)], "it is the recording itself"),
        ([str(tmp_path / "none.mcap"), "--ros2", "-o", y], "does not exist"),
        ([str(tmp_path / "text.mcap"), "--ros2", "-o", y], "not an MCAP file"),
        ([str(ros), "--ros2", "-o", y], "is not JSON"),
    ]
    for args, what in cases:
        code, _, err = invoke("export", *args)
        assert code == 2 and err.startswith("thermoskin: error: ") and err.count("\n") == 1, (args, err)
        assert what in err, (args, err)
    assert not (tmp_path / "y.mcap").exists()


def flip(src: Path, dst: Path, at: int, n: int = 50, keep: int | None = None) -> None:
    data = bytearray(src.read_bytes())
    for i in range(at, min(at + n, len(data))):
        data[i] ^= 0xFF
    dst.write_bytes(bytes(data[:keep]))


def test_damaged_and_cut_off_recordings(synthetic: Path, tmp_path: Path) -> None:
    """As the table export: every intact part exported, one warning per damaged part, exit 4
    if messages were lost; a cut-off file up to where it ends, exit 0."""
    bad, out = tmp_path / "bad.mcap", tmp_path / "bad_ros.mcap"
    with open(synthetic, "rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    size = synthetic.stat().st_size
    ci = min(summary.chunk_indexes, key=lambda c: abs(c.chunk_start_offset - size / 2))
    flip(synthetic, bad, ci.chunk_start_offset + ci.chunk_length // 2)  # the middle chunk's data
    code, _, err = invoke("export", str(bad), "--ros2", "-o", str(out))
    _, _, err_table = invoke("export", str(bad), "-o", str(tmp_path / "bad.csv"))
    assert code == 4 and err == err_table and "damaged bytes" in err and "lost" in err
    kept = read_mcap(bad)  # what the damage-tolerant reader keeps, by topic
    got: dict[str, list[Any]] = {}
    for topic, *_, ros in ros_messages(out):
        got.setdefault(topic, []).append(ros)
    assert {k: len(v) for k, v in got.items()} == {k: len(v) for k, v in kept.items()}
    assert len(got["/skin/sample"]) < N
    assert [m.t for m in got["/skin/sample"]] == [m["t"] for m in kept["/skin/sample"]]

    cut = tmp_path / "cut.mcap"
    cut.write_bytes(synthetic.read_bytes()[: synthetic.stat().st_size * 2 // 3])
    code, _, err = invoke("export", str(cut), "--ros2", "-o", str(out))
    assert code == 0 and "cut off" in err and err.count("\n") == 1
    kept = read_mcap(cut)
    assert Counter(m[0] for m in ros_messages(out)) == {k: len(v) for k, v in kept.items()}
