"""Recordings read block by block: `export` and `replay` in memory that does not grow with the
recording (`iter_columns`, `replay_blocks`, the scanner letting go of the mapped file)."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import thermoskin.runtime.record as rec_mod
from thermoskin.params import Config
from thermoskin.runtime.closed_loop import run_closed_loop
from thermoskin.runtime.record import LoopRecorder, Recorder, iter_columns, replay, replay_blocks, to_columns
from thermoskin.sim.scenarios import SCENARIOS

CFG = Config()


def record_run(path: Path, seconds: float) -> None:
    """A closed-loop run of touches recorded as `thermoskin run --record` does."""
    rec = LoopRecorder(path, CFG)
    try:
        # (its touches after the skin has reached its set-point and the estimator learnt its
        # sensors, as `thermoskin run` shifts them)
        run_closed_loop(SCENARIOS["one-finger"].shifted(4.0).with_duration(seconds), CFG,
                        on_block=rec.write_rows, keep=False)
    finally:
        rec.close()


@pytest.fixture(scope="module")
def recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    p = tmp_path_factory.mktemp("rec") / "run.mcap"
    record_run(p, 12.0)
    return p


def _joined(blocks: list[dict]) -> dict:  # type: ignore[type-arg]
    return {k: [v for b in blocks for v in b[k]] for k in blocks[0]}


def test_blocks_join_to_the_whole_table(recording: Path, tmp_path: Path) -> None:
    """Blocks of 997 rows (a sample's merged messages on either side of a block's edge) join to
    the whole table, columns in the same order; so does a recording cut off mid-chunk (its last
    whole sample, and the report's end, as the whole table says)."""
    whole = to_columns(recording)
    blocks = list(iter_columns(recording, block=997))
    assert len(blocks) >= 11 and all(len(b["t"]) == 997 for b in blocks[:-1])
    got = _joined(blocks)
    assert list(got) == list(whole) and "control.drive" in got and "q_i_hat" in got
    for k in whole:
        assert np.array_equal(np.asarray(got[k]), np.asarray(whole[k]), equal_nan=True), k
    data = recording.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) * 2 // 3 + 11])
    info_w: dict = {}  # type: ignore[type-arg]
    info_b: dict = {}  # type: ignore[type-arg]
    whole = to_columns(cut, info=info_w)
    got = _joined(list(iter_columns(cut, info=info_b, block=997)))
    assert not info_b["complete"] and info_b["report"].t_end == info_w["report"].t_end
    assert 1000 < len(got["t"]) < 12_000 and len(got["t"]) == len(whole["t"])
    for k in whole:
        assert np.array_equal(np.asarray(got[k]), np.asarray(whole[k]), equal_nan=True), k


def test_a_recording_replaced_while_read_is_read_to_its_end(recording: Path, tmp_path: Path) -> None:
    """Another `run --record` to the path of a recording that `export` or `replay` is reading
    (mapped) makes a new file: the reader still gets the old recording whole (cut to nothing in
    place, the mapping would fault: SIGBUS), and the new one is whole too."""
    path = tmp_path / "again.mcap"
    path.write_bytes(recording.read_bytes())
    blocks = iter_columns(path, block=997)
    first = [next(blocks)]
    record_run(path, 2.0)
    got = _joined(first + list(blocks))
    whole = to_columns(recording)
    assert len(got["t"]) == len(whole["t"]) > 11_000
    for k in whole:
        assert np.array_equal(np.asarray(got[k]), np.asarray(whole[k]), equal_nan=True), k
    assert 1900 < len(to_columns(path)["t"]) < 2100


CUT_IN_PLACE = """
import os, sys
from thermoskin.runtime.record import RecordingError, iter_columns
path = sys.argv[1]
blocks = iter_columns(path, block=997)
next(blocks)
os.truncate(path, os.path.getsize(path) // 3)  # in place, as `cp other.mcap` onto it would
try:
    for _ in blocks:
        pass
except RecordingError as e:
    print(e)
    sys.exit(2)
"""


