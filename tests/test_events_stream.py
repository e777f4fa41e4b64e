"""The events table written as contacts end (``events.EventsStream``): readable row by row
before the writer closes (what a killed run leaves), in the same form as the whole table."""

from __future__ import annotations

import csv
import math
from pathlib import Path

from thermoskin.estimation.events import EVENT_COLUMNS, ContactEvent, EventsStream, write_events
from thermoskin.skin.observe import SKIN_EVENT_COLUMNS, SkinEvent

TAP = ContactEvent(onset=1.0, detected_at=1.1, release=1.5, duration=0.5, sign=1, peak_dq=0.2,
                   mean_dq=0.1, energy=0.05)
HOLD = ContactEvent(onset=3.0, detected_at=3.2, release=6.0, duration=3.0, sign=-1, peak_dq=-0.4,
                    mean_dq=-0.3, energy=-0.9)


def rows(path: Path) -> list[dict[str, str]]:
    with open(path, newline="", encoding="utf-8") as fh:
        return list(csv.DictReader(fh))


def test_rows_are_there_before_close_and_match_the_whole_table(tmp_path: Path) -> None:
    p = tmp_path / "ev.csv"
    s = EventsStream(p)
    assert p.read_text().splitlines() == [",".join(EVENT_COLUMNS)]  # the header at once
    s.add(TAP)
    got = rows(p)  # not closed: flushed row by row
    assert len(got) == 1 and got[0]["kind"] == "tap" and got[0]["toucher"] == ""
    s.add(HOLD)
    assert [r["kind"] for r in rows(p)] == ["tap", "hold"]
    s.close()
    whole = tmp_path / "whole.csv"
    write_events(whole, [TAP, HOLD])  # the table of the end of a run, no characterisation
    streamed, final = rows(p), rows(whole)
    for a, b in zip(streamed, final, strict=True):
        for k in EVENT_COLUMNS:
            if k == "kind":
                continue  # the whole table's kind comes from the characteriser
            assert a[k] == b[k], (k, a[k], b[k])
    assert float(streamed[1]["onset"]) == 3.0 and streamed[1]["sign"] == "-1"


def test_a_skin_table_keeps_its_patch_and_leaves_what_is_said_at_the_end_empty(tmp_path: Path) -> None:
    p = tmp_path / "skin_ev.csv"
    with EventsStream(p, (*SKIN_EVENT_COLUMNS, "kind"), fill_kind=False) as s:
        s.add_row(SkinEvent(2, "dorsal3", HOLD).row())
        got = rows(p)
    assert list(got[0]) == [*SKIN_EVENT_COLUMNS, "kind"]
    r = got[0]
    assert r["patch"] == "dorsal3" and r["position"] == "" and r["kind"] == ""
    assert math.isclose(float(r["mean_dq"]), -0.3) and r["sign"] == "-1"


WHAT = ContactEvent(onset=8.0, detected_at=8.05, release=9.0, duration=1.0, sign=1, peak_dq=0.6, mean_dq=0.45,
                    energy=0.45, kind="hold", toucher="person", material="skin", p_human=0.93, G_hat=0.05,
                    G_sd=0.01, T_f_hat=33.9, T_f_sd=0.4, effusivity_hat=1100.0)


def test_the_whole_table_in_parquet(tmp_path: Path) -> None:
    """`--events E.parquet` (a folder that is not there yet): every column, numbers as float64 with
    NaN as null, text as text with an empty field as null, the rows in order (pyarrow reads it)."""
    import pyarrow.parquet as pq

    p = tmp_path / "new" / "deeper" / "ev.parquet"
    write_events(p, [TAP, WHAT])
    t = pq.read_table(p)
    assert t.column_names == list(EVENT_COLUMNS)
    got = t.to_pylist()
    assert got[0]["onset"] == 1.0 and got[0]["sign"] == 1.0 and got[0]["toucher"] is None
    assert got[0]["G_hat"] is None and got[0]["kind"] is None  # NaN and "" as nulls
    assert got[1] == {"onset": 8.0, "detected": 8.05, "release": 9.0, "duration": 1.0, "sign": 1.0,
                      "peak_dq": 0.6, "mean_dq": 0.45, "energy": 0.45, "kind": "hold", "toucher": "person",
                      "material": "skin", "p_human": 0.93, "G_hat": 0.05, "G_sd": 0.01, "T_f_hat": 33.9,
                      "T_f_sd": 0.4, "effusivity_hat": 1100.0}
    assert str(t.schema.field("onset").type) == "double" and str(t.schema.field("kind").type) == "string"


