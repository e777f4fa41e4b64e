"""MCAP recording: round trip, a killed writer, export to CSV and Parquet, replay."""

from __future__ import annotations

import io
import json
import math
import signal
import subprocess
import sys
import textwrap
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader
from mcap.records import Footer
from mcap.records import Message as McapMessage
from mcap.stream_reader import StreamReader, breakup_chunk

from thermoskin.devices.base import Sample
from thermoskin.logio import read_log
from thermoskin.params import Config
from thermoskin.runtime.record import (
    Recorder,
    RecordingError,
    ReplayDevice,
    check,
    export,
    read_mcap,
    to_columns,
)

N = 500


def write_run(path: Path, n: int = N) -> None:
    with Recorder(path, Config()) as rec:
        for k in range(n):
            t = k * 1e-3
            T_w = math.nan if k == 7 else 24.0 + 0.001 * k
            rec.write_sample(Sample(t, T_w, 24.3, 20.0, fresh=7 if k % 100 == 0 else 0, seq=k + 1,
                                    v=0.141, drive=0.1))
            if k % 2 == 0:  # an estimate every other sample: the gaps export as NaN
                rec.write("/skin/estimate", t, {"q_i_hat": 3.6 + k * 1e-4, "dq_i_hat": 0.0,
                                                "contact": int(k > 300)})
            rec.write("/control", t, {"T_p_cmd": 24.5, "drive": 0.2, "v_cmd": 0.141})
        rec.event(0.301, "contact-on", n_fingers=1)