def test_a_recording_cut_short_in_place_while_read_is_an_error(recording: Path, tmp_path: Path) -> None:
    """Another program cutting a recording short in place while `export` or `replay` reads it
    (mapped): the reader stops with an error naming the file and what happened, before it
    reads a page past the new end (which would end the process: SIGBUS). In a process of its
    own: without the check, it is the process that dies."""
    path = tmp_path / "cut_in_place.mcap"
    path.write_bytes(recording.read_bytes())
    r = subprocess.run([sys.executable, "-c", CUT_IN_PLACE, str(path)], capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 2, (r.returncode, r.stderr[-500:])
    assert str(path) in r.stdout and "cut short" in r.stdout and "another program" in r.stdout, r.stdout


def test_a_column_met_late_falls_back_to_the_whole_table(tmp_path: Path) -> None:
    """A field first met after the first block (or text in a column of numbers) cannot be
    streamed: iter_columns says so, and export writes the whole table instead, the same as
    to_columns'."""
    path = tmp_path / "late.mcap"
    with Recorder(path, None) as rec:
        for k in range(3000):
            t = k * 1e-3
            msg = {"T_w": 24.0 + k * 1e-4}
            if k >= 2500:
                msg["extra"] = 1.0
            rec.write("/skin/sample", t, msg)
            rec.write("/control", t, {"v_cmd": 0.1, "note": "x" if k == 2900 else 1.0})
    with pytest.raises(rec_mod.SchemaChangeError, match=r"extra|note"):
        list(iter_columns(path, block=1000))
    out = rec_mod.export(path, tmp_path / "late.csv")
    want = rec_mod._write_csv(tmp_path / "want.csv", to_columns(path))  # the whole table's text CSV
    assert out.read_bytes() == want.read_bytes()
    assert out.read_text().splitlines()[0] == "t,T_w,extra,v_cmd,note"


def test_replay_in_blocks_is_the_whole_replay(recording: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """replay_blocks (blocks of 16 384 rows; here 997) gives the whole replay's columns and
    comparison: the estimator is carried from block to block, bit for bit."""
    cols, cmp = replay(recording)
    monkeypatch.setattr(rec_mod, "BLOCK_ROWS", 997)
    got: dict = {}  # type: ignore[type-arg]
    blocks = list(replay_blocks(recording, comparison=got))
    assert len(blocks) > 10 and cmp["exact"] and got["exact"]
    assert {k: v for k, v in got.items() if k != "events"} == {k: v for k, v in cmp.items() if k != "events"}
    assert got["events"] == cmp["events"] and len(cmp["events"]) >= 1
    for k, x in cols.items():
        assert np.array_equal(np.concatenate([b[k] for b in blocks]), x, equal_nan=True), k


def test_reading_a_recording_does_not_grow_with_it(tmp_path: Path, peak_memory) -> None:  # type: ignore[no-untyped-def]
    """Python's peak while a recording is read block by block (iter_columns, then a replay) is
    the same (within 10 %) for one twice as long: the file is mapped, not read into memory,
    and only a block of rows is held. The whole table's peak doubles."""
    short, long = tmp_path / "short.mcap", tmp_path / "long.mcap"
    record_run(short, 4.0)  # 4 and 8 blocks of 1000 rows
    record_run(long, 8.0)

    def stream(p: Path) -> None:
        for _ in iter_columns(p, block=1000):
            pass

    stream(short)  # imports first
    s1, s2 = peak_memory(lambda: stream(short)), peak_memory(lambda: stream(long))
    w1, w2 = peak_memory(lambda: to_columns(short)), peak_memory(lambda: to_columns(long))
    assert s2 < 1.1 * s1 and w2 > 1.6 * w1, (s1, s2, w1, w2)


def test_a_skins_recording_in_blocks_is_its_whole_table(tmp_path: Path) -> None:
    """A skin's recording (nine patches, their messages in reverse order, the last sample of one
    patch never recorded) read about 2000 rows at a time joins to skin_columns' long table; the
    export's CSV is the whole table's."""
    from thermoskin.live.skin_topics import layout, skin_topics
    from thermoskin.skin.layout import load_skin

    skin = load_skin(Path(__file__).resolve().parents[1] / "examples" / "forearm.toml")
    names = [p.name for p in skin.patches]
    path = tmp_path / "s.mcap"
    rec = Recorder(path, CFG, schemas=skin_topics(skin), params={"skin": layout(skin)})
    n = 3000
    for r in range(n):
        t = r * 1e-3
        for i in reversed(range(len(names))):
            if r == n - 1 and i == 2:
                continue
            rec.write(f"/patch/{names[i]}/sample", t, {"T_w": 20.0 + i + r / 1e3, "T_p": 30.0, "T_a": 19.0,
                                                       "v": 0.1, "fresh": 1})
            rec.write(f"/patch/{names[i]}/estimate", t, {"q_i_hat": float(i), "dq_i_hat": -r * 1e-3,
                                                         "contact": 0, "gap": 0})
    rec.close()
    whole = rec_mod.skin_columns(path)
    assert whole is not None and len(whole["t"]) == (n - 1) * len(names)
    blocks = list(rec_mod.iter_skin_columns(path, block=2000))  # type: ignore[arg-type]
    assert len(blocks) > 5
    got = _joined(blocks)
    assert list(got) == list(whole)
    for k in whole:
        assert np.array_equal(np.asarray(got[k]), np.asarray(whole[k]), equal_nan=True), k
    out = rec_mod.export(path, tmp_path / "s.csv")
    want = tmp_path / "want.csv"
    from thermoskin.logio import write_log

    write_log(want, {k: np.asarray(v) for k, v in whole.items()})
    assert out.read_bytes() == want.read_bytes()


def _late_control(path: Path, start: int, n: int = 20_000, estimates: bool = True) -> None:
    """A recording whose /control (v_cmd) begins at row ``start``."""
    with Recorder(path, CFG) as rec:
        for k in range(n):
            t = k * 1e-3
            rec.write("/skin/sample", t, {"T_w": 24.0 + 1e-5 * k, "T_p": 26.0, "T_a": 20.0, "fresh": 7})
            if k >= start:
                rec.write("/control", t, {"T_w_cmd": 24.0, "T_p_cmd": 26.0, "drive": 0.1, "v_cmd": 0.141})
            if estimates:
                rec.write("/skin/estimate", t, {"q_i_hat": 0.0, "dq_i_hat": 0.0, "contact": 0, "gap": 0})


def test_what_streaming_cannot_see_is_read_whole(tmp_path: Path) -> None:
    """What a block cannot know is read whole, as before: a column the replay needs first met
    after the first block (the replay runs, as the whole one); a merged message that comes more
    than the rows held after its sample; a cut-off recording whose last whole sample is before
    the rows held (the table ends there). And the errors are the whole recording's: a recording
    with no estimate and no v_cmd says it has no estimates; a recording with no sample says so,
    also when exported to CSV."""
    late = tmp_path / "late.mcap"
    _late_control(late, 18_000)
    cols, cmp = replay(late)
    assert len(cols["t"]) == 20_000 and cmp["samples"] == 20_000
    with pytest.raises(rec_mod.SchemaChangeError):
        list(replay_blocks(late))
    # a merged message 1500 rows after its sample
    lag = tmp_path / "lag.mcap"
    with Recorder(lag, None) as rec:
        for k in range(20_000):
            rec.write("/skin/sample", k * 1e-3, {"T_w": 24.0})
            if k >= 1500:
                rec.write("/control", (k - 1500) * 1e-3, {"v_cmd": float(k - 1500)})
    with pytest.raises(rec_mod.SchemaChangeError):
        list(iter_columns(lag))
    out = rec_mod.export(lag, tmp_path / "lag.csv")
    from thermoskin.logio import read_log, write_log

    got = read_log(out, required=("t",))
    assert np.array_equal(got["v_cmd"][:18_500], np.arange(18_500.0))
    # a cut-off recording whose estimates stopped 10 000 rows before its end
    stop = tmp_path / "stop.mcap"
    with Recorder(stop, None) as rec:
        for k in range(40_000):
            rec.write("/skin/sample", k * 1e-3, {"T_w": 24.0})
            if k < 10_000:
                rec.write("/skin/estimate", k * 1e-3, {"q_i_hat": 1.0})
    data = stop.read_bytes()
    cut = tmp_path / "cut.mcap"
    cut.write_bytes(data[: len(data) - 200])  # no footer: cut off
    whole = to_columns(cut)
    assert len(whole["t"]) == 10_000
    out = rec_mod.export(cut, tmp_path / "cut.csv")
    want = write_log(tmp_path / "want.csv", {k: np.asarray(v) for k, v in whole.items()})
    assert out.read_bytes() == want.read_bytes()
    # errors
    none = tmp_path / "none.mcap"
    _late_control(none, 10**9, n=100, estimates=False)
    with pytest.raises(rec_mod.RecordingError, match="no /skin/estimate messages"):
        replay(none)
    empty = tmp_path / "empty.mcap"
    with Recorder(empty, None) as rec:
        rec.write("/control", 0.0, {"v_cmd": 0.1})
    with pytest.raises(rec_mod.RecordingError, match=r"^\S*empty.mcap: no messages on /skin/sample$"):
        rec_mod.export(empty, tmp_path / "e.csv")


def test_export_of_a_fault_run_is_the_whole_tables_csv(tmp_path: Path,
                                                      monkeypatch: pytest.MonkeyPatch) -> None:
    """A run that ended in a fault has a row with no estimate (NaN in the flag columns): the
    streamed export writes the same CSV as the whole table written at once. The CSV writer
    chooses a flag column's integers or floats per slice it is handed, so the blocks are handed
    over in write_log's slices whatever their lengths: here slices of 600 rows (262 144 in use)
    and blocks of 250 (16 384), so that a block ends neither at the slice's end nor at the NaN."""
    import thermoskin.logio as logio
    from thermoskin.logio import write_log

    monkeypatch.setattr(logio, "_WRITE_SLICE", 600)
    monkeypatch.setattr(rec_mod, "BLOCK_ROWS", 250)

    path = tmp_path / "f.mcap"  # the tank over 22 °C trips the supervisor at 1.16 s
    rec = LoopRecorder(path, CFG)
    try:
        run_closed_loop(SCENARIOS["one-finger"].with_duration(6.0),
                        CFG.replace(safety={"T_p_max": 22.0}), on_block=rec.write_rows, keep=False)
    finally:
        rec.close()
    whole = to_columns(path)
    contact = np.asarray(whole["contact"], dtype=float)
    assert 1000 < len(contact) < 1200 and np.isnan(contact[600:]).any()
    assert not np.isnan(contact[:750]).any()  # the first slice is integers, the second floats
    out = rec_mod.export(path, tmp_path / "f.csv")
    want = write_log(tmp_path / "want.csv", {k: np.asarray(v) for k, v in whole.items()})
    assert out.read_bytes() == want.read_bytes()