def test_stream_counts_rows_fills_what_it_can_and_ends_lines_with_lf(tmp_path: Path) -> None:
    """Rows counted; a missing column left empty; a row without kind gets the one patch's kind of
    its duration (none without one); lines end in LF alone, the file in UTF-8 (a non-ASCII
    toucher's name as written), in a folder made for it."""
    p = tmp_path / "made" / "ev.csv"
    with EventsStream(p) as s:
        assert s.rows == 0
        s.add(TAP)
        s.add_row({"onset": 2.0, "duration": 2.5})
        s.add_row({"onset": 4.0, "toucher": "Müller"})
        assert s.rows == 3
    raw = p.read_bytes()
    assert b"\r" not in raw and raw.endswith(b"\n")
    got = rows(p)
    assert [r["kind"] for r in got] == ["tap", "hold", ""]
    assert got[1]["release"] == "" and got[2]["toucher"] == "Müller"


def test_the_whole_csv_table_ends_lines_with_lf_and_a_given_kind_stays(tmp_path: Path) -> None:
    """The end-of-run table's lines end in LF alone; a row that says its kind keeps it (a stroke
    of 0.2 s is not made a tap); a stream two folders down makes both."""
    p = tmp_path / "ev.csv"
    write_events(p, [TAP, HOLD])
    assert b"\r" not in p.read_bytes()
    q = tmp_path / "a" / "b" / "ev.csv"
    with EventsStream(q) as s:
        s.add_row({"onset": 1.0, "duration": 0.2, "kind": "stroke"})
    assert rows(q)[0]["kind"] == "stroke"


def test_a_parquet_table_at_a_name_pyarrow_cannot_take(tmp_path: Path) -> None:
    import os

    import pyarrow.parquet as pq

    p = tmp_path / (os.fsdecode(b"ev\xff") + ".parquet")
    write_events(p, [TAP, HOLD])
    with open(p, "rb") as fh:
        assert pq.read_table(fh).column("onset").to_pylist() == [1.0, 3.0]


def test_columns_are_floats_and_text_and_an_empty_text_column_is_text_in_parquet(tmp_path: Path) -> None:
    """``events_columns``: numbers as float64 (``sign`` given as an int too), text as ``str``; in
    Parquet a text column that no event fills (no characterisation) is still of type string."""
    import numpy as np
    import pyarrow.parquet as pq

    from thermoskin.estimation.events import events_columns

    cols = events_columns([TAP, HOLD])
    assert cols["sign"].dtype == np.float64 and cols["onset"].dtype == np.float64
    assert cols["kind"].dtype.kind == "U"
    p = tmp_path / "ev.parquet"
    write_events(p, [TAP, HOLD])
    schema = pq.read_schema(p)
    assert {str(schema.field(k).type) for k in ("toucher", "material")} == {"string"}
    assert str(schema.field("sign").type) == "double"


def test_a_stream_under_an_ascii_locale_writes_utf8(tmp_path: Path) -> None:
    """A skin's patch named ``Handrücken``, the process's character type the C locale's (ASCII,
    as under ``LC_ALL=C`` with coercion and UTF-8 mode off): the streamed table is UTF-8, as the
    whole one."""
    import locale
    import sys

    if sys.flags.utf8_mode:
        import pytest

        pytest.skip("UTF-8 mode: every file is UTF-8 whatever the locale")
    p = tmp_path / "ev.csv"
    old = locale.setlocale(locale.LC_CTYPE)
    locale.setlocale(locale.LC_CTYPE, "C")
    try:
        with EventsStream(p, ("onset", "patch")) as s:
            s.add_row({"onset": 1.0, "patch": "Handrücken"})
    finally:
        locale.setlocale(locale.LC_CTYPE, old)
    assert p.read_bytes() == "onset,patch\n1.0,Handrücken\n".encode()


def test_an_event_from_the_kernels_record() -> None:
    """The compiled kernel's event record, fields in the ``EV_*`` order, by hand: the event with
    those values, the sign an int; ``as_dict`` gives every field by its name."""
    import numpy as np

    from thermoskin.estimation import events as ev

    layout = (ev.EV_ONSET, ev.EV_DETECTED, ev.EV_RELEASE, ev.EV_DURATION, ev.EV_SIGN, ev.EV_PEAK,
              ev.EV_MEAN, ev.EV_ENERGY)
    assert layout == tuple(range(8))
    e = ContactEvent.from_kernel(np.array([3.0, 3.2, 6.0, 3.0, -1.0, -0.4, -0.3, -0.9]))
    assert e == HOLD
    assert isinstance(e.sign, int) and e.sign == -1
    d = e.as_dict()
    assert d["onset"] == 3.0 and d["detected_at"] == 3.2 and d["release"] == 6.0 and d["energy"] == -0.9
    assert d["kind"] == "" and math.isnan(d["G_hat"])  # type: ignore[arg-type]