def test_round_trip_and_foxglove_schemas(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    write_run(path)
    info: dict[str, object] = {}
    data = read_mcap(path, info=info)
    assert info["complete"] and not info["truncated"]
    assert len(data["/skin/sample"]) == N and len(data["/control"]) == N
    assert len(data["/skin/estimate"]) == N // 2
    s7 = data["/skin/sample"][7]
    assert math.isnan(s7["T_w"]) and s7["t"] == pytest.approx(0.007) and s7["seq"] == 8
    assert data["/events"] == [{"t": 0.301, "kind": "contact-on", "detail": {"n_fingers": 1}}]
    (params,) = data["/params"]
    assert params["config"]["skin"]["R_g"] == Config().skin.R_g
    # a complete file has a summary; every channel is JSON with a JSON schema (Foxglove)
    with open(path, "rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    topics = {ch.topic: ch for ch in summary.channels.values()}
    assert set(topics) == {"/params", "/skin/sample", "/skin/estimate", "/control", "/events"}
    for ch in topics.values():
        assert ch.message_encoding == "json"
        schema = summary.schemas[ch.schema_id]
        assert schema.encoding == "jsonschema"
        assert json.loads(schema.data)["type"] == "object"
    assert summary.statistics.message_count == 1 + N + N // 2 + N + 1


def test_flush_interval_closes_chunks_by_time(tmp_path: Path) -> None:
    path = tmp_path / "chunks.mcap"
    rec = Recorder(path, {"a": 1}, flush_interval=0.05)
    size0 = path.stat().st_size
    rec.write("/skin/sample", 0.0, {"T_w": 24.0})
    time.sleep(0.06)
    rec.write("/skin/sample", 0.001, {"T_w": 24.0})  # this write finds the interval passed
    assert path.stat().st_size > size0
    assert len(read_mcap(path)["/skin/sample"]) == 2  # readable while still open
    rec.close()


WRITER = textwrap.dedent("""
    import sys, time
    from thermoskin.runtime.record import Recorder
    rec = Recorder(sys.argv[1], '{"sim": true}')
    t0 = time.monotonic()
    k = 0
    last = 0.0
    while True:
        t = k * 1e-3
        while time.monotonic() - t0 < t:
            time.sleep(0.0002)
        rec.write("/skin/sample", t, {"T_w": 24.0, "seq": k})
        k += 1
        if t - last >= 0.05:
            print(t, flush=True)
            last = t
""")


def test_killed_writer_loses_at_most_a_second(tmp_path: Path) -> None:
    path = tmp_path / "killed.mcap"
    proc = subprocess.Popen([sys.executable, "-c", WRITER, str(path)], stdout=subprocess.PIPE, text=True)
    last = 0.0
    try:
        assert proc.stdout is not None
        for line in proc.stdout:
            last = float(line)
            if last >= 2.2:
                break
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait(10)
    assert last >= 2.2
    info: dict[str, object] = {}
    data = read_mcap(path, info=info)
    assert not info["complete"]  # no footer: the process never closed the file
    samples = data["/skin/sample"]
    ts = [s["t"] for s in samples]
    assert ts == [k * 1e-3 for k in range(len(ts))]  # everything kept is intact and in order
    assert ts[-1] >= last - 1.0, f"lost {last - ts[-1]:.3f} s"
    assert data["/params"][0]["config"] == {"sim": True}


def test_truncated_anywhere_never_raises(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    with Recorder(path, None, flush_interval=0.0) as rec:  # a chunk per message
        for k in range(50):
            rec.write("/skin/sample", k * 1e-3, {"T_w": 24.0})
    whole = path.read_bytes()
    counts = []
    for cut in range(8, len(whole), 37):
        part = tmp_path / "part.mcap"
        part.write_bytes(whole[:cut])
        counts.append(len(read_mcap(part).get("/skin/sample", [])))
    assert counts == sorted(counts) and counts[-1] >= 49


def test_bad_files(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="does not exist"):
        read_mcap(tmp_path / "none.mcap")
    bad = tmp_path / "bad.mcap"
    bad.write_text("t,T_w\n0,1\n")
    with pytest.raises(RecordingError, match="not an MCAP file"):
        read_mcap(bad)


def test_export_csv_and_parquet(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    write_run(path)
    cols = to_columns(path)
    assert len(cols["t"]) == N
    assert cols["drive"][0] == pytest.approx(0.1) and cols["control.drive"][0] == pytest.approx(0.2)
    assert math.isnan(cols["q_i_hat"][1]) and cols["q_i_hat"][2] == pytest.approx(3.6002)
    csv = export(path, tmp_path / "run.csv")
    log = read_log(csv, nan_columns=list(cols))  # q_i_hat has gaps here, hence NaN
    assert np.allclose(log["t"], np.arange(N) * 1e-3)
    assert np.isnan(log["T_w"][7]) and log["T_w"][8] == pytest.approx(24.008)
    assert np.allclose(log["T_p_cmd"], 24.5) and log["contact"][302] == 1
    pq = pytest.importorskip("pyarrow.parquet")
    out = export(path, tmp_path / "run.parquet")
    table = pq.read_table(out)
    assert table.num_rows == N and "q_i_hat" in table.column_names
    assert table.column("v").to_pylist()[0] == pytest.approx(0.141)
    with pytest.raises(RecordingError, match=r"\.csv or \.parquet"):
        export(path, tmp_path / "run.xlsx")


def test_replay_device(tmp_path: Path) -> None:
    path = tmp_path / "run.mcap"
    write_run(path, 20)
    dev = ReplayDevice(path)
    dev.open()
    got = []
    while (s := dev.read_sample(0.0)) is not None:
        got.append(s)
        dev.write_command(0.0, 0.141)
    assert dev.link_lost and len(got) == 20 and len(dev.commands) == 20
    assert got[3].T_w == pytest.approx(24.003) and got[0].fresh == 7 and got[1].fresh == 0
    assert math.isnan(got[7].T_w)
    dev.close()


# ----------------------------------------------------------------------------- signals

def read_to_end_with_mcap(path: Path) -> int:
    """The `mcap` library's own readers: every record up to the footer (chunk CRCs checked),
    then the summary's message count against the messages its indexed reader yields."""
    with open(path, "rb") as fh:
        records = list(StreamReader(fh, validate_crcs=True).records)
    assert isinstance(records[-1], Footer)
    with open(path, "rb") as fh:
        reader = make_reader(fh)
        summary = reader.get_summary()
        n = sum(1 for _ in reader.iter_messages())
    assert summary is not None and summary.statistics is not None
    assert n == summary.statistics.message_count
    return n


# Forks one recording child at a time (imports once), interrupts it with a real signal at a
# random moment while it writes 20-row blocks (as `thermoskin run` drains its loop), reports
# how each child ended.
INTERRUPTED = textwrap.dedent("""
    import faulthandler, os, random, signal, sys, time
    import numpy as np
    from thermoskin.runtime.record import LoopRecorder
    # Python's own SIGINT handler, as in a terminal: a shell's background job (`cmd &`) starts
    # with SIGINT ignored, which Python keeps, and the children would never see the signal
    signal.signal(signal.SIGINT, signal.default_int_handler)
    out, n = sys.argv[1], int(sys.argv[2])
    rng = random.Random(11)
    B = 20
    for i in range(n):
        r, w = os.pipe()
        pid = os.fork()
        if pid == 0:
            os.close(r)
            code = 0
            faulthandler.dump_traceback_later(60, exit=True)  # a child that hangs says where
            try:
                rec = LoopRecorder(f"{out}/r{i}.mcap", {"i": i}, flush_interval=0.003)
                try:
                    os.write(w, b"x")
                    k = 0
                    while True:
                        t = (k + np.arange(B)) * 1e-3
                        one = np.ones(B)
                        rec.write_rows({"t": t, "T_w": 24 + t, "T_p": 24.3 * one, "T_a": 20 * one,
                                        "v": 0.141 * one, "drive": 0.1 * one, "T_w_cmd": 25 * one,
                                        "T_p_cmd": 24.5 * one, "q_i_hat": 3.6 + t, "dq_i_hat": 0 * one,
                                        "contact": 0 * one, "gap": 0 * one})
                        k += B
                finally:
                    rec.close()
            except KeyboardInterrupt:
                code = 130
            finally:
                os._exit(code)
        os.close(w)
        os.read(r, 1)
        os.close(r)
        time.sleep(rng.uniform(0.0, 0.04))
        sig = (signal.SIGINT, signal.SIGTERM)[i % 2]
        os.kill(pid, sig)
        print(i, int(sig), os.waitstatus_to_exitcode(os.waitpid(pid, 0)[1]), flush=True)
""")


def test_signals_never_tear_a_recording(tmp_path: Path) -> None:
    n = 20
    r = subprocess.run([sys.executable, "-c", INTERRUPTED, str(tmp_path), str(n)], capture_output=True,
                       text=True, timeout=120)
    assert r.returncode == 0, r.stderr
    ends = [tuple(map(int, line.split())) for line in r.stdout.splitlines()]
    assert "Timeout" not in r.stderr, r.stderr  # a child hung (its stack, from faulthandler)
    assert len(ends) == n
    for i, sig, code in ends:
        # SIGINT: KeyboardInterrupt after the block, the file closed; SIGTERM: the file
        # finished, then the process ended by the signal as the default action would
        assert code == (130 if sig == signal.SIGINT else -signal.SIGTERM), (i, sig, code)
        path = tmp_path / f"r{i}.mcap"
        m = read_to_end_with_mcap(path)
        info: dict[str, object] = {}
        data = read_mcap(path, info=info)
        assert info["complete"], (i, info)
        # (a signal before the first block, under load, leaves a whole file with no sample)
        samples = data.get("/skin/sample", [])
        rows = len(samples)
        assert rows % 20 == 0  # whole blocks: a signal waits for the block being written
        assert [s["t"] for s in samples] == [k * 1e-3 for k in range(rows)]
        assert len(data.get("/control", [])) == len(data.get("/skin/estimate", [])) == rows
        assert m == 1 + 3 * rows


def test_torn_writer_ends_the_file_readably(tmp_path: Path) -> None:
    """An exception inside the MCAP writer (here a topic that cannot be encoded, raised while
    the writer has half a schema record in its chunk) leaves its buffers torn: the recorder
    refuses further writes and ends the file after what it had written, without a summary."""
    path = tmp_path / "torn.mcap"
    rec = Recorder(path, {"a": 1})
    for k in range(100):
        rec.write("/skin/sample", k * 1e-3, {"T_w": 24.0})
    rec.flush()
    with pytest.raises(UnicodeEncodeError):
        rec.write("/bad\ud800", 0.1, {"x": 1})
    with pytest.raises(RecordingError, match="interrupted inside a record"):
        rec.write("/skin/sample", 0.1, {"T_w": 24.0})
    rec.close()
    with open(path, "rb") as fh:
        records = list(StreamReader(fh, validate_crcs=True).records)
    assert isinstance(records[-1], Footer)
    assert sum(isinstance(x, McapMessage) for x in records) == 101
    info: dict[str, object] = {}
    data = read_mcap(path, info=info)
    assert info["complete"] and len(data["/skin/sample"]) == 100


# ----------------------------------------------------------------------------- damage

def sample_value(k: int) -> float:
    return 24.0 + 1e-4 * k


def write_rows(path: Path, n: int, **kw: object) -> None:
    """``n`` rows: a sample and an estimate each, values known from ``k``."""
    with Recorder(path, {"n": n}, **kw) as rec:  # type: ignore[arg-type]
        for k in range(n):
            t = k * 1e-3
            rec.write("/skin/sample", t, {"T_w": sample_value(k), "seq": k})
            rec.write("/skin/estimate", t, {"q_i_hat": 3.6 + 1e-5 * k, "contact": 0})


def chunks_with_mcap(path: Path) -> list[tuple[int, int, dict[str, int]]]:
    """``(start, end, messages by topic)`` of every chunk record, by the `mcap` library
    (its summary's chunk index and its own chunk decoder)."""
    with open(path, "rb") as fh:
        summary = make_reader(fh).get_summary()
    assert summary is not None
    topics = {c.id: c.topic for c in summary.channels.values()}
    out = []
    data = path.read_bytes()
    for ci in summary.chunk_indexes:
        rec = next(iter(StreamReader(io.BytesIO(data[ci.chunk_start_offset: ci.chunk_start_offset
                                                      + ci.chunk_length]), skip_magic=True,
                                     emit_chunks=True).records))
        counts: dict[str, int] = {}
        for m in breakup_chunk(rec, validate_crc=True):
            if isinstance(m, McapMessage):
                counts[topics[m.channel_id]] = counts.get(topics[m.channel_id], 0) + 1
        out.append((ci.chunk_start_offset, ci.chunk_start_offset + ci.chunk_length, counts))
    return out


def flip(src: Path, dst: Path, at: int, n: int = 50, keep: int | None = None) -> None:
    data = bytearray(src.read_bytes())
    for i in range(at, min(at + n, len(data))):
        data[i] ^= 0xFF
    dst.write_bytes(bytes(data[:keep]))


def check_kept(data: dict[str, list[dict[str, object]]], report: object, n: int) -> list[int]:
    """Every sample read is one that was written, intact; every sample missing lies in a
    reported span (its times included); the spans' counts are the samples missing.
    Returns the missing rows."""
    kept = [round(float(s["t"]) * 1e3) for s in data.get("/skin/sample", [])]  # type: ignore[arg-type]
    assert kept == sorted(set(kept))
    for s in data.get("/skin/sample", []):
        assert s["T_w"] == sample_value(int(s["seq"]))  # type: ignore[call-overload]
    missing = sorted(set(range(n)) - set(kept))
    spans = report.spans  # type: ignore[attr-defined]
    for k in missing:
        t = k * 1e-3
        assert any((math.isnan(sp.t_before) or sp.t_before <= t)
                   and (math.isnan(sp.t_after) or t <= sp.t_after) for sp in spans), k
    if all(sp.known for sp in spans):
        assert sum(sp.lost.get("/skin/sample", 0) for sp in spans) == len(missing)
    return missing


def test_damaged_middle_keeps_every_intact_chunk(tmp_path: Path) -> None:
    """The brief's target: 50 bytes flipped in the middle of a 40 000-row recording (written
    with the default chunking); at least 90 % of the rows kept, the loss said exactly."""
    n = 40_000
    clean, bad = tmp_path / "clean.mcap", tmp_path / "bad.mcap"
    write_rows(clean, n)
    chunks = chunks_with_mcap(clean)
    size = clean.stat().st_size
    start, end, lost = min(chunks, key=lambda c: abs((c[0] + c[1]) / 2 - size / 2))  # the middle chunk
    flip(clean, bad, (start + end) // 2)
    info: dict[str, object] = {}
    cols = to_columns(bad, info=info)
    rep = info["report"]
    assert len(cols["t"]) >= 0.9 * n
    assert len(cols["t"]) == n - lost["/skin/sample"]
    (span,) = rep.spans  # type: ignore[attr-defined]
    assert span.known and span.lost == lost and span.start == start
    assert rep.data_lost and not rep.cut_off  # type: ignore[attr-defined]
    missing = check_kept(read_mcap(bad), rep, n)
    assert len(missing) == lost["/skin/sample"] and missing == list(range(missing[0], missing[-1] + 1))
    assert span.t_after - span.t_before <= (len(missing) + 1) * 1e-3 + 1e-9  # no wider than the gap
    # the estimates are joined to their samples by t; NaN only where a row's estimate was lost
    rows = [round(t * 1e3) for t in cols["t"]]
    q = cols["q_i_hat"]
    assert all(q[i] == 3.6 + 1e-5 * k for i, k in enumerate(rows) if q[i] == q[i])
    assert {rows[i] for i in range(len(rows)) if q[i] != q[i]} <= {missing[0] - 1, missing[-1] + 1}


@pytest.mark.parametrize("compression", ["zstd", "lz4", "none"])
def test_damage_anywhere_costs_only_what_it_touches(tmp_path: Path, compression: str) -> None:
    n = 3000
    clean, bad = tmp_path / "clean.mcap", tmp_path / "bad.mcap"
    write_rows(clean, n, chunk_size=8192, compression=compression)
    chunks = chunks_with_mcap(clean)
    per_chunk = max(c[2].get("/skin/sample", 0) for c in chunks)
    assert len(chunks) > 20
    size = clean.stat().st_size
    losses = 0
    for at in [*range(8, size - 50, size // 37), size - 60, size - 30]:
        flip(clean, bad, at)
        info: dict[str, object] = {}
        data = read_mcap(bad, info=info)
        rep = info["report"]
        assert check(bad) == rep  # reading without decoding finds the same
        missing = check_kept(data, rep, n)
        assert len(missing) <= 2 * per_chunk, at  # 50 bytes touch at most two chunks
        hit = [c for c in chunks if c[0] < at + 50 and at < c[1]]
        assert len(missing) == sum(c[2].get("/skin/sample", 0) for c in hit), at
        in_hit = Counter[str]()
        for c in hit:
            in_hit.update(c[2])
        in_spans = Counter[str]()
        for sp in rep.spans:  # type: ignore[attr-defined]
            assert sp.known, at
            in_spans.update(sp.lost)
        assert in_spans == in_hit, at  # every topic's loss, as the mcap library counts the chunks
        assert rep.data_lost == bool(in_hit), at  # type: ignore[attr-defined]
        losses += bool(missing)
        # the lines a user sees: one per span, saying what was lost and when
        for line, sp in zip(rep.lines(), rep.spans, strict=False):  # type: ignore[attr-defined]
            assert line.startswith(f"damaged bytes {sp.start}-{sp.end}: ")
            assert ("no message lost" in line) == (sp.messages == 0 and sp.known)
    assert losses >= 10  # (the message indexes between chunks are as large as the chunks)


def test_damage_in_the_summary_loses_nothing(tmp_path: Path) -> None:
    clean, bad = tmp_path / "clean.mcap", tmp_path / "bad.mcap"
    write_rows(clean, 500)
    footer_at = clean.stat().st_size - 8 - 29
    flip(clean, bad, footer_at - 60)  # the summary's last records and the footer
    info: dict[str, object] = {}
    got = read_mcap(bad, info=info)
    rep = info["report"]
    assert len(got["/skin/sample"]) == 500 and not rep.cut_off  # type: ignore[attr-defined]
    (span,) = rep.spans  # type: ignore[attr-defined]
    assert span.in_summary and "no message lost" in span.describe()


def test_cut_off_says_where_it_ends(tmp_path: Path) -> None:
    clean, cut = tmp_path / "clean.mcap", tmp_path / "cut.mcap"
    write_rows(clean, 2000, chunk_size=8192)
    data = clean.read_bytes()
    for keep in (len(data) // 3, len(data) // 2 + 7):
        cut.write_bytes(data[:keep])
        info: dict[str, object] = {}
        got = read_mcap(cut, info=info)
        rep = info["report"]
        assert rep.cut_off and not rep.damaged and not info["complete"]  # type: ignore[attr-defined]
        t_last = max(got["/skin/estimate"][-1]["t"], got["/skin/sample"][-1]["t"])
        assert rep.t_end == pytest.approx(t_last)  # type: ignore[attr-defined]
        (line,) = rep.lines()  # type: ignore[attr-defined]
        assert f"it ends at t = {t_last:.3f} s" in line
    cut.write_bytes(data[:-40])  # in the summary, after the data section's end
    info = {}
    assert len(read_mcap(cut, info=info)["/skin/sample"]) == 2000
    rep = info["report"]
    assert not rep.cut_off and not rep.data_lost and rep.damaged  # type: ignore[attr-defined]
    (line,) = rep.lines()  # type: ignore[attr-defined]
    assert "in the summary" in line and "no message lost" in line


def test_lost_channel_definition(tmp_path: Path) -> None:
    """The chunk defining /skin/sample damaged: a finished file still has it in its summary;
    a cut-off one cannot decode that channel's messages and says so."""
    clean, bad = tmp_path / "clean.mcap", tmp_path / "bad.mcap"
    write_rows(clean, 2000, chunk_size=8192)
    with open(clean, "rb") as fh:
        first = next(m for _, ch, m in make_reader(fh).iter_messages() if ch.topic == "/skin/sample")
    defining = next(c for c in chunks_with_mcap(clean) if c[2].get("/skin/sample") == 1)
    assert defining[2] == {"/skin/sample": 1}  # a new topic's first message gets a chunk of its own
    flip(clean, bad, defining[0] + 40, 20)
    info: dict[str, object] = {}
    got = read_mcap(bad, info=info)
    assert len(got["/skin/sample"]) == 1999 and got["/skin/sample"][0]["seq"] == first.sequence
    rep = info["report"]
    assert rep.lost_messages == 1 and rep.spans[0].lost == {"/skin/sample": 1}  # type: ignore[attr-defined]
    flip(clean, bad, defining[0] + 40, 20, keep=clean.stat().st_size // 2)
    got = read_mcap(bad, info=info)
    rep = info["report"]
    assert "/skin/sample" not in got and rep.orphans > 0 and rep.cut_off  # type: ignore[attr-defined]
    assert any("channel was defined in a damaged part" in line for line in rep.lines())  # type: ignore[attr-defined]


def test_export_keeps_text_fields(tmp_path: Path) -> None:
    path = tmp_path / "text.mcap"
    with Recorder(path, None) as rec:
        for k in range(4):
            t = k * 1e-3
            rec.write("/skin/sample", t, {"T_w": 24.0 + k / 8, "mode": 'heat, "fast"' if k % 2 else "cool"})
            if k != 2:  # no /control at t = 2 ms: the text cell is empty there
                rec.write("/control", t, {"v_cmd": 0.1, "note": {"k": k}})
    import csv

    out = export(path, tmp_path / "text.csv")
    with open(out, newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["mode"] for r in rows] == ["cool", 'heat, "fast"', "cool", 'heat, "fast"']
    assert [r["note"] for r in rows] == ['{"k":0}', '{"k":1}', "", '{"k":3}']
    assert [float(r["T_w"]) for r in rows] == [24.0, 24.125, 24.25, 24.375]  # full precision
    assert [float(r["v_cmd"]) if r["v_cmd"] != "nan" else None for r in rows] == [0.1, 0.1, None, 0.1]
    assert out.read_text().splitlines()[:2] == ["t,T_w,mode,v_cmd,note", '0,24,"cool",0.1,"{""k"":0}"']
    pq = pytest.importorskip("pyarrow.parquet")
    import pyarrow as pa

    table = pq.read_table(export(path, tmp_path / "text.parquet"))
    assert table.schema.field("mode").type == pa.string() and table.schema.field("T_w").type == pa.float64()
    assert table.column("note").to_pylist() == ['{"k":0}', '{"k":1}', None, '{"k":3}']
    assert table.column("mode").to_pylist()[1] == 'heat, "fast"'


def test_directory_and_missing_recording(tmp_path: Path) -> None:
    with pytest.raises(RecordingError, match="is a directory"):
        read_mcap(tmp_path)
    with pytest.raises(RecordingError, match="does not exist"):
        to_columns(tmp_path / "none.mcap")
    empty = tmp_path / "empty.mcap"
    empty.write_bytes(b"")
    with pytest.raises(RecordingError, match="nothing was recorded"):
        read_mcap(empty)
    with pytest.raises(RecordingError, match=r"cannot record to .*: Is a directory"):
        Recorder(tmp_path)
