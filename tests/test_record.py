"""MCAP recording: round trip, a killed writer, export to CSV and Parquet, replay."""

from __future__ import annotations

import json
import math
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import numpy as np
import pytest
from mcap.reader import make_reader

from thermoskin.devices.base import Sample
from thermoskin.logio import read_log
from thermoskin.params import Config
from thermoskin.runtime.record import (
    Recorder,
    RecordingError,
    ReplayDevice,
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
